"""The batched env (``envs/batched.py``) against N single envs on the same seeds, and its API.

Episode ``i`` of ``reset(seed=s)`` must be the single env's ``reset(seed=s + i)``: every observation,
reward and flag within ``TOLERANCE`` each step, the same metrics at the end; an ended slot restarts as
the single env's ``reset()`` without a seed does.
"""

import numpy as np
import pytest
from bitwise import largest_difference

from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.effects.registry import build_effects

TOLERANCE = 1e-12
"""Largest relative difference allowed (see ``test_step_kernel.py``: the compiled step's last-bit rounding)."""


def _actions(seed: int, n: int, num_envs: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.4, 0.4, (n, num_envs, 4)).astype(np.float32)
    a[..., 3] = np.repeat(rng.uniform(-0.5, 0.5, (n // 5 + 1, num_envs)), 5, axis=0)[:n]
    return a


def _step_alongside(batch, singles, actions, episodes_each):
    """Step the batch and each slot's single env on the same actions until every slot has ended ``episodes_each``
    episodes: flags, rewards, observations and metrics equal within ``TOLERANCE``; an ended slot restarts as the
    single env's ``reset()`` without a seed. The batch's last infos."""
    episodes = np.zeros(len(singles), dtype=int)
    for step in range(len(actions)):
        obs_b, reward_b, term_b, trunc_b, infos = batch.step(actions[step])
        for i, env in enumerate(singles):
            obs_s, reward_s, term_s, trunc_s, info_s = env.step(actions[step, i])
            assert (term_s, trunc_s) == (term_b[i], trunc_b[i]), f"step {step}, episode {i}"
            assert abs(reward_s - reward_b[i]) <= TOLERANCE * (abs(reward_s) + 1e-9)
            seen = {k: v[i] for k, v in (infos["final_obs"] if term_s or trunc_s else obs_b).items()}
            worst, where = largest_difference(seen, obs_s)
            assert worst <= TOLERANCE, f"step {step}, episode {i}: {where} differs by {worst:.2e}"
            if term_s or trunc_s:
                metrics_b = {k: v[i] for k, v in infos["final_info"]["metrics"].items() if not k.startswith("_")}
                worst, where = largest_difference(metrics_b, info_s["metrics"])
                assert worst <= TOLERANCE, f"episode {i} metrics: {where} differs by {worst:.2e}"
                episodes[i] += 1
                obs_s, _ = env.reset()  # what the batch's slot restarts as
                worst, _ = largest_difference({k: v[i] for k, v in obs_b.items()}, obs_s)
                assert worst <= TOLERANCE
        if (episodes >= episodes_each).all():
            break
    assert (episodes >= episodes_each).all()
    return infos


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"beta_deg": -15.0, "feed_mm_s": 1.0, "latency_s": 0.1}, {"tracker": False, "cortical_thickness_mm": 1.5}],
)
def test_each_batched_episode_is_the_single_envs_episode_of_its_seed(kwargs):
    num_envs, seed = 3, 20
    batch = BatchedDrillEnv(num_envs, **kwargs)
    singles = [UR5BoneDrillEnv(pybullet_world=False, **kwargs) for _ in range(num_envs)]
    actions = _actions(1, 2000, num_envs)
    try:
        obs_b, _ = batch.reset(seed=seed)
        for i, env in enumerate(singles):
            obs_s, _ = env.reset(seed=seed + i)
            assert largest_difference({k: v[i] for k, v in obs_b.items()}, obs_s)[0] == 0.0
        _step_alongside(batch, singles, actions, episodes_each=2)
    finally:
        batch.close()
        for env in singles:
            env.close()


def test_reset_takes_one_seed_per_episode():
    batch = BatchedDrillEnv(2)
    single = UR5BoneDrillEnv(pybullet_world=False)
    try:
        batch.reset(seed=[7, 3])
        single.reset(seed=3)
        assert batch.params["force_scale"][1] == single.cell.specimen_hardness  # the specimen of seed 3
        with pytest.raises(ValueError, match="2 episodes"):
            batch.reset(seed=[1, 2, 3])
    finally:
        batch.close()
        single.close()


def test_observations_are_in_the_batched_observation_space():
    batch = BatchedDrillEnv(4)
    try:
        obs, _ = batch.reset(seed=0)
        assert batch.observation_space.contains(obs)
        for _ in range(60):
            obs, *_ = batch.step(batch.action_space.sample())
        assert batch.observation_space.contains(obs)
    finally:
        batch.close()


