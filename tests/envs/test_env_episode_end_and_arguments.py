"""Episode end and reset options: metrics on every ending, unknown reset options rejected."""

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.envs.constants import MAX_EPISODE_STEPS

ENV_ID = "drillgym/UR5BoneDrill-v1"


def test_a_time_limit_truncation_still_reports_the_episode_metrics_flagged_as_truncated():
    env = gym.make(ENV_ID, feed_mm_s=0.25, depth_mm=30.0)  # 480 s at a quarter feed: past the 4000-step limit
    env.reset(seed=0)
    slowest = np.array([0.0, 0.0, 0.0, -1.0], np.float32)
    steps, done = 0, False
    while not done:
        _, _, terminated, truncated, info = env.step(slowest)
        steps, done = steps + 1, terminated or truncated
    assert truncated and not terminated and steps == MAX_EPISODE_STEPS
    assert info["metrics_truncated"] is True and np.isfinite(info["metrics"]["deviation_mean_mm"])
    env.close()


def test_a_complete_episode_is_not_flagged_as_truncated():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        done = terminated or truncated
    assert terminated and info["metrics_truncated"] is False
    env.close()


def test_unknown_reset_options_are_rejected_naming_the_allowed_ones():
    env = gym.make(ENV_ID)
    with pytest.raises(
        ValueError, match=r"unknown key\(s\) \['beta_deg'\].*\['effects', 'scenario', 'specimen_seed'\]"
    ):
        env.reset(seed=0, options={"beta_deg": 10})
    env.reset(seed=0, options={"scenario": {"beta_deg": 10}})
    assert env.unwrapped.scenario.beta_deg == 10
    env.close()


def test_an_unknown_argument_names_the_closest_one_and_every_accepted_one():
    with pytest.raises(TypeError, match=r"'reward_forc_weight' \(did you mean 'reward_force_weight'\?\)") as e:
        gym.make(ENV_ID, reward_forc_weight=1.0)
    assert "render_mode" in str(e.value) and "beta_deg" in str(e.value)


def test_render_frames_have_the_asked_size_and_bad_sizes_are_errors():
    env = gym.make(ENV_ID, render_mode="rgb_array", render_width_px=64, render_height_px=48)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0
    env.close()
    with pytest.raises(ValueError, match="render_width_px=0"):
        gym.make(ENV_ID, render_width_px=0)


def test_a_time_limit_of_your_own_reports_the_episode_metrics_under_the_metrics_wrapper():
    from drillgym.envs.wrappers import MetricsOnTruncation

    # 150 steps: past contact (the tip starts 3 mm above the bone at 0.5 mm/s)
    env = MetricsOnTruncation(gym.make(ENV_ID, max_episode_steps=150, pybullet_world=False))
    env.reset(seed=0)
    steps, done, info = 0, False, {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        steps, done = steps + 1, terminated or truncated
        if not done:
            assert "metrics" not in info
    assert truncated and not terminated and steps == 150
    assert info["metrics_truncated"] is True
    assert info["metrics"] == env.unwrapped.episode_metrics()
    assert np.isfinite(info["metrics"]["lateral_force_max_n"])
    env.close()
