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
from drillgym.envs.effects.registry import EFFECTS

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
        rec_c, rec_p = compiled.unwrapped.recorder.__dict__, python.unwrapped.recorder.__dict__
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


def test_compiled_step_matches_the_python_step_with_a_density_gradient():
    def effects():
        return [EFFECTS["density_gradient"](offset=0.2, gradient_per_m=-60.0)]

    assert _run({}, 7, _random_actions(8), effects) > 100


def test_compiled_step_is_used_only_without_step_hooks():
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0, options={"effects": [EFFECTS["latency"](extra_latency_s=0.02)]})
        assert env.unwrapped._kernel is None
        gradient = EFFECTS["density_gradient"](offset=0.1)
        env.reset(seed=0, options={"effects": [gradient, EFFECTS["kinematic_offset"](dx_base_m=1e-4)]})
        assert env.unwrapped._kernel is None
        env.reset(seed=0, options={"effects": [gradient]})
        assert env.unwrapped._kernel is not None
        env.reset(seed=0, options={"effects": []})
        assert env.unwrapped._kernel is not None
    finally:
        env.close()