def test_bad_actions_and_arguments_are_rejected_with_the_state_unchanged():
    with pytest.raises(ValueError, match="num_envs"):
        BatchedDrillEnv(0)
    batch = BatchedDrillEnv(2)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            batch.step(np.zeros((2, 4)))
        batch.reset(seed=0)
        before = (batch.state.tobytes(), batch.params.tobytes(), batch.record.tobytes())
        bad = np.zeros((2, 4))
        bad[1, 2] = np.nan
        with pytest.raises(ValueError, match=r"episodes \[1\]"):
            batch.step(bad)
        with pytest.raises(ValueError, match="shape"):
            batch.step(np.zeros((3, 4)))
        assert before == (batch.state.tobytes(), batch.params.tobytes(), batch.record.tobytes())  # bit for bit
        with pytest.raises(ValueError, match="options"):
            batch.reset(options={"effects": []})
    finally:
        batch.close()


def test_make_vec_builds_the_batched_env_and_truncates_at_its_step_limit():
    import gymnasium as gym

    from drillgym.envs import SIM_ENV_ID

    batch = gym.make_vec(SIM_ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=30)
    try:
        assert isinstance(batch, BatchedDrillEnv)
        batch.reset(seed=0)
        for step in range(30):
            _, _, terminated, truncated, infos = batch.step(np.zeros((2, 4)))
            assert not terminated.any()
            assert truncated.all() == (step == 29)
        assert infos["final_info"]["metrics_truncated"].all()
    finally:
        batch.close()


def test_without_autoreset_an_ended_episode_stays_ended_and_is_not_stepped():
    batch = BatchedDrillEnv(2, autoreset=False, max_episode_steps=20)
    try:
        batch.reset(seed=0)
        for _ in range(19):
            batch.step(np.zeros((2, 4)))
        batch.active[1] = False  # as if episode 1 had ended already
        _, reward, terminated, truncated, _infos = batch.step(np.zeros((2, 4)))
        assert truncated.tolist() == [True, False] and not terminated.any() and reward[1] == 0.0
        assert batch.final_info(0)["metrics_truncated"] and not batch.active.any()
        frozen = (batch.state.tobytes(), batch.record.tobytes(), batch.recorded.tolist())
        _, reward, terminated, truncated, _ = batch.step(np.ones((2, 4)))
        assert not (terminated.any() or truncated.any() or reward.any())
        assert frozen == (batch.state.tobytes(), batch.record.tobytes(), batch.recorded.tolist())
        assert batch.recorded.tolist() == [100, 95]
        batch.reset(seed=0)
        assert batch.active.all()
    finally:
        batch.close()


def test_compiled_effects_run_in_every_episode_as_in_the_single_env():
    spec = "joint_backlash:play_rad=8e-4+latency:extra_latency_s=0.12+thermal_softening:softening=0.5,work_j=5"
    batch = BatchedDrillEnv(2, effects=spec)
    single = UR5BoneDrillEnv(pybullet_world=False)
    actions = _actions(3, 400, 2)
    try:
        batch.reset(seed=5)
        single.reset(seed=6, options={"effects": build_effects(spec)})
        assert batch.arrays.delay.shape[1] >= 1024  # grown for the delay line
        for step in range(400):
            obs_b, _, term_b, _trunc_b, infos = batch.step(actions[step])
            obs_s, _, term_s, trunc_s, _info_s = single.step(actions[step, 1])
            seen = {k: v[1] for k, v in (infos["final_obs"] if term_s or trunc_s else obs_b).items()}
            assert largest_difference(seen, obs_s)[0] == 0.0, f"step {step}"
            if term_s or trunc_s:
                assert term_b[1] == term_s
                break
        assert term_s or trunc_s
    finally:
        batch.close()
        single.close()


def test_effects_the_compiled_step_does_not_run_are_refused():
    with pytest.raises(ValueError, match="compiled step"):
        BatchedDrillEnv(1, effects="servo_deadband:band_m=1e-4").reset(seed=0)
    with pytest.raises(ValueError):
        BatchedDrillEnv(1, effects="no_such_effect:x=1")


def test_each_episode_reads_its_generators_stream_and_leaves_the_generator_where_the_single_env_does():
    """The batched env draws each episode's normals ahead, in blocks; at the episode's end its generator is put back
    where the single env's step-by-step draws leave it (so a reset without a seed continues the same stream)."""
    batch = BatchedDrillEnv(2, autoreset=False)
    single = UR5BoneDrillEnv(pybullet_world=False)
    try:
        batch.reset(seed=[11, 12])
        single.reset(seed=12)
        assert batch.state["noise_at"].tolist() == [batch.normals.size] * 2  # nothing drawn before a step
        actions = _actions(4, 2000, 2)
        for step in range(2000):
            *_, terminated, truncated, _ = batch.step(actions[step])
            *_, term_s, trunc_s, _ = single.step(actions[step, 1])
            if term_s or trunc_s:
                break
        assert terminated[1] or truncated[1]
        assert batch.envs[1].np_random.bit_generator.state == single.np_random.bit_generator.state
        assert batch.envs[1].np_random.random() == single.np_random.random()
    finally:
        batch.close()
        single.close()


