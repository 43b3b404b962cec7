from __future__ import annotations

import itertools
import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from drillgym import envs
from drillgym.envs.effects import build_effects
from drillgym.envs.observation import OBS_BOUNDS

ENV_ID = envs.ENV_IDS[0]
PRIVILEGED_INFO_KEYS = (
    "tip_pos_task_m",
    "stage",
    "deviation_m",
    "tip_deflection_robot_m",
    "tip_deflection_tool_m",
    "force_true_n",
)
REQUIRED_METRICS = (
    "deviation_mean_mm",
    "deviation_max_mm",
    "lateral_force_max_n",
    "lateral_force_stable_n",
    "hole_offset_mm",
    "drill_time_s",
)
ZERO = np.zeros(4, dtype=np.float32)


def run_episode(env: gym.Env, action: np.ndarray = ZERO, seed: int = 0) -> list[tuple]:
    """(obs, reward, terminated, truncated, info) of every step, the reset as step 0 (reward None)."""
    obs, info = env.reset(seed=seed)
    out = [(obs, None, False, False, info)]
    while True:
        obs, reward, terminated, truncated, info = env.step(action)
        out.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            return out


@pytest.fixture(scope="module")
def zero_episode():
    env = gym.make(ENV_ID)
    steps = run_episode(env)
    yield env, steps
    env.close()


