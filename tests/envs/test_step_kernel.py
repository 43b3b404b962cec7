"""The compiled step (``envs/step_kernel.py``) against the env's Python step on the same seeded episodes.

``UR5BoneDrillEnv.use_compiled_step`` picks the step: two envs with the same seed, one on each, must agree on
every observation, reward, flag and info entry and on the recorded channels, within ``TOLERANCE`` (integers,
flags and strings exactly); the command queue, mid-step feed changes, the force limit and sensor settings are
all exercised.
"""

import gymnasium as gym
import numpy as np
import pytest
from bitwise import largest_difference

from drillgym import envs
from drillgym.envs.effects.registry import EFFECTS, build_effects

ENV_ID = envs.ENV_IDS[0]
TOLERANCE = 1e-12
"""Largest relative difference allowed: the kernel's ``math.hypot`` and sums of three products may round
differently from numpy's in the last bit (measured: ≤ 3e-16 relative on these episodes)."""


def _pair(kwargs: dict) -> tuple[gym.Env, gym.Env]:
    compiled, python = gym.make(ENV_ID, **kwargs), gym.make(ENV_ID, **kwargs)
    python.unwrapped.use_compiled_step = False
    return compiled, python


def _run(kwargs: dict, seed: int, actions: np.ndarray | None, effects=None) -> int:
    compiled, python = _pair(kwargs)
    try:
        out_c = compiled.reset(seed=seed, options={"effects": effects() if effects else []})
        out_p = python.reset(seed=seed, options={"effects": effects() if effects else []})
        assert compiled.unwrapped._kernel is not None
        assert python.unwrapped._kernel is None
        for step in range(4000):
            a = np.zeros(4, np.float32) if actions is None else actions[step % len(actions)]
            out_c, out_p = compiled.step(a), python.step(a)
            worst, where = largest_difference(out_c, out_p)
            assert worst <= TOLERANCE, f"step {step}: {where} differs by {worst:.2e}"
            if out_c[2] or out_c[3]:
                break
        rec_c, rec_p = compiled.unwrapped.recorder.channels(), python.unwrapped.recorder.channels()
        worst, where = largest_difference(
            {k: np.asarray(v) for k, v in rec_c.items()}, {k: np.asarray(v) for k, v in rec_p.items()}
        )
        assert worst <= TOLERANCE, f"recorder: {where} differs by {worst:.2e}"
        for k in rec_c:
            assert np.asarray(rec_c[k]).dtype == np.asarray(rec_p[k]).dtype, k
        return step + 1
    finally:
        compiled.close()
        python.close()


