from __future__ import annotations

import re

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs
from drillgym.envs.scenario import Scenario

ENV_ID = envs.ENV_IDS[0]


@pytest.mark.parametrize(
    ("kwargs", "name", "value", "allowed"),
    [
        ({"feed_mm_s": -0.5}, "feed_mm_s", "-0.5", "(0, 3]"),
        ({"feed_mm_s": 0.0}, "feed_mm_s", "0.0", "(0, 3]"),
        ({"beta_deg": 60}, "beta_deg", "60", "[-40, 40]"),
        ({"beta_deg": float("nan")}, "beta_deg", "nan", "[-40, 40]"),
        ({"stickout_mm": 0}, "stickout_mm", "0", "[10, 100]"),
        ({"depth_mm": 1.0}, "depth_mm", "1.0", "[2, 30]"),
        ({"ft_noise_n": -1}, "ft_noise_n", "-1", "[0, 2]"),
    ],
)
def test_out_of_range_scenario_value_raises_value_error_naming_argument_value_and_range(kwargs, name, value, allowed):
    with pytest.raises(ValueError) as err:
        gym.make(ENV_ID, **kwargs)
    msg = str(err.value)
    assert name in msg and value in msg and allowed in msg, msg


def test_unknown_bone_preset_raises_value_error_listing_presets():
    with pytest.raises(ValueError) as err:
        gym.make(ENV_ID, bone="granite")
    msg = str(err.value)
    assert "bone" in msg and "granite" in msg and "buffalo_femur" in msg, msg


def test_too_shallow_depth_for_the_entry_raises_value_error_with_minimum_depth():
    # A 6 mm drill at β = 40° needs R (cot κ + tan β) ≈ 4.3 mm to enter fully: 3 mm is in [2, 30] but too shallow.
    entry_mm = Scenario(drill_diameter_mm=6.0, beta_deg=40.0, depth_mm=30.0).entry_depth_m * 1e3
    assert 3.0 < entry_mm + 1.0
    with pytest.raises(ValueError) as err:
        gym.make(ENV_ID, drill_diameter_mm=6.0, beta_deg=40.0, depth_mm=3.0)
    msg = str(err.value)
    assert "depth_mm=3.0" in msg, msg
    assert f"depth_mm >= {entry_mm + 1.0:.2f}" in msg, msg


def test_misspelled_scenario_argument_raises_type_error_naming_it():
    with pytest.raises(TypeError, match=re.escape("feed_mms")):
        gym.make(ENV_ID, feed_mms=0.5)


@pytest.fixture
def twins():
    """Two envs reset with the same seed and advanced by the same 10 steps."""
    pair = [gym.make(ENV_ID), gym.make(ENV_ID)]
    warmup = np.random.default_rng(0).uniform(-0.2, 0.2, (10, 4)).astype(np.float32)
    for env in pair:
        env.reset(seed=3)
        for a in warmup:
            env.step(a)
    yield pair
    for env in pair:
        env.close()


def assert_same_step(result_a, result_b) -> None:
    (obs_a, r_a, te_a, tr_a, info_a), (obs_b, r_b, te_b, tr_b, info_b) = result_a, result_b
    for k in obs_a:
        np.testing.assert_array_equal(obs_a[k], obs_b[k], err_msg=f"obs[{k!r}]")
    assert r_a == r_b
    assert (te_a, tr_a) == (te_b, tr_b)
    for k in ("t_s", "phase", "stage", "depth_cmd_m", "deviation_m", "tip_pos_task_m", "force_true_n"):
        np.testing.assert_array_equal(info_a[k], info_b[k], err_msg=f"info[{k!r}]")
    assert info_a["reward_terms"] == info_b["reward_terms"]


@pytest.mark.parametrize(
    "bad",
    [[np.nan, 0, 0, 0], [0, 0, 0, np.inf], [0, -np.inf, 0, 0]],
    ids=["nan", "inf", "-inf"],
)
def test_non_finite_action_raises_and_leaves_state_unchanged(twins, bad):
    env, twin = twins
    with pytest.raises(ValueError):
        env.step(np.array(bad, np.float32))
    good = np.array([0.1, -0.1, 0.05, 0.2], np.float32)
    for _ in range(3):
        assert_same_step(env.step(good), twin.step(good))


@pytest.mark.parametrize("shape", [(3,), (5,), (0,), ()], ids=str)
def test_wrong_shape_action_raises_value_error(twins, shape):
    env, twin = twins
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(shape, np.float32))
    assert_same_step(env.step(np.zeros(4, np.float32)), twin.step(np.zeros(4, np.float32)))


@pytest.mark.parametrize("shape", [(2, 2), (1, 4)], ids=str)
def test_four_element_action_of_wrong_shape_raises_value_error(shape):
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0)
        with pytest.raises(ValueError):
            env.step(np.zeros(shape, np.float32))
    finally:
        env.close()


def test_out_of_range_action_is_clipped_to_the_box(twins):
    env, twin = twins
    for _ in range(3):
        assert_same_step(
            env.step(np.array([5, -7, 3, 10], np.float32)),
            twin.step(np.array([1, -1, 1, 1], np.float32)),
        )


@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf"), "1"])
def test_a_negative_or_non_finite_reward_weight_is_an_error(weight):
    with pytest.raises(ValueError, match="reward_force_weight"):
        gym.make(ENV_ID, reward_force_weight=weight)
