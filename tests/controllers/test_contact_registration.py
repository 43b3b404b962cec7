"""Contact registration: where the tool first touches, what it changes (nothing in a true cell), what it fixes."""

import math

import gymnasium as gym
import numpy as np
import pytest
from cell_plan import plan_at_entry

from drillgym.controllers import make_controller
from drillgym.controllers.contact_registration import ContactRegistered, first_touch_depth_m
from drillgym.controllers.rollout import run_episode, run_episodes
from drillgym.envs.effects import build_effects
from drillgym.envs.errors import UserError
from drillgym.envs.seeds import Purpose, episode_seed

SEEDS = [episode_seed(Purpose.TUNE, 900 + k) for k in range(2)]


@pytest.mark.parametrize("beta_deg", [0.0, 20.0, 30.0, 35.0, 40.0])
def test_first_touch_depth_is_where_a_sampled_lip_first_meets_the_inclined_surface(beta_deg):
    plan = plan_at_entry(beta_deg=beta_deg, drill_diameter_mm=1.5)
    r, kappa, beta = 0.75e-3, math.radians(59.0), math.radians(beta_deg)
    x = np.linspace(-r, r, 20001)  # both lips, across the plane of inclination
    lip_behind_tip = np.abs(x) / math.tan(kappa)
    surface = -x * math.tan(beta)  # task z of the surface: closer (lower z) uphill, +x
    # a lip point |x| cot κ behind the tip reaches the surface once the tip is at depth surface + that: the first one
    touch = float(np.min(surface + lip_behind_tip))
    assert first_touch_depth_m(plan) == pytest.approx(touch, abs=1e-9)


def _episode_actions(spec: str, seed: int, **scenario) -> np.ndarray:
    env = gym.make("drillgym/UR5BoneDrill-v1", pybullet_world=False, **scenario)
    controller = make_controller(spec)
    obs, _ = env.reset(seed=seed)
    controller.set_plan(env.unwrapped.plan)
    actions = []
    while True:
        action, _ = controller.predict(obs)
        actions.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            return np.array(actions)


@pytest.mark.parametrize(
    "scenario", [{}, {"beta_deg": 40.0, "feed_mm_s": 0.8}, {"beta_deg": -25.0, "bone": "porcine_femur"}]
)
def test_registration_changes_no_action_when_the_tool_is_where_the_plan_says(scenario):
    registered = _episode_actions("li2023_registered", SEEDS[0], **scenario)
    tuned = _episode_actions("li2023_tuned", SEEDS[0], **scenario)
    np.testing.assert_array_equal(registered, tuned)


@pytest.mark.parametrize("dl_mm", [-1.0, 1.0])
def test_registration_estimates_the_tool_offset_and_drills_the_hole_far_closer_to_plan(dl_mm):
    env = gym.make("drillgym/UR5BoneDrill-v1", pybullet_world=False)
    options = {"effects": build_effects(f"tool_length:dl_m={dl_mm * 1e-3}")}
    deviation = {}
    for spec in ("li2023_tuned", "li2023_registered"):
        controller = make_controller(spec)
        rows = [run_episode(env, controller, s, keep_trace=False, options=options).metrics for s in SEEDS]
        deviation[spec] = np.mean([r["deviation_mean_mm"] for r in rows])
        if isinstance(controller, ContactRegistered):
            # resolution: one agent step of the path at contact (0.1 mm in the approach, 0.025 mm at the feed)
            assert controller.offset_m * 1e3 == pytest.approx(dl_mm, abs=0.1)
    # measured on these seeds: -1 mm 0.284 -> 0.035 mm, +1 mm 0.476 -> 0.044 mm
    assert deviation["li2023_registered"] < 0.25 * deviation["li2023_tuned"]


def test_a_long_tool_is_held_so_the_hole_ends_at_the_planned_depth():
    def deepest_mm(spec: str, effects: str) -> float:
        env = gym.make("drillgym/UR5BoneDrill-v1", pybullet_world=False)
        options = {"effects": build_effects(effects)} if effects else None
        run_episode(env, make_controller(spec), SEEDS[0], keep_trace=False, options=options)
        return float(np.max(np.asarray(env.unwrapped.recorder.tip_task_m)[:, 2])) * 1e3

    planned = deepest_mm("li2023_tuned", "")  # the arm and drill yield to the thrust: a little short of 6 mm
    assert deepest_mm("li2023_tuned", "tool_length:dl_m=0.0015") == pytest.approx(planned + 1.5, abs=0.1)
    assert deepest_mm("li2023_registered", "tool_length:dl_m=0.0015") == pytest.approx(planned, abs=0.1)


def test_batched_rollout_of_registered_episodes_equals_the_single_env():
    effects = "tool_length:dl_m=0.0008"
    batched = run_episodes(lambda: make_controller("li2023_registered"), SEEDS, {}, effects)
    env = gym.make("drillgym/UR5BoneDrill-v1", pybullet_world=False)
    for seed, result in zip(SEEDS, batched, strict=True):
        alone = run_episode(
            env,
            make_controller("li2023_registered"),
            seed,
            keep_trace=False,
            options={"effects": build_effects(effects)},
        )
        assert alone.metrics == result.metrics


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ("contact_threshold_n=0", "contact_threshold_n"),
        ("contact_threshold_n=nan", "contact_threshold_n"),
        ("contact_backoff_mm=3", "contact_backoff_mm"),
        ("air_feed_scale=2", "never faster"),
        ("register_contact=maybe", "not a boolean"),
        ("contact_dead_band_mm=-1", "contact_dead_band_mm"),
    ],
)
def test_bad_registration_fields_raise_a_clear_error(fields, message):
    with pytest.raises(UserError, match=message):
        make_controller(f"li2023:register_contact=1,{fields}")


def test_register_contact_off_builds_the_plain_controller():
    assert not isinstance(make_controller("li2023:register_contact=0,contact_threshold_n=1"), ContactRegistered)
    assert isinstance(make_controller("none:register_contact=1"), ContactRegistered)


def test_registered_prefix_wraps_a_spec_that_takes_no_fields():
    wrapped = make_controller("registered:li2023_tuned")
    assert isinstance(wrapped, ContactRegistered)
    assert wrapped.describe()["config"]["register_contact"] is True
    np.testing.assert_array_equal(
        _episode_actions("registered:li2023_tuned", SEEDS[1]), _episode_actions("li2023_registered", SEEDS[1])
    )


@pytest.mark.parametrize(
    ("spec", "message"), [("registered:", "needs the controller"), ("registered:li2023_registered", "already")]
)
def test_registered_prefix_refuses_nothing_or_a_registered_controller(spec, message):
    with pytest.raises(UserError, match=message):
        make_controller(spec)