def _random_actions(seed: int, n: int = 4000) -> np.ndarray:
    """Random corrections, with the feed override held for a few steps at a time (mid-step feed changes)."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.3, 0.3, (n, 4)).astype(np.float32)
    a[:, 3] = np.repeat(rng.uniform(-0.5, 0.5, n // 7 + 1), 7)[:n]
    return a


@pytest.mark.parametrize(
    ("kwargs", "seed", "actions_seed"),
    [
        ({}, 0, None),
        ({}, 1, 2),
        ({"latency_s": 0.0}, 2, 3),
        ({"latency_s": 0.33, "servo_time_constant_s": 0.1}, 3, 4),
        ({"beta_deg": -20.0, "feed_mm_s": 1.5, "cortical_thickness_mm": 1.0}, 4, 5),
        ({"tracker": False, "ft_noise_n": 0.0, "tracker_noise_mm": 0.0}, 5, 6),
        ({"bone": "sawbones_20pcf", "stickout_mm": 26.0}, 6, 7),
    ],
)
def test_compiled_step_matches_the_python_step_to_rounding(kwargs, seed, actions_seed):
    actions = None if actions_seed is None else _random_actions(actions_seed)
    assert _run(kwargs, seed, actions) > 100


def test_compiled_step_stops_at_the_force_limit_like_the_python_step():
    assert _run({"force_limit_n": 4.0}, 0, None) < 200


COMPILED_EFFECTS = {
    "density_gradient": "density_gradient:offset=0.2,gradient_per_m=-60",
    "kinematic_offset": "kinematic_offset:dx_base_m=4e-4,dy_base_m=-3e-4,dz_base_m=5e-4",
    "tool_length": "tool_length:dl_m=4e-3",
    "skid_friction": "skid_friction:mu=1.5",
    "thermal_softening": "thermal_softening:softening=0.5,work_j=5",
    "joint_friction": "joint_friction:coulomb_rad=5e-4,viscous_s=0.01",
    "latency": "latency:extra_latency_s=0.12",
    "spindle_sag": "spindle_sag:sag_per_nm=300",
    "registration": "registration:surface_dz_m=6e-4,slope_error_rad=-0.1",
    "joint_backlash": "joint_backlash:play_rad=8e-4",
    "ft_drift": "ft_drift:fx_rate_n_s=0.05,fy_rate_n_s=-0.04,fz_rate_n_s=0.05",
    "kinematic_offset_trend": "kinematic_offset_trend:dx_first_m=4e-4,dy_first_m=-3e-4,dz_first_m=5e-4,dz_last_m=-5e-4",
    "all": "kinematic_offset:dx_base_m=2e-4+tool_length:dl_m=-3e-3+skid_friction:mu=0.7"
    "+thermal_softening:softening=0.3+joint_friction:coulomb_rad=2e-4,viscous_s=0.005+density_gradient:offset=-0.1"
    "+latency:extra_latency_s=0.3+spindle_sag:sag_per_nm=100"
    "+registration:surface_dz_m=-4e-4,slope_error_rad=0.08+joint_backlash:play_rad=3e-4"
    "+ft_drift:fx_rate_n_s=0.01,fy_rate_n_s=-0.01",
}
"""Every effect the compiled step runs, each at a size that moves the episode well away from the nominal one."""


@pytest.mark.parametrize("name", sorted(COMPILED_EFFECTS))
def test_compiled_step_matches_the_python_step_with_each_compiled_effect(name):
    def effects():
        return build_effects(COMPILED_EFFECTS[name])

    assert _run({}, 7, _random_actions(8), effects) > 100
    moved = _largest_force_change(effects(), 7, _random_actions(8))
    assert moved > 0.5, f"{name} changes the F/T force by only {moved:.3g} N: the test would not see it"


def _largest_force_change(effects: list, seed: int, actions: np.ndarray) -> float:
    """Largest change of the recorded F/T force (N) the effects make on a seeded episode (compiled step)."""
    forces = []
    for fx in (effects, []):
        env = gym.make(ENV_ID)
        env.reset(seed=seed, options={"effects": fx})
        for step in range(4000):
            if any(env.step(actions[step % len(actions)])[2:4]):
                break
        forces.append(np.asarray(env.unwrapped.recorder.ft_force_n))
        env.close()
    n = min(len(f) for f in forces)
    return float(np.abs(forces[0][:n] - forces[1][:n]).max())


def test_every_compiled_effect_is_exercised():
    compiled = {n for n, cls in EFFECTS.items() if cls.__dict__.get("compiled", False)}
    assert compiled == set(COMPILED_EFFECTS) - {"all"}


def test_compiled_step_is_used_only_for_compiled_effects():
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0, options={"effects": [EFFECTS["servo_deadband"](band_m=1e-4)]})
        assert env.unwrapped._kernel is None
        gradient = EFFECTS["density_gradient"](offset=0.1)
        env.reset(seed=0, options={"effects": [gradient, EFFECTS["ft_gain"](fz_gain=0.1)]})
        assert env.unwrapped._kernel is None
        two = [EFFECTS["joint_friction"](coulomb_rad=1e-4), EFFECTS["joint_friction"](viscous_s=1e-3)]
        env.reset(seed=0, options={"effects": two})  # one set of kernel parameters per hooked effect
        assert env.unwrapped._kernel is None
        env.reset(seed=0, options={"effects": [gradient, EFFECTS["kinematic_offset"](dx_base_m=1e-4)]})
        assert env.unwrapped._kernel is not None
        env.reset(seed=0, options={"effects": []})
        assert env.unwrapped._kernel is not None
    finally:
        env.close()


def test_a_subclass_of_a_compiled_effect_steps_in_python_unless_it_says_so():
    class Shifted(EFFECTS["kinematic_offset"]):
        name = "shifted"

    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0, options={"effects": [Shifted(dx_base_m=1e-4)]})
        assert env.unwrapped._kernel is None
    finally:
        env.close()


@pytest.mark.parametrize(
    ("kwargs", "spec", "compiled"),
    [
        ({"ft_noise_n": 0.0, "tracker_noise_mm": 0.0}, "", True),
        ({"ft_noise_n": 0.0, "tracker_noise_mm": 0.0, "latency_s": 0.1}, COMPILED_EFFECTS["all"], True),
        ({}, "kinematic_offset:dx_base_m=2e-4", False),  # noisy sensors: step by step
        ({"ft_noise_n": 0.0, "tracker_noise_mm": 0.0}, "servo_deadband:band_m=1e-4", False),  # Python step
    ],
)
def test_an_open_loop_replay_equals_stepping_the_same_actions(kwargs, spec, compiled):
    actions = _random_actions(11)
    envs_ = [gym.make(ENV_ID, **kwargs).unwrapped for _ in range(2)]
    try:
        for env in envs_:
            env.reset(seed=3, options={"effects": build_effects(spec) if spec else []})
        replayed, stepped = envs_
        assert replayed._kernel is not None and replayed._kernel.noiseless if compiled else True
        done, q, tracker = replayed.advance_open_loop(actions)
        q_ref, tracker_ref = np.full_like(q, np.nan), np.full_like(tracker, np.nan)
        for k, a in enumerate(actions):
            ended = stepped.advance(a)
            q_ref[k], tracker_ref[k] = stepped.cell.q_motor_rad, stepped.tracker_reading
            if any(ended):
                break
        assert done == k + 1 < len(actions)
        worst, where = largest_difference(
            {"q": q, "tracker": tracker, **{k: np.asarray(v) for k, v in replayed.recorder.channels().items()}},
            {"q": q_ref, "tracker": tracker_ref, **{k: np.asarray(v) for k, v in stepped.recorder.channels().items()}},
        )
        assert worst <= TOLERANCE, f"{where} differs by {worst:.2e}"
        assert replayed.metrics == pytest.approx(stepped.metrics, rel=TOLERANCE)
        assert replayed.t_s == stepped.t_s and replayed.path.phase == stepped.path.phase
        with pytest.raises(RuntimeError, match="ended"):
            replayed.advance_open_loop(actions[:1])
    finally:
        for env in envs_:
            env.close()


def test_an_open_loop_replay_rejects_a_nan_action_and_keeps_the_state():
    env = gym.make(ENV_ID, ft_noise_n=0.0, tracker_noise_mm=0.0).unwrapped
    env.reset(seed=0)
    actions = _random_actions(1, 50)
    actions[30, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        env.advance_open_loop(actions)
    assert env.steps == 0 and len(env.recorder) == 0
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "spec"),
    [
        ({"ft_noise_n": 0.0, "tracker_noise_mm": 0.0}, COMPILED_EFFECTS["all"]),  # one compiled call
        ({"ft_noise_n": 0.0, "tracker_noise_mm": 0.0}, "servo_deadband:band_m=1e-4"),  # Python step
    ],
)
def test_a_replay_returns_the_channels_an_open_loop_advance_records_bit_for_bit(kwargs, spec):
    actions = _random_actions(12)  # float32, as a policy's: scaled as the single step scales them
    envs_ = [gym.make(ENV_ID, **kwargs).unwrapped for _ in range(2)]
    try:
        for env in envs_:
            env.reset(seed=4, options={"effects": build_effects(spec)})
        replayed, recorded = envs_
        done, q, tracker, channels = replayed.replay_open_loop(actions)
        done_ref, q_ref, tracker_ref = recorded.advance_open_loop(actions)
        assert done == done_ref and np.array_equal(q, q_ref, equal_nan=True)
        assert np.array_equal(tracker, tracker_ref, equal_nan=True)
        for name, values in recorded.recorder.channels().items():
            ref = np.asarray(values)
            assert channels[name].shape == ref.shape and np.array_equal(channels[name], ref), name
        assert replayed.truncated == recorded.truncated
    finally:
        for env in envs_:
            env.close()
