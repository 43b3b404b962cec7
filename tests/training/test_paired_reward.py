"""The paired reward: the agent's step reward minus the base's on the same episode."""

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.training.config import TrainConfig
from drillgym.training.env_factory import ENV_ID, residual_env
from drillgym.training.paired_reward import PairedReward

BASE = "li2023_tuned"


def _cfg() -> TrainConfig:
    return TrainConfig(
        base=BASE,
        residual_mode="gain",
        residual_scale=0.25,
        residual_feed=True,
        residual_feed_ceiling="nominal",
        paired_reward=True,
        env_kwargs={"reward_deviation_weight": 10.0, "reward_force_weight": 0.0, "reward_peak_force_weight": 200.0},
    )


def _episode(env, residual):
    _, info = env.reset()
    paired, unpaired = [], []
    while True:
        _, r, terminated, truncated, info = env.step(residual)
        paired.append(r)
        unpaired.append(info["reward_unpaired"])
        if terminated or truncated:
            return np.array(paired), np.array(unpaired), info


def _base_return(wrapper: PairedReward) -> tuple[float, int]:
    """The base controller's return and steps on the wrapper's last episode, from a fresh env built with the scenario."""
    env = gym.make(ENV_ID, **_cfg().env_kwargs, **wrapper.unwrapped.scenario.to_dict())
    obs, _ = env.reset(seed=wrapper.last_seed)
    controller = make_controller(BASE)
    controller.set_plan(env.unwrapped.plan)
    total, steps = 0.0, 0
    while True:
        action, _ = controller.predict(obs)
        obs, r, terminated, truncated, _ = env.step(action)
        total, steps = total + r, steps + 1
        if terminated or truncated:
            return total, steps


def test_a_zero_residual_earns_exactly_zero_at_every_step():
    env = residual_env(_cfg(), randomize=True)
    env.reset(seed=3)
    for _ in range(2):  # the first (seeded) episode and one drawn after it
        paired, unpaired, _ = _episode(env, np.zeros(env.action_space.shape, np.float32))
        assert np.all(paired == 0.0)
        assert unpaired.sum() < -1.0  # the unpaired reward is far from zero: the pairing cancels it


def test_the_paired_return_is_the_agent_return_minus_the_base_return_on_the_same_episode():
    env = residual_env(_cfg(), randomize=True)
    env.reset(seed=5)
    residual = np.array([0.6, -0.4, -0.8], np.float32)  # more x, less y correction, a slower feed
    paired, unpaired, _ = _episode(env, residual)
    wrapper = env.env
    assert isinstance(wrapper, PairedReward)
    base_return, base_steps = _base_return(wrapper)
    assert base_steps == len(wrapper.last_base_rewards)
    assert len(paired) > base_steps  # a slower feed: the agent's episode is longer than the base's
    np.testing.assert_allclose(paired.sum(), unpaired.sum() - base_return, rtol=0, atol=1e-9)
    assert abs(paired.sum()) > 0.1


def test_a_seeded_run_replays_the_same_episode_seeds():
    seeds = []
    for _ in range(2):
        env = residual_env(_cfg(), randomize=True)
        run = []
        for k in range(3):
            _, info = env.reset(seed=11 if k == 0 else None)
            run.append(info["episode_seed"])
        seeds.append(run)
    assert seeds[0] == seeds[1]
    assert len(set(seeds[0])) == 3
