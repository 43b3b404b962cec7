"""A series of holes: the episodes' order from their logs, a trend candidate replayed at each episode's place in it,
and the reality whose joint zeros drift from hole to hole (issue 45, item 3)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs
from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode
from drillgym.eval.diagnosis.episodes import EpisodeData, set_series_positions
from drillgym.eval.diagnosis.reality.generate import build_reality


def _episode(name: str, created: str | None) -> EpisodeData:
    empty = np.zeros(0)
    return EpisodeData(
        name,
        {},
        "none",
        np.zeros((0, 4), np.float32),
        empty,
        empty,
        empty,
        empty,
        np.zeros((0, 15)),
        created_utc=created,
    )


def test_episodes_are_ordered_by_their_logs_start_times_then_by_name():
    eps = [
        _episode("hole_02", "2026-11-27T10:00:05+00:00"),
        _episode("hole_10", "2026-11-27T09:59:00+00:00"),
        _episode("hole_01", "2026-11-27T10:00:05+00:00"),  # same second as hole_02: its name comes first
        _episode("hole_00", None),  # no start time: before every timed log
    ]
    order = set_series_positions(eps)
    assert [eps[i].name for i in order] == ["hole_00", "hole_10", "hole_01", "hole_02"]
    assert [eps[i].series_position for i in order] == [0.0, 1 / 3, 2 / 3, 1.0]
    single = [_episode("only", None)]
    set_series_positions(single)
    assert single[0].series_position == 0.0


def _tips(effect):
    env = gym.make(envs.ENV_IDS[0])
    try:
        run_episode(env, make_controller("li2023"), seed=2, options={"effects": [effect]}, keep_trace=False)
        return np.asarray(env.unwrapped.recorder.tip_task_m)
    finally:
        env.close()


@pytest.mark.parametrize("hole", [0, 7])
def test_the_drifting_joints_reality_drills_hole_k_as_static_zero_errors_of_first_plus_k_steps(hole):
    (drift,) = build_reality("joint_drift:dq1_first_rad=-5e-4,dq0_per_hole_rad=1e-4,dq2_per_hole_rad=-1.5e-4")
    drift.set_series(hole, 12)
    (static,) = build_reality(f"joint_offsets:dq0_rad={hole * 1e-4},dq1_rad=-5e-4,dq2_rad={hole * -1.5e-4}")
    np.testing.assert_array_equal(_tips(drift), _tips(static))