def test_noiseless_sensors_draw_nothing():
    batch = BatchedDrillEnv(1, ft_noise_n=0.0, tracker_noise_mm=0.0)
    try:
        batch.reset(seed=0)
        before = batch.envs[0].np_random.bit_generator.state
        for _ in range(30):
            batch.step(np.zeros((1, 4)))
        assert batch.envs[0].np_random.bit_generator.state == before
    finally:
        batch.close()


def test_each_episode_can_drill_its_own_scenario_as_the_single_env_does():
    """Three holes of different angle, feed, stick-out, bone and depth in one batch: each slot's observations, rewards
    and metrics are the single env's reset with that scenario, and the scenario stays for the slot's next episode."""
    scenarios = [
        {"beta_deg": 10.0, "feed_mm_s": 1.2, "bone": "porcine_femur"},
        {},
        {"beta_deg": 35.0, "stickout_mm": 45.0, "depth_mm": 9.0, "cortical_thickness_mm": 3.0},
    ]
    num_envs, seed = len(scenarios), 11
    batch = BatchedDrillEnv(num_envs)
    singles = [UR5BoneDrillEnv(pybullet_world=False) for _ in range(num_envs)]
    actions = _actions(2, 3000, num_envs)
    try:
        obs_b, _ = batch.reset(seed=seed, options={"scenario": scenarios})
        for i, env in enumerate(singles):
            obs_s, _ = env.reset(seed=seed + i, options={"scenario": scenarios[i]})
            assert largest_difference({k: v[i] for k, v in obs_b.items()}, obs_s)[0] == 0.0
            assert batch.scenario_of(i) == env.scenario
        infos = _step_alongside(batch, singles, actions, episodes_each=1)  # the slot's next episode keeps its scenario
        durations = {round(float(m), 3) for m in infos["t_s"]}
        assert len(durations) > 1  # the holes differ in length: the slots are not in step
    finally:
        batch.close()
        for env in singles:
            env.close()


def test_bad_scenario_options_change_no_episode():
    batch = BatchedDrillEnv(2)
    try:
        batch.reset(seed=0)
        before = (batch.state.tobytes(), batch.params.tobytes())
        with pytest.raises(ValueError, match="beta_deg"):
            batch.reset(seed=0, options={"scenario": [{"beta_deg": 10.0}, {"beta_deg": 400.0}]})
        with pytest.raises(ValueError, match="list of 2"):
            batch.reset(seed=0, options={"scenario": [{"beta_deg": 10.0}]})
        with pytest.raises(ValueError, match="tracker"):
            batch.reset(seed=0, options={"scenario": [{}, {"tracker": False}]})
        assert before == (batch.state.tobytes(), batch.params.tobytes())
        assert batch.scenario_of(0) == batch.scenario_of(1) == batch.scenario
    finally:
        batch.close()


def test_each_episode_can_run_its_own_effects_as_the_single_env_does():
    """Three slots, three cells (friction, none, backlash + latency): each slot's episode is the single env's with those
    effects, bit for bit, and the slot keeps its cell for its next episode."""
    cells = ["joint_friction:coulomb_rad=3e-4", "", "joint_backlash:play_rad=6e-4+latency:extra_latency_s=0.05"]
    num_envs, seed = len(cells), 4
    batch = BatchedDrillEnv(num_envs, effects="joint_friction:coulomb_rad=1e-4")
    singles = [UR5BoneDrillEnv(pybullet_world=False) for _ in range(num_envs)]
    try:
        batch.reset(seed=seed, options={"effects": cells})
        for i, env in enumerate(singles):
            env.reset(seed=seed + i, options={"effects": build_effects(cells[i]) if cells[i] else []})
            assert batch.effects_of(i) == cells[i]
        _step_alongside(batch, singles, _actions(6, 3000, num_envs), episodes_each=1)
    finally:
        batch.close()
        for env in singles:
            env.close()


def test_bad_effects_options_change_no_episode():
    batch = BatchedDrillEnv(2, effects="latency:extra_latency_s=0.02")
    try:
        batch.reset(seed=0)
        before = (batch.state.tobytes(), batch.params.tobytes())
        with pytest.raises(ValueError, match="compiled step"):
            batch.reset(seed=0, options={"effects": ["", "servo_deadband:band_m=1e-4"]})
        with pytest.raises(ValueError, match="list of 2"):
            batch.reset(seed=0, options={"effects": [""]})
        with pytest.raises(ValueError, match="no_such_effect"):
            batch.reset(seed=0, options={"effects": "no_such_effect:x=1"})
        assert before == (batch.state.tobytes(), batch.params.tobytes())
        assert batch.effects_of(0) == batch.effects_of(1) == "latency:extra_latency_s=0.02"
    finally:
        batch.close()