@pytest.mark.parametrize("env_id", envs.ENV_IDS)
def test_gymnasium_env_checker_passes_including_render(env_id):
    # render_mode="rgb_array" renders headless (PyBullet DIRECT + TinyRenderer), so the render check runs.
    env = gym.make(env_id, render_mode="rgb_array")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped, skip_render_check=False)
        assert not [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    finally:
        env.close()


@pytest.mark.parametrize("env_id", envs.ENV_IDS)
def test_stable_baselines3_env_checker_passes(env_id):
    env = gym.make(env_id)
    try:
        sb3_check_env(env.unwrapped, warn=True)
    finally:
        env.close()


def test_action_space_is_unit_box_of_four_float32():
    env = gym.make(ENV_ID)
    try:
        space = env.action_space
        assert isinstance(space, spaces.Box)
        assert space.shape == (4,)
        assert space.dtype == np.float32
        np.testing.assert_array_equal(space.low, -np.ones(4, np.float32))
        np.testing.assert_array_equal(space.high, np.ones(4, np.float32))
    finally:
        env.close()


def test_observation_space_is_dict_with_exactly_the_obs_bounds_keys(zero_episode):
    env, steps = zero_episode
    space = env.observation_space
    assert isinstance(space, spaces.Dict)
    assert set(space.spaces) == set(OBS_BOUNDS)
    for key, (size, _) in OBS_BOUNDS.items():
        sub = space[key]
        assert isinstance(sub, spaces.Box) and sub.dtype == np.float32 and sub.shape == (size,), key
    for i, (obs, *_) in enumerate(steps):
        assert set(obs) == set(OBS_BOUNDS), f"step {i}: keys {sorted(obs)}"


def test_every_observation_of_a_zero_action_episode_is_inside_the_space(zero_episode):
    env, steps = zero_episode
    for i, (obs, *_) in enumerate(steps):
        if not env.observation_space.contains(obs):
            bad = [k for k, v in obs.items() if not env.observation_space[k].contains(v)]
            pytest.fail(f"step {i}: observation outside the space for {bad}")


@pytest.mark.parametrize("action", [[1, 1, 1, 1], [-1, -1, -1, -1], [1, -1, 1, 0.5]])
def test_observations_stay_inside_the_space_under_saturated_actions(action):
    env = gym.make(ENV_ID)
    try:
        for i, (obs, *_) in enumerate(run_episode(env, np.array(action, np.float32))):
            assert env.observation_space.contains(obs), f"step {i}"
    finally:
        env.close()


def test_observation_holds_no_privileged_state(zero_episode):
    _, steps = zero_episode
    obs, *_, info = steps[-1]
    for key in PRIVILEGED_INFO_KEYS:
        assert key in info, f"{key} missing from info"
        assert key not in obs, f"privileged {key} leaked into the observation"


def test_zero_action_episode_terminates_with_finite_metrics(zero_episode):
    _, steps = zero_episode
    _, _, terminated, truncated, info = steps[-1]
    assert terminated and not truncated
    assert info["failure"] is None
    metrics = info["metrics"]
    for name in REQUIRED_METRICS:
        assert name in metrics, name
        assert math.isfinite(metrics[name]), f"{name}={metrics[name]}"
    for i, (*_, t, tr, _) in enumerate(steps[:-1]):
        assert not t and not tr, f"episode ended early at step {i}"


def test_step_info_has_stage_deflections_and_reward_terms_summing_to_reward(zero_episode):
    _, steps = zero_episode
    for i, (_, reward, _, _, info) in enumerate(steps[1:], start=1):
        assert info["stage"] in range(5), f"step {i}: stage={info['stage']}"
        assert np.shape(info["tip_deflection_robot_m"]) == (3,), f"step {i}"
        assert np.shape(info["tip_deflection_tool_m"]) == (3,), f"step {i}"
        terms = info["reward_terms"]
        assert terms, f"step {i}: empty reward_terms"
        assert math.isclose(sum(terms.values()), reward, rel_tol=1e-12, abs_tol=1e-12), f"step {i}: {terms} vs {reward}"
        assert math.isfinite(reward), f"step {i}"


def test_peak_force_reward_sums_to_minus_weight_times_the_episode_peak_and_is_off_by_default(zero_episode):
    _, default_steps = zero_episode
    assert all(info["reward_terms"]["peak_force"] == 0.0 for *_, info in default_steps[1:])
    w_peak, w_force = 5.0, 0.5
    env = gym.make(ENV_ID, reward_peak_force_weight=w_peak, reward_force_weight=w_force)
    try:
        steps = run_episode(env)
    finally:
        env.close()
    terms = [info["reward_terms"] for *_, info in steps[1:]]
    # the force term is -w_force x the step's mean lateral force: recover it independently of the peak term
    step_force_n = np.array([-t["force"] / w_force for t in terms])
    peak_terms = np.array([t["peak_force"] for t in terms])
    assert step_force_n.max() > 0.5, "the uncompensated paper hole should load the drill sideways"
    assert np.all(peak_terms <= 0.0)
    np.testing.assert_allclose(peak_terms.sum(), -w_peak * step_force_n.max(), rtol=1e-9)
    # it is paid only on the steps that raise the running maximum
    raised = step_force_n > np.maximum.accumulate(np.concatenate([[0.0], step_force_n[:-1]]))
    assert np.all(peak_terms[~raised] == 0.0) and np.all(peak_terms[raised] < 0.0)


def test_stages_appear_in_order_during_paper_scenario(zero_episode):
    _, steps = zero_episode
    infos = [info for *_, info in steps[1:]]
    drilling = [info["stage"] for info in infos if info["phase"] < 2]
    assert all(b >= a for a, b in itertools.pairwise(drilling)), drilling
    assert set(drilling) == {0, 1, 2, 3, 4}, f"stages seen before retract: {sorted(set(drilling))}"
    assert any(info["phase"] == 2 for info in infos), "no retract phase"


def test_step_after_termination_raises_and_reset_recovers():
    env = gym.make(ENV_ID)
    try:
        run_episode(env)
        with pytest.raises(RuntimeError):
            env.step(ZERO)
        env.reset(seed=1)
        obs, reward, terminated, truncated, _ = env.step(ZERO)
        assert not terminated and not truncated
        assert env.observation_space.contains(obs) and math.isfinite(reward)
    finally:
        env.close()


def test_force_limit_terminates_with_failure_and_metrics():
    env = gym.make(ENV_ID, force_limit_n=2.0)
    try:
        *_, (_, _, terminated, truncated, info) = run_episode(env)
        assert terminated and not truncated
        assert info["failure"] == "force_limit"
        assert "metrics" in info
        with pytest.raises(RuntimeError):
            env.step(ZERO)
    finally:
        env.close()


def test_slowest_feed_override_truncates_at_three_times_nominal_duration():
    env = gym.make(ENV_ID)
    try:
        *_, (_, _, terminated, truncated, info) = run_episode(env, np.array([0, 0, 0, -1], np.float32))
        assert truncated and not terminated
        assert info["t_s"] >= env.unwrapped.max_time_s
        assert "metrics" in info
    finally:
        env.close()


def test_after_retract_the_tip_is_out_of_the_bone_and_unloaded(zero_episode):
    env, steps = zero_episode
    obs, *_, info = steps[-1]
    tip = info["tip_pos_task_m"]
    beta = env.unwrapped.scenario.beta_rad
    assert tip[2] + tip[0] * math.tan(beta) < 0.0, f"tip {tip} not above the surface"
    assert info["stage"] == 0
    np.testing.assert_array_equal(info["force_true_n"], np.zeros(3))
    assert np.linalg.norm(obs["ft_wrench"][:3]) < 0.2, obs["ft_wrench"]  # noise only (0.02 N std per axis)


def test_reset_options_change_the_scenario_and_validate_it():
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0, options={"scenario": {"beta_deg": 10.0, "feed_mm_s": 1.0}})
        assert env.unwrapped.scenario.beta_deg == 10.0
        assert env.unwrapped.plan.feed_m_s == pytest.approx(1.0e-3)
        with pytest.raises(ValueError, match="beta_deg"):
            env.reset(seed=0, options={"scenario": {"beta_deg": 80.0}})
        env.reset(seed=0)  # no options: the scenario stays
        assert env.unwrapped.scenario.beta_deg == 10.0
    finally:
        env.close()


