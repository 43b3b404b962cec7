"""The schedule residual: the base's tuning set once per hole from the plan, trained one hole per step."""

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import (
    SCHEDULE_SPANS,
    PlanScheduledController,
    ScheduleSpec,
    base_fields,
    normalized_plan,
)
from drillgym.controllers.rollout import run_episode
from drillgym.training.config import TrainConfig
from drillgym.training.domain_randomization import training_plan_support
from drillgym.training.schedule_env import ScheduleEnv, ScheduleReward, paired_schedule_reward

ENV_ID = "drillgym/UR5BoneDrill-v1"


def test_base_fields_fill_in_the_preset_and_the_defaults():
    name, values = base_fields("li2023_tuned")
    assert name == "li2023"
    assert values["kp"] == 3.0 and values["y_gain"] == 1.3 and values["ki"] == 0.25  # preset, preset, default
    assert values["entry_feed_scale"] == 0.45 and values["entry_depth_mm"] == 1.25
    assert base_fields("li2023_tuned:kp=2")[1]["kp"] == 2.0  # the user's field over the preset's


def test_a_schedule_action_multiplies_each_field_by_a_power_of_two_within_its_range():
    spec = ScheduleSpec("li2023_tuned")
    assert spec.values(np.zeros(4)) == {"kp": 3.0, "y_gain": 1.3, "entry_feed_scale": 0.45, "entry_depth_mm": 1.25}
    up = spec.values(np.array([1.0, -1.0, 0.5, 2.0]))  # the last is clipped to 1
    assert up["kp"] == pytest.approx(3.0 * 2**0.5)
    assert up["y_gain"] == pytest.approx(1.3 * 2**-0.4)
    assert up["entry_feed_scale"] == pytest.approx(0.45 * 2**0.5)
    assert up["entry_depth_mm"] == pytest.approx(2.5)
    # the entry feed never speeds up and never falls below the env's slowest feed override
    wide = ScheduleSpec("li2023:entry_feed_scale=0.8,entry_depth_mm=1", {"entry_feed_scale": 2.0})
    assert wide.values(np.array([1.0]))["entry_feed_scale"] == 1.0
    assert wide.values(np.array([-1.0]))["entry_feed_scale"] == pytest.approx(0.25)
    assert spec.controller_spec(np.zeros(4)).startswith("li2023_tuned:kp=3,y_gain=1.3,")
    # a field the base spec already sets is replaced, not repeated
    over = ScheduleSpec("li2023_tuned:kp=2,ki=0.3", {"kp": 0.5})
    assert over.controller_spec(np.array([1.0])) == f"li2023_tuned:kp={2 * 2**0.5:.6g},ki=0.3"


