"""Residual RL: wrapper arithmetic, zero start, save/load, a smoke run, the shipped policy."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.controllers.residual import BASE_ACTION_KEY, PLAN_KEY, PREV_RESIDUAL_KEY, combine, plan_support
from drillgym.training.config import TrainConfig, load_config
from drillgym.training.domain_randomization import TRAINING_BONES, merged_ranges
from drillgym.training.env_factory import make_train_vec_env
from drillgym.training.model import build_model
from drillgym.training.residual_wrapper import ResidualWrapper

ENV_ID = "drillgym/UR5BoneDrill-v1"
SHIPPED = Path(__file__).resolve().parents[2] / "training" / "policies" / "residual_li2023_sac.zip"


def test_combine_adds_the_scaled_residual_and_clips():
    base = np.array([0.2, -0.9, 0.0, 0.1], np.float32)
    # lateral residual: task x, y turned into base axes (x_task = +y_base, y_task = +x_base here)
    from drillgym.envs.cell_params import R_BASE_TASK

    lat = combine(base, np.array([0.4, -0.2]), 0.5, R_BASE_TASK)
    np.testing.assert_allclose(lat, [0.1, -0.7, 0.0, 0.1], atol=1e-6)
    out = combine(base, np.array([1.0, -1.0, 0.5]), 0.5)
    np.testing.assert_allclose(out, [0.7, -1.0, 0.25, 0.1], atol=1e-6)  # feed untouched by a 3-d residual
    out4 = combine(base, np.array([0.0, 0.0, 0.0, -1.0]), 0.5)
    np.testing.assert_allclose(out4[3], -0.4, atol=1e-6)
    # a feed residual only slows the base's feed: a positive one leaves it as it is
    out4_up = combine(base, np.array([0.0, 0.0, 0.0, 1.0]), 0.5)
    np.testing.assert_allclose(out4_up[3], base[3], atol=1e-7)
    # the residual is clipped to [-1, 1] before scaling, the sum to the action box
    np.testing.assert_allclose(combine(base, np.array([9.0, 9.0, 9.0]), 1.0)[:3], [1.0, 0.1, 1.0], atol=1e-6)


def test_a_nominal_feed_ceiling_lets_the_residual_undo_a_base_slowdown_but_not_pass_the_plan_feed():
    slowed = np.array([0.0, 0.0, 0.0, -0.6], np.float32)  # base at 2^-1.2 of the plan's feed
    up = combine(slowed, np.array([0.0, 0.0, 1.0]), 0.5, np.eye(3), feed_ceiling="nominal")
    np.testing.assert_allclose(up[3], -0.1, atol=1e-6)  # sped up by the whole residual
    capped = combine(slowed, np.array([0.0, 0.0, 1.0]), 1.0, np.eye(3), feed_ceiling="nominal")
    np.testing.assert_allclose(capped[3], 0.0, atol=1e-7)  # never past the plan's feed
    down = combine(slowed, np.array([0.0, 0.0, -1.0]), 0.5, np.eye(3), feed_ceiling="nominal")
    np.testing.assert_allclose(down[3], -1.0, atol=1e-6)
    fast = np.array([0.0, 0.0, 0.0, 0.3], np.float32)  # a base above the plan's feed is its own ceiling
    np.testing.assert_allclose(combine(fast, np.array([0.0, 0.0, 1.0]), 0.5, np.eye(3), feed_ceiling="nominal")[3], 0.3)
    with pytest.raises(ValueError, match="feed ceiling"):
        combine(fast, np.zeros(3), 0.5, np.eye(3), feed_ceiling="faster")


def test_a_gain_residual_scales_the_base_correction_per_task_axis():
    from drillgym.envs.cell_params import R_BASE_TASK

    base = np.array([0.2, -0.9, 0.05, 0.1], np.float32)  # task x = base y = -0.9, task y = base x = 0.2
    out = combine(base, np.array([-0.5, 1.0]), 0.5, R_BASE_TASK, mode="gain")
    np.testing.assert_allclose(out, [0.3, -0.675, 0.05, 0.1], atol=1e-6)
    np.testing.assert_allclose(combine(base, np.zeros(2), 1.0, R_BASE_TASK, mode="gain"), base, atol=1e-7)
    cancelled = combine(base, -np.ones(2), 1.0, R_BASE_TASK, mode="gain")
    np.testing.assert_allclose(cancelled, [0.0, 0.0, 0.05, 0.1], atol=1e-7)  # only the across-drill part
    np.testing.assert_allclose(combine(base, np.array([1.0, 0.0, -1.0]), 0.5, mode="gain")[:3], [0.3, -0.9, 0.025])
    with pytest.raises(ValueError, match="mode"):
        combine(base, np.zeros(2), 0.5, R_BASE_TASK, mode="multiply")


@pytest.mark.parametrize(("mode", "scale"), [("add", 0.5), ("gain", 1.0)])
def test_zero_residual_reproduces_the_base_controller_exactly(mode, scale):
    wrapped = ResidualWrapper(gym.make(ENV_ID), "li2023", scale, mode=mode)
    plain = gym.make(ENV_ID)
    base = make_controller("li2023")
    obs_w, _ = wrapped.reset(seed=1)
    obs_p, _ = plain.reset(seed=1)
    base.set_plan(plain.unwrapped.plan)
    start = True
    for _ in range(120):
        a, _ = base.predict(obs_p, episode_start=np.array([start]))
        start = False
        np.testing.assert_array_equal(obs_w[BASE_ACTION_KEY], a)
        obs_w, rw, *_ = wrapped.step(np.zeros(2, np.float32))
        obs_p, rp, *_ = plain.step(a)
        assert rw == rp
    wrapped.close()
    plain.close()


def test_wrapper_rejects_nan_and_wrong_shape_residuals():
    env = ResidualWrapper(gym.make(ENV_ID))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0], np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, np.float32))
    env.close()


@pytest.mark.parametrize("algo", ["sac", "td3", "ppo"])
def test_initial_policy_outputs_zero_residual(algo):
    cfg = TrainConfig(algo=algo, n_envs=1, net_arch=[16], n_steps=64, batch_size=32, learning_starts=10)
    venv = make_train_vec_env(cfg)
    model = build_model(cfg, venv)
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    np.testing.assert_array_equal(action, np.zeros_like(action))
    venv.close()


@pytest.mark.parametrize(
    ("algo", "warmup", "frozen"), [("sac", 10_000, True), ("sac", 0, False), ("td3", 10_000, True)]
)
def test_critic_warmup_keeps_the_residual_at_zero_while_the_critic_learns(algo, warmup, frozen):
    import torch

    cfg = TrainConfig(
        algo=algo, n_envs=1, net_arch=[16], batch_size=32, learning_starts=20, actor_warmup_steps=warmup, seed=3
    )
    venv = make_train_vec_env(cfg)
    model = build_model(cfg, venv)
    actor0 = [p.detach().clone() for p in model.actor.parameters()]
    critic0 = [p.detach().clone() for p in model.critic.parameters()]
    model.learn(total_timesteps=120)
    same = lambda a, b: all(torch.equal(x, y) for x, y in zip(a, b, strict=True))  # noqa: E731
    assert not same(critic0, list(model.critic.parameters()))  # the critic learned either way
    assert same(actor0, list(model.actor.parameters())) == frozen
    if frozen:
        action, _ = model.predict(venv.reset(), deterministic=True)
        np.testing.assert_array_equal(action, np.zeros_like(action))
    venv.close()


def test_policy_sees_its_previous_residual_reset_to_zero_at_each_episode():
    assert PREV_RESIDUAL_KEY not in ResidualWrapper(gym.make(ENV_ID)).observation_space.spaces  # off by default
    env = ResidualWrapper(gym.make(ENV_ID), "li2023", 0.5, observe_prev_residual=True)
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs[PREV_RESIDUAL_KEY], [0.0, 0.0])
    obs, *_ = env.step(np.array([0.3, -2.0], np.float32))
    np.testing.assert_allclose(obs[PREV_RESIDUAL_KEY], [0.3, -1.0])  # clipped as applied
    obs, _ = env.reset(seed=1)
    np.testing.assert_array_equal(obs[PREV_RESIDUAL_KEY], [0.0, 0.0])
    env.close()


def test_config_yaml_overrides_and_rejects_typos(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("algo: td3\ntotal_timesteps: 123\n")
    cfg = load_config(p, {"seed": 7})
    assert (cfg.algo, cfg.total_timesteps, cfg.seed) == ("td3", 123, 7)
    p.write_text("learning_rat: 0.1\n")
    with pytest.raises(ValueError, match="learning_rat"):
        load_config(p)
    with pytest.raises(ValueError, match="algo"):
        TrainConfig(algo="dqn")


def test_smoke_training_run_saves_a_policy_that_loads_and_resumes(tmp_path):
    from drillgym.eval.cli import main

    cfg = Path(__file__).resolve().parents[2] / "training" / "configs" / "smoke.yaml"
    out = tmp_path / "run"
    assert main(["train", "--config", str(cfg), "--out", str(out)]) == 0
    for name in ("policy.zip", "policy.json", "policy.vecnormalize.pkl", "training_curves.png", "summary.json"):
        assert (out / name).exists(), name
    assert list((out / "checkpoints").glob("rl_model_*_steps.zip"))
    # resume to a larger budget continues from the checkpoint instead of starting over
    assert main(["train", "--out", str(out), "--resume", "--timesteps", "900"]) == 0
    import json

    assert json.loads((out / "summary.json").read_text())["timesteps"] >= 900
    controller = make_controller(f"residual:{out / 'policy.zip'}")
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    controller.set_plan(env.unwrapped.plan)
    action, _ = controller.predict(obs, episode_start=np.array([True]))
    assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
    env.close()


def test_missing_policy_file_is_a_clear_error():
    with pytest.raises(FileNotFoundError, match="does not exist"):
        make_controller("residual:/nonexistent/policy.zip")


@pytest.mark.skipif(not SHIPPED.exists(), reason="no shipped policy")
def test_shipped_policy_completes_an_episode_from_real_cell_signals_only():
    from drillgym.controllers.rollout import run_episode

    controller = make_controller(f"residual:{SHIPPED}")
    env = gym.make(ENV_ID)
    result = run_episode(env, controller, seed=0)
    env.close()
    assert np.isfinite(result.metrics["deviation_mean_mm"])
    # the policy's inputs are the env observation keys (real-cell signals) plus the base action
    keys = set(controller.policy.bundle.policy.observation_space.spaces)
    extra = {BASE_ACTION_KEY} | ({PREV_RESIDUAL_KEY} if controller.spec.observe_prev_residual else set())
    extra |= {PLAN_KEY} if controller.spec.observe_plan else set()
    assert keys == set(env.observation_space.spaces) | extra


def test_saved_policy_acts_through_the_controller_exactly_as_in_its_training_wrapper(tmp_path):
    import torch

    from drillgym.training.policy_bundle import save_bundle

    cfg = TrainConfig(
        n_envs=1, net_arch=[16], observe_prev_residual=True, observe_plan=True, normalize_obs=False, seed=5
    )
    venv = make_train_vec_env(cfg)
    model = build_model(cfg, venv)
    with torch.no_grad():  # a policy that is not zero, and depends on its previous residual
        torch.manual_seed(0)
        for p in model.actor.parameters():
            p.add_(0.3 * torch.randn_like(p))
    model.save(tmp_path / "m.zip")
    save_bundle(tmp_path / "m.zip", None, cfg, {}, tmp_path / "p.zip")
    venv.close()

    controller = make_controller(f"residual:{tmp_path / 'p.zip'}")
    wrapped = ResidualWrapper(
        gym.make(ENV_ID), cfg.base, cfg.residual_scale, observe_prev_residual=True, observe_plan=True
    )
    plain = gym.make(ENV_ID)
    obs_w, _ = wrapped.reset(seed=2)
    obs_p, _ = plain.reset(seed=2)
    controller.set_plan(plain.unwrapped.plan)
    start, residuals = True, []
    for _ in range(80):
        residual, _ = model.predict(obs_w, deterministic=True)
        action, _ = controller.predict(obs_p, episode_start=np.array([start]))
        start = False
        obs_w, *_ = wrapped.step(residual)
        np.testing.assert_allclose(action, wrapped.unwrapped.prev_action, atol=1e-6)  # what the env was sent
        obs_p, *_ = plain.step(action)
        residuals.append(residual)
    assert np.ptp(np.array(residuals), axis=0).max() > 0.01  # the residual did vary
    wrapped.close()
    plain.close()


def test_validation_scenarios_are_held_in_and_visited_once_per_evaluation():
    from drillgym.eval.bench.suites import outside_training
    from drillgym.training.domain_randomization import ScenarioCycle, validation_scenarios

    scenarios = validation_scenarios(6)
    assert scenarios[0] == {} and len(scenarios) == 6 and validation_scenarios(6) == scenarios
    for kw in scenarios:
        assert outside_training(kw) == [], kw  # inside the training ranges
    env = ScenarioCycle(gym.make(ENV_ID), scenarios[1:3], seeds=[7, 8])
    seen, first_obs = [], []
    for _ in range(4):
        _, info = env.reset()
        seen.append(info["scenario"])
        first_obs.append(env.step(np.zeros(4, np.float32))[0]["ft_wrench"])  # noisy F/T reading
    assert seen == [scenarios[1], scenarios[2], scenarios[1], scenarios[2]]
    assert env.unwrapped.scenario.beta_deg == scenarios[2]["beta_deg"]
    np.testing.assert_array_equal(first_obs[0], first_obs[2])  # the same episode replayed (same noise)
    assert not np.array_equal(first_obs[0], first_obs[1])
    env.close()


def test_the_paper_validation_episode_is_the_paper_scenario_even_after_other_draws():
    from drillgym.envs.scenario import Scenario
    from drillgym.training.domain_randomization import ScenarioCycle, validation_scenarios

    scenarios = validation_scenarios(3)
    env = ScenarioCycle(gym.make(ENV_ID), scenarios, seeds=[1, 2, 3])
    for _ in range(4):  # paper, draw, draw, paper again
        env.reset()
    assert env.unwrapped.scenario == Scenario()
    env.close()


def test_extra_randomisation_ranges_reach_training_and_validation_draws():
    from drillgym.training.domain_randomization import DomainRandomization, merged_ranges, validation_scenarios

    cfg = TrainConfig(dr_ranges={"density_scale": [0.9, 1.1]})
    ranges = merged_ranges(cfg.dr_ranges)
    assert ranges["density_scale"] == (0.9, 1.1) and ranges["beta_deg"] == (15.0, 35.0)
    draws = [s["density_scale"] for s in validation_scenarios(8, ranges=ranges)[1:]]
    assert all(0.9 <= d <= 1.1 for d in draws) and np.ptp(draws) > 0.05
    env = DomainRandomization(gym.make(ENV_ID), ranges)
    env.reset(seed=3)
    assert env.unwrapped.scenario.density_scale == env.current["density_scale"] != 1.0
    env.close()


def test_a_paper_share_drills_that_share_of_episodes_in_the_paper_scenario_and_draws_the_rest():
    from drillgym.training.domain_randomization import DomainRandomization

    env = DomainRandomization(gym.make(ENV_ID), paper_share=0.5)
    paper = gym.make(ENV_ID).unwrapped.scenario.to_dict()
    kinds = []
    for k in range(40):
        env.reset(seed=7 if k == 0 else None)
        kinds.append(env.unwrapped.scenario.to_dict() == paper)
    assert 12 <= sum(kinds) <= 28 and not all(kinds)  # about half (binomial 40 x 0.5: 12-28 is beyond 3 SD)
    with pytest.raises(ValueError, match="paper_share"):
        TrainConfig(paper_share=1.5)
    env.close()


@pytest.mark.parametrize(
    ("ranges", "message"),
    [
        ({"hardness": [0.9, 1.1]}, "not a numeric scenario argument"),
        ({"bone": [0.9, 1.1]}, "not a numeric scenario argument"),
        ({"density_scale": [1.1, 0.9]}, "low <= high"),
        ({"density_scale": 1.0}, "must be [low, high]"),
        ({"density_scale": [0.1, 1.0]}, "density_scale"),
    ],
)
def test_bad_randomisation_ranges_are_rejected_with_a_clear_message(ranges, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        TrainConfig(dr_ranges=ranges)


@pytest.mark.parametrize(
    ("bone", "hardness"), [("buffalo_femur", 1.0), ("porcine_femur", 0.75), ("sawbones_20pcf", 0.6)]
)
def test_plan_features_are_what_the_plan_says_in_si_units(bone, hardness):
    env = ResidualWrapper(
        gym.make(ENV_ID, beta_deg=20.0, feed_mm_s=0.8, stickout_mm=33.0, bone=bone), observe_plan=True
    )
    obs, _ = env.reset(seed=0)
    thickness_m = env.unwrapped.plan.cortical_thickness_m
    # the hardness is the named preset's nominal one (the BONE_PRESETS table), not the episode's drawn specimen
    np.testing.assert_allclose(obs[PLAN_KEY], [np.radians(20.0), 0.8e-3, 33e-3, thickness_m, hardness], rtol=1e-6)
    assert env.observation_space[PLAN_KEY].contains(obs[PLAN_KEY])
    env.close()


def test_the_plan_outside_the_training_ranges_is_clamped_to_their_edges():
    # 48 mm of drill and Sawbones (hardness 0.6) lie outside 30-42 mm and the training bones' 0.75-1.0;
    # beta 20 deg and feed 0.8 mm/s lie inside and pass unchanged
    support = plan_support(merged_ranges({"stickout_mm": [30.0, 42.0]}), TRAINING_BONES)
    env = ResidualWrapper(
        gym.make(ENV_ID, beta_deg=20.0, feed_mm_s=0.8, stickout_mm=48.0, bone="sawbones_20pcf"),
        observe_plan=True,
        plan_support=support,
    )
    obs, _ = env.reset(seed=0)
    thickness_m = env.unwrapped.plan.cortical_thickness_m
    np.testing.assert_allclose(obs[PLAN_KEY], [np.radians(20.0), 0.8e-3, 42e-3, thickness_m, 0.75], rtol=1e-6)
    env.close()


def test_the_shipped_policy_clamps_the_plan_as_its_training_did():
    ctl = make_controller(f"residual:{SHIPPED}")
    low, high = ctl.spec.plan_support
    assert low[2] == pytest.approx(30e-3) and high[2] == pytest.approx(42e-3)  # stick-out (m)
    assert low[4] == pytest.approx(0.75) and high[4] == pytest.approx(1.0)  # porcine .. buffalo


def test_resuming_nothing_and_overwriting_a_run_by_accident_are_errors(tmp_path, capsys):
    from drillgym.eval.cli import main

    empty = tmp_path / "empty"
    assert main(["train", "--out", str(empty), "--resume"]) == 2
    assert "nothing to resume" in capsys.readouterr().err
    held = tmp_path / "held"
    (held / "checkpoints").mkdir(parents=True)
    (held / "config.yaml").write_text("algo: sac\n")
    assert main(["train", "--out", str(held)]) == 2
    err = capsys.readouterr().err
    assert "already holds a training run" in err and "--overwrite" in err and "--resume" in err
    assert main(["train", "--out", str(held), "--resume", "--overwrite"]) == 2
    assert (held / "config.yaml").read_text() == "algo: sac\n"  # nothing was touched


def test_shipped_policies_and_configs_are_found_by_name_from_any_directory(tmp_path, monkeypatch):
    from drillgym.training.config import load_config
    from drillgym.training.policy_bundle import NAMED_POLICIES, resolve_policy

    monkeypatch.chdir(tmp_path)
    assert resolve_policy("shipped").exists()
    for name in NAMED_POLICIES:
        assert resolve_policy(name).exists(), name
    c = make_controller("residual:shipped")
    assert Path(c.describe()["config"]["path"]).is_absolute()
    assert (
        load_config("smoke").total_timesteps
        == load_config(Path(SHIPPED).parents[1] / "configs" / "smoke.yaml").total_timesteps
    )
    with pytest.raises(ValueError, match=r"shipped config: .*smoke"):
        load_config("smok")
    with pytest.raises(FileNotFoundError, match="shipped policies by name"):
        make_controller("residual:nosuch.zip")