def test_a_first_reset_that_raises_leaves_gym_make_env_usable():
    # Gymnasium's passive checker (which gym.make adds) used to break here: the failed first reset left it
    # without the reset data its first step compares against (TypeError inside the checker).
    env = gym.make(ENV_ID, pybullet_world=False)
    try:
        for bad in ({"scenario": {"beta_deg": 80.0}}, {"scenario": {"no_such": 1}}, {"effects": ["x"]}, {"bogus": 1}):
            with pytest.raises((ValueError, TypeError)):
                env.reset(seed=0, options=bad)
        env.reset(seed=0)
        for _ in range(3):
            env.step(ZERO)
    finally:
        env.close()


def test_a_reset_that_raises_changes_nothing():
    env = gym.make(ENV_ID, pybullet_world=False)
    ref = gym.make(ENV_ID, pybullet_world=False)
    u = env.unwrapped
    try:
        env.reset(seed=1)
        ref.reset(seed=1)
        env.step(ZERO)
        ref.step(ZERO)
        backlash = {"effects": [build_effects("joint_backlash")[0]]}
        for bad in (
            {**backlash, "scenario": {"beta_deg": 80.0}},  # valid effects, invalid scenario: effects not switched
            {"scenario": {"feed_mm_s": 1.0}, "specimen_seed": -1},
        ):
            with pytest.raises(ValueError):
                env.reset(seed=5, options=bad)  # neither re-seeds nor rebuilds
        assert u.effects is None
        assert u.scenario == ref.unwrapped.scenario
        for _ in range(20):  # the episode under way goes on as if no reset had been tried
            oa, ra, *_ = env.step(ZERO)
            ob, rb, *_ = ref.step(ZERO)
            assert ra == rb
            for k in oa:
                np.testing.assert_array_equal(oa[k], ob[k], err_msg=k)
    finally:
        env.close()
        ref.close()


def test_reset_options_give_the_same_episode_as_a_fresh_env():
    a = gym.make(ENV_ID, beta_deg=20.0)
    b = gym.make(ENV_ID)
    try:
        a.reset(seed=3)
        b.reset(seed=3, options={"scenario": {"beta_deg": 20.0}})
        zero = np.zeros(4, np.float32)
        for _ in range(60):
            oa, ra, *_ = a.step(zero)
            ob, rb, *_ = b.step(zero)
            assert ra == rb
            for k in oa:
                np.testing.assert_array_equal(oa[k], ob[k], err_msg=k)
    finally:
        a.close()
        b.close()


def test_the_specimen_seed_option_keeps_the_specimen_and_changes_only_the_noise():
    env = gym.make(ENV_ID)
    u = env.unwrapped
    zero = np.zeros(4, np.float32)
    try:
        env.reset(seed=4)
        hardness_4 = u.specimen_hardness
        plain = [env.step(zero)[0]["ft_wrench"] for _ in range(5)]
        env.reset(seed=4, options={"specimen_seed": 4})  # its own seed: the plain episode, bit for bit
        assert u.specimen_hardness == hardness_4
        for a, b in zip(plain, [env.step(zero)[0]["ft_wrench"] for _ in range(5)], strict=True):
            np.testing.assert_array_equal(a, b)
        env.reset(seed=9, options={"specimen_seed": 4})  # seed 4's specimen under seed 9's noise
        assert u.specimen_hardness == hardness_4
        noisy = [env.step(zero)[0]["ft_wrench"] for _ in range(5)]
        env.reset(seed=9)
        assert u.specimen_hardness != hardness_4
        for a, b in zip(noisy, [env.step(zero)[0]["ft_wrench"] for _ in range(5)], strict=True):
            np.testing.assert_array_equal(a, b)  # before contact the readings are noise only: seed 9's
        for bad in (-1, 1.5, True, "3"):
            with pytest.raises(ValueError, match="specimen_seed"):
                env.reset(seed=0, options={"specimen_seed": bad})
    finally:
        env.close()


def test_the_rollout_hands_a_controller_its_plan_and_matches_the_benchmark():
    from drillgym.controllers import make_controller
    from drillgym.controllers.rollout import run_episode as rollout
    from drillgym.eval.bench.episode import run_controller_episode

    env = gym.make(ENV_ID)
    result = rollout(env, make_controller("li2023_slow_entry"), seed=3, keep_trace=False)
    bench = run_controller_episode(env, make_controller("li2023_slow_entry"), seed=3)
    env.close()
    for name, value in result.metrics.items():
        assert value == bench[name] or (np.isnan(value) and np.isnan(bench[name])), name


def test_the_rollout_reports_steps_end_time_and_the_failure():
    from drillgym.controllers.rollout import run_episode as rollout

    env = gym.make(ENV_ID, force_limit_n=2.0)
    try:
        result = rollout(env, None, seed=0, keep_trace=False)
    finally:
        env.close()
    assert result.failure == "force_limit"
    assert result.steps > 0 and result.sim_time_s == pytest.approx(result.steps * 0.05)
    row = result.row()
    assert row["failure"] == "force_limit" and row["steps"] == result.steps
    assert result.info["failure"] == "force_limit" and not result.trace