def test_bad_schedules_are_clear_errors():
    with pytest.raises(ValueError, match="no numeric field 'gain'"):
        ScheduleSpec("li2023", {"gain": 0.5})
    with pytest.raises(ValueError, match=r"must be in \(0, 3\]"):
        ScheduleSpec("li2023", {"kp": 0.0})
    with pytest.raises(ValueError, match="entry_depth_mm = 0 cannot be scaled"):  # plain li2023 has no slow entry
        ScheduleSpec("li2023")
    with pytest.raises(ValueError, match="classical base controller"):
        ScheduleSpec("residual:shipped")
    with pytest.raises(ValueError, match="NaN"):
        ScheduleSpec().values(np.array([0.0, np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match=r"shape \(4,\)"):
        ScheduleSpec().values(np.zeros(3))


def test_the_plan_is_scaled_to_plus_minus_one_across_the_training_ranges_and_clamped_outside():
    support = training_plan_support()
    env = gym.make(
        ENV_ID, beta_deg=15.0, feed_mm_s=1.0, stickout_mm=48.0, cortical_thickness_mm=6.5, bone="sawbones_20pcf"
    )
    env.reset(seed=0)
    x = normalized_plan(env.unwrapped.plan, support)
    env.close()
    # β at the low edge, feed at the high edge, stick-out beyond it (clamped), cortex in the middle, the softest bone
    np.testing.assert_allclose(x, [-1.0, 1.0, 1.0, 0.0, -1.0], atol=1e-5)


def test_a_zero_schedule_is_the_base_controller_exactly():
    env = gym.make(ENV_ID)
    base = run_episode(env, make_controller("li2023_tuned"), seed=4, keep_trace=False)
    tuned = run_episode(env, PlanScheduledController(ScheduleSpec("li2023_tuned")), seed=4, keep_trace=False)
    env.close()
    assert tuned.metrics == base.metrics and tuned.steps == base.steps


def test_the_controller_applies_the_policys_tuning_for_the_hole():
    seen = []

    def policy(plan):
        seen.append(plan)
        return np.array([-1.0, 0.0, 0.0, 1.0])

    controller = PlanScheduledController(ScheduleSpec("li2023_tuned"), policy)
    env = gym.make(ENV_ID)
    tuned = run_episode(env, controller, seed=4, keep_trace=False)
    same = run_episode(env, make_controller("li2023_tuned:kp=2.12132,entry_depth_mm=2.5"), seed=4, keep_trace=False)
    env.close()
    assert len(seen) == 1 and seen[0].shape == (5,)  # asked once, before the hole
    assert controller.describe()["config"]["values"]["kp"] == pytest.approx(3 / 2**0.5)
    assert tuned.metrics["deviation_mean_mm"] == pytest.approx(same.metrics["deviation_mean_mm"], rel=1e-4)


def test_the_paired_hole_reward_charges_deviation_a_higher_peak_and_a_much_longer_drill():
    base = {"deviation_mean_mm": 0.04, "lateral_force_max_n": 1.0, "drill_time_s": 15.0}
    w = ScheduleReward()
    assert paired_schedule_reward(base, base, w) == 0.0
    lower = {**base, "deviation_mean_mm": 0.035}
    assert paired_schedule_reward(lower, base, w) == pytest.approx(0.005 / 0.05)
    softer = {**base, "lateral_force_max_n": 0.8}  # a lower peak earns nothing
    assert paired_schedule_reward(softer, base, w) == 0.0
    harder = {**lower, "lateral_force_max_n": 1.02}
    assert paired_schedule_reward(harder, base, w) == pytest.approx(0.1 - 3 * 0.02)
    slower = {**base, "drill_time_s": 15.0 * 1.5}  # +50 %: 30 points beyond the free 20
    assert paired_schedule_reward(slower, base, w) == pytest.approx(-2 * 0.3)
    assert paired_schedule_reward({**base, "deviation_mean_mm": float("nan")}, base, w) == -10.0


def test_the_schedule_env_pays_zero_for_the_base_and_the_paired_difference_otherwise():
    spec = ScheduleSpec("li2023_tuned", plan_support=training_plan_support())
    env = ScheduleEnv(spec, paper_share=0.5)
    obs, info = env.reset(seed=1)
    assert obs.shape == (5,) and np.all(np.abs(obs) <= 1.0)
    _, reward, terminated, _, info0 = env.step(np.zeros(4, np.float32))
    assert reward == 0.0 and terminated and info0["metrics"] == info0["base"]
    env.reset()
    action = np.array([-0.5, 0.3, 0.2, 0.1], np.float32)
    _, reward, _, _, info = env.step(action)
    # the same hole drilled outside the env, by both controllers
    sim = gym.make(ENV_ID)
    opts = {"scenario": info["scenario"]}
    agent = run_episode(sim, make_controller(info["tuned_spec"]), info["episode_seed"], keep_trace=False, options=opts)
    base = run_episode(sim, make_controller("li2023_tuned"), info["episode_seed"], keep_trace=False, options=opts)
    sim.close()
    env.close()
    assert agent.metrics == info["metrics"] and base.metrics == info["base"]
    assert reward == pytest.approx(paired_schedule_reward(agent.metrics, base.metrics, ScheduleReward()))
    assert reward != 0.0


def test_a_seeded_schedule_env_replays_the_same_holes_and_fixed_episodes_cycle():
    spec = ScheduleSpec("li2023_tuned", plan_support=training_plan_support())
    a, b = ScheduleEnv(spec), ScheduleEnv(spec)
    draws = []
    for env in (a, b):
        env.reset(seed=7)
        _, info = env.reset()
        draws.append((info["scenario"], info["episode_seed"]))
    assert draws[0] == draws[1]
    fixed = ScheduleEnv(spec, episodes=[({"beta_deg": 20.0}, 11), ({}, 12)])
    seeds = [fixed.reset()[1]["episode_seed"] for _ in range(3)]
    assert seeds == [11, 12, 11]
    for env in (a, b, fixed):
        env.close()


def test_schedule_configs_are_checked():
    with pytest.raises(ValueError, match="normalize_obs: false"):
        TrainConfig(residual_mode="schedule", base="li2023_tuned")
    with pytest.raises(ValueError, match="unknown weight"):
        TrainConfig(residual_mode="schedule", normalize_obs=False, base="li2023_tuned", schedule_reward={"force": 1.0})
    with pytest.raises(ValueError, match="no numeric field"):
        TrainConfig(residual_mode="schedule", normalize_obs=False, base="li2023_tuned", schedule_spans={"kd_gain": 1.0})
    cfg = TrainConfig(residual_mode="schedule", normalize_obs=False, base="li2023_tuned")
    assert cfg.schedule and cfg.schedule_spec().spans == SCHEDULE_SPANS


def test_a_tiny_schedule_run_exports_a_policy_that_tunes_each_hole(tmp_path):
    from drillgym.eval.cli import main

    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(
        "base: li2023_tuned\nresidual_mode: schedule\nnormalize_obs: false\ntotal_timesteps: 40\nn_envs: 1\n"
        "learning_starts: 10\nbatch_size: 8\nnet_arch: [8]\neval_freq: 20\neval_episodes: 2\n"
        "eval_scenarios: validation\ncheckpoint_freq: 20\nmodel_selection: deviation\ngamma: 0.0\n"
    )
    out = tmp_path / "run"
    assert main(["train", "--config", str(cfg), "--out", str(out)]) == 0
    controller = make_controller(f"residual:{out / 'policy.zip'}")
    assert isinstance(controller, PlanScheduledController)
    env = gym.make(ENV_ID)
    result = run_episode(env, controller, seed=0, keep_trace=False)
    env.close()
    assert np.isfinite(result.metrics["deviation_mean_mm"])
    assert set(controller.describe()["config"]) >= {"path", "residual_mode", "base"}
    # the schedule map: what the policy sets for each scenario's plan (a classical run is left out)
    from drillgym.eval.learning.schedule_map import plot_schedule_map, schedule_table

    table = schedule_table({"seed0": f"residual:{out / 'policy.zip'}", "li2023": "li2023"}, ["paper", "heldout"])
    assert len(table) == 9 and set(table["run"]) == {"seed0"}
    paper = table[table["scenario"] == "paper"].iloc[0]
    assert paper["kp"] == pytest.approx(controller.spec.values(controller.action)["kp"], rel=1e-6)  # it drilled paper
    assert paper["base_kp"] == 3.0 and paper["base_entry_depth_mm"] == 1.25
    plot_schedule_map(table, tmp_path / "map.png")
    assert (tmp_path / "map.png").stat().st_size > 1000


def test_the_shipped_policy_is_a_schedule_that_tunes_the_paper_hole_within_its_spans():
    controller = make_controller("residual:shipped")
    assert isinstance(controller, PlanScheduledController)
    env = gym.make(ENV_ID)
    result = run_episode(env, controller, seed=0, keep_trace=False)
    env.close()
    values = controller.spec.values(controller.action)
    _, base = base_fields("li2023_tuned")
    for field, span in controller.spec.spans.items():
        assert base[field] * 2**-span - 1e-9 <= values[field] <= base[field] * 2**span + 1e-9, field
    assert np.any(controller.action != 0.0)  # it changes the paper hole's tuning
    assert result.metrics["deviation_mean_mm"] < 0.1 and not result.failure


def test_a_schedule_run_is_evaluated_on_fixed_holes():
    from drillgym.envs.seeds import Purpose, episode_seed
    from drillgym.training.env_factory import EVAL_SEED, make_eval_vec_env
    from drillgym.training.selection import validation_episodes

    kw = {"residual_mode": "schedule", "normalize_obs": False, "base": "li2023_tuned"}
    cfg = TrainConfig(**kw, eval_episodes=3, eval_scenarios="validation")
    venv = make_eval_vec_env(cfg)  # one batch slot per hole, each visiting its own
    assert venv.num_envs == 3
    assert [slot.episodes for slot in venv.venv.here.holes] == [validation_episodes(cfg)[:3]] * 3
    assert [(slot.first, slot.stride) for slot in venv.venv.here.holes] == [(0, 3), (1, 3), (2, 3)]
    venv.close()
    cfg = TrainConfig(**kw, eval_episodes=2, eval_scenarios="paper")
    venv = make_eval_vec_env(cfg)
    select = [episode_seed(Purpose.SELECT, EVAL_SEED + i) for i in range(2)]
    assert venv.venv.here.holes[0].episodes == [({}, select[0]), ({}, select[1])]
    venv.close()
