"""Trend forms (envs/effects/trends.py): an effect whose value drifts over a series of holes.

The oracle is the static form: at its place ``p`` in the series, ``kinematic_offset_trend`` must drill exactly the
episode ``kinematic_offset`` drills at ``δ_first + (δ_last − δ_first) p`` (the same compiled step, the same
arithmetic: records equal to the last bit).
"""

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs
from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode
from drillgym.envs.effects.registry import EFFECTS, physics_of

FIRST = {"dx_first_m": 4e-4, "dy_first_m": -2e-4, "dz_first_m": 0.0}
LAST = {"dx_last_m": -2e-4, "dy_last_m": 6e-4, "dz_last_m": 3e-4}


def _tip_path(effect):
    env = gym.make(envs.ENV_IDS[0])
    try:
        result = run_episode(env, make_controller("li2023"), seed=4, options={"effects": [effect]}, keep_trace=True)
        return np.asarray(env.unwrapped.recorder.tip_task_m), result.metrics
    finally:
        env.close()


@pytest.mark.parametrize("position", [0.0, 0.25, 1.0])
def test_a_trend_drills_at_its_place_in_the_series_what_the_static_offset_drills_at_the_interpolated_value(position):
    trend = EFFECTS["kinematic_offset_trend"](**FIRST, **LAST)
    trend.series_position = position
    static = EFFECTS["kinematic_offset"](
        **{
            f"d{a}_base_m": FIRST[f"d{a}_first_m"] + (LAST[f"d{a}_last_m"] - FIRST[f"d{a}_first_m"]) * position
            for a in "xyz"
        }
    )
    np.testing.assert_allclose(
        trend.offset_base_m(), [static.values[f"d{a}_base_m"] for a in "xyz"], rtol=0, atol=1e-18
    )
    got, got_metrics = _tip_path(trend)
    want, want_metrics = _tip_path(static)
    np.testing.assert_array_equal(got, want)
    assert got_metrics == want_metrics


def test_a_trend_names_the_physics_of_its_static_form_and_is_compiled():
    cls = EFFECTS["kinematic_offset_trend"]
    assert physics_of("kinematic_offset_trend") == "kinematic_offset" and cls.in_series and cls.__dict__["compiled"]
    assert not EFFECTS["kinematic_offset"].in_series


def test_a_trends_start_is_the_line_through_each_holes_tracker_reading_over_the_series():
    cls = EFFECTS["kinematic_offset_trend"]
    r_base_task = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # the paper pose's axes
    positions = np.array([0.0, 0.25, 0.5, 1.0])
    first_base, last_base = np.array([1e-4, -2e-4, 0.0]), np.array([1e-4, 2e-4, -6e-4])
    base = first_base + np.outer(positions, last_base - first_base)
    readings = base @ r_base_task  # base -> task frame, per hole
    evidence = {
        "tracker_offset_task_m": readings.mean(axis=0),
        "tracker_offsets_task_m": readings,
        "series_positions": positions,
        "R_base_task": r_base_task,
    }
    guess = cls.initial_guess(evidence)
    assert guess is not None
    for k, axis in enumerate("xyz"):
        assert guess[f"d{axis}_first_m"] == pytest.approx(first_base[k], abs=1e-12)
        assert guess[f"d{axis}_last_m"] == pytest.approx(last_base[k], abs=1e-12)
    # One place in the series (or no per-hole readings): the static reading at both ends.
    same = cls.initial_guess({**evidence, "series_positions": np.zeros(4)})
    static = r_base_task @ readings.mean(axis=0)
    assert same is not None and [same[f"d{a}_first_m"] for a in "xyz"] == pytest.approx(static.tolist(), abs=1e-12)
    assert [same[f"d{a}_last_m"] for a in "xyz"] == pytest.approx(static.tolist(), abs=1e-12)
    old = {k: v for k, v in evidence.items() if k in ("tracker_offset_task_m", "R_base_task")}
    assert cls.initial_guess(old) == same
