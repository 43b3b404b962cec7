from __future__ import annotations

import gymnasium as gym
import numpy as np
from bitwise import first_difference

from drillgym import envs

ENV_ID = envs.ENV_IDS[0]


def random_actions(seed: int, n: int = 4000) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.2, 0.2, size=(n, 4)).astype(np.float32)


def rollout(env: gym.Env, seed: int, actions: np.ndarray) -> list[dict]:
    """Records of reset + every step until the episode ends."""
    obs, info = env.reset(seed=seed)
    records = [{"obs": obs, "info": info}]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        records.append({"obs": obs, "reward": reward, "terminated": terminated, "truncated": truncated, "info": info})
        if terminated or truncated:
            return records
    raise AssertionError("episode did not end")


def assert_identical(run_a: list[dict], run_b: list[dict]) -> None:
    for step, (ra, rb) in enumerate(zip(run_a, run_b, strict=False)):
        diff = first_difference(ra, rb)
        assert diff is None, f"diverged at step {step}: {diff}"
    assert len(run_a) == len(run_b), f"episode lengths differ: {len(run_a)} vs {len(run_b)} steps"


def test_two_envs_same_seed_same_actions_are_bit_identical():
    actions = random_actions(123)
    env_a, env_b = gym.make(ENV_ID), gym.make(ENV_ID)
    try:
        run_a = rollout(env_a, 7, actions)
        run_b = rollout(env_b, 7, actions)
    finally:
        env_a.close()
        env_b.close()
    assert run_a[-1]["terminated"] or run_a[-1]["truncated"]
    assert "metrics" in run_a[-1]["info"]
    assert_identical(run_a, run_b)


def test_reset_with_same_seed_twice_replays_identical_episode():
    actions = random_actions(5)
    env = gym.make(ENV_ID)
    try:
        first = rollout(env, 11, actions)
        rollout(env, 99, actions)  # something else in between
        second = rollout(env, 11, actions)
    finally:
        env.close()
    assert_identical(first, second)


def test_different_seeds_give_different_sensor_readings():
    actions = np.zeros((4000, 4), np.float32)
    env = gym.make(ENV_ID)
    try:
        run_a = rollout(env, 1, actions)
        run_b = rollout(env, 2, actions)
    finally:
        env.close()
    differs = [
        not np.array_equal(ra["obs"]["ft_wrench"], rb["obs"]["ft_wrench"])
        for ra, rb in zip(run_a[1:], run_b[1:], strict=False)
    ]
    assert any(differs), "ft_wrench identical at every step for seeds 1 and 2"


def _rollout_with(env: gym.Env, seed: int, actions: np.ndarray, options: dict) -> list[dict]:
    obs, info = env.reset(seed=seed, options=options)
    records = [{"obs": obs, "info": info}]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        records.append({"obs": obs, "reward": reward, "info": info})
        if terminated or truncated:
            return records
    raise AssertionError("episode did not end")


def test_returning_to_an_earlier_scenario_reuses_its_cell_and_replays_the_fresh_envs_episode():
    from drillgym.envs.effects import build_effects

    actions = random_actions(8)
    hard, soft = {"scenario": {"density_scale": 1.2}}, {"scenario": {"density_scale": 0.8}}
    fresh = gym.make(ENV_ID, density_scale=1.2)
    env = gym.make(ENV_ID)
    try:
        expected = _rollout_with(fresh, 3, actions, {})
        _rollout_with(env, 3, actions, hard)
        cell = env.unwrapped.cell
        # the same cell, left with effects attached by another episode, then a different scenario in between
        _rollout_with(
            env, 5, actions, {**hard, "effects": build_effects("tool_length:dl_m=0.004+latency:extra_latency_s=0.03")}
        )
        _rollout_with(env, 6, actions, {**soft, "effects": []})
        again = _rollout_with(env, 3, actions, hard)
        assert env.unwrapped.cell is cell  # kept, not built again
    finally:
        env.close()
        fresh.close()
    assert_identical(expected, again)


def test_an_episode_after_one_with_effects_is_the_fresh_envs_episode():
    """The last episode's effects (the links' play moving the tool and marker) never reach the next's start."""
    from drillgym.controllers import make_controller
    from drillgym.controllers.rollout import run_episode
    from drillgym.envs.effects import build_effects

    spec = "joint_backlash:play_rad=3e-4+ft_gain:fz_gain=0.05"  # an uncompiled one: the Python step

    def deviation(env, controller, seed):
        env.unwrapped.set_effects(build_effects(spec))
        return run_episode(env, make_controller(controller), seed, keep_trace=False).metrics["deviation_mean_mm"]

    fresh, used = gym.make(ENV_ID), gym.make(ENV_ID)
    try:
        expected = deviation(fresh, "li2023", 0)
        deviation(used, "none", 0)
        assert deviation(used, "li2023", 0) == expected
    finally:
        fresh.close()
        used.close()
