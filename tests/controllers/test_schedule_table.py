"""The gain-scheduling table: exact at its anchors, separable piecewise-linear between them, a file that loads."""

import json

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec, normalized_plan
from drillgym.controllers.rollout import run_episode
from drillgym.controllers.schedule_table import Anchor, ScheduleTable, load_table, table_from_dict
from drillgym.training.domain_randomization import training_plan_support

SPEC = ScheduleSpec("li2023_tuned", plan_support=training_plan_support())
NOMINAL = (0.0, 0.0, 0.0, 0.0, 0.0)


def _table(anchors=None) -> ScheduleTable:
    """Nominal at the origin (action 0.1 each), feature 0 at ±1 and feature 4 at -1 with their own actions."""
    anchors = anchors or [
        Anchor("nominal", {}, NOMINAL, (0.1, 0.1, 0.1, 0.1)),
        Anchor("f0=-1", {}, (-1.0, 0, 0, 0, 0), (0.5, 0.1, 0.1, 0.1)),
        Anchor("f0=+1", {}, (1.0, 0, 0, 0, 0), (-0.3, 0.1, 0.1, 0.1)),
        Anchor("f4=-1", {}, (0, 0, 0, 0, -1.0), (0.1, 0.9, 0.1, 0.1)),
    ]
    return ScheduleTable(SPEC, tuple(anchors))


def test_the_table_gives_each_anchor_its_own_action_exactly():
    table = _table()
    for anchor in table.anchors:
        assert table.action(np.array(anchor.features)) == pytest.approx(anchor.action)


def test_between_anchors_each_feature_interpolates_linearly_and_the_changes_add():
    table = _table()
    # half way to f0 = -1: a0 = 0.1 + (0.5 - 0.1) / 2; half way to f4 = -1: a1 = 0.1 + (0.9 - 0.1) / 2
    got = table.action(np.array([-0.5, 0.3, -0.2, 0.7, -0.5]))  # features 1-3 have no anchors: no change
    assert got == pytest.approx([0.3, 0.5, 0.1, 0.1])
    # beyond the outermost knot the change is held; on the side without a knot (f4 > 0) it is 0
    assert table.action(np.array([0.0, 0, 0, 0, 0.8])) == pytest.approx([0.1] * 4)
    # the sum is clipped to [-1, 1]
    wide = _table([Anchor("nominal", {}, NOMINAL, (0.9, 0, 0, 0)), Anchor("f1", {}, (0, 1.0, 0, 0, 0), (1.0, 0, 0, 0)),
                   Anchor("f2", {}, (0, 0, 1.0, 0, 0), (1.0, 0, 0, 0))])  # fmt: skip
    assert wide.action(np.array([0, 1.0, 1.0, 0, 0]))[0] == 1.0  # 0.9 + 0.1 + 0.1


def test_anchors_must_move_one_feature_and_actions_stay_in_range():
    with pytest.raises(ValueError, match="exactly one feature"):
        _table([Anchor("nominal", {}, NOMINAL, (0,) * 4), Anchor("two", {}, (1.0, 1.0, 0, 0, 0), (0,) * 4)])
    with pytest.raises(ValueError, match=r"in \[-1, 1\]"):
        _table([Anchor("nominal", {}, NOMINAL, (1.5, 0, 0, 0))])
    with pytest.raises(ValueError, match="4 fields"):
        _table([Anchor("nominal", {}, NOMINAL, (0.0,))])


def test_a_table_file_round_trips_is_never_overwritten_and_loads_as_a_controller(tmp_path):
    table = _table()
    path = tmp_path / "table.json"
    table.save(path)
    with pytest.raises(FileExistsError, match="never overwritten"):
        table.save(path)
    loaded = load_table(str(path))
    assert [a.action for a in loaded.anchors] == [a.action for a in table.anchors]
    ctrl = make_controller(f"table:{path}")
    assert isinstance(ctrl, PlanScheduledController)
    env = gym.make("drillgym/UR5BoneDrill-v1")
    env.reset(seed=0)
    ctrl.set_plan(env.unwrapped.plan)
    features = normalized_plan(env.unwrapped.plan, SPEC.plan_support)
    assert ctrl.action == pytest.approx(table.action(features), abs=1e-6)
    env.close()


def test_bad_table_files_get_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="tune-table writes one"):
        make_controller(f"table:{tmp_path / 'missing.json'}")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_table(str(tmp_path / "bad.json"))
    with pytest.raises(ValueError, match="not a schedule table"):
        table_from_dict({"format": "other"})
    data = _table().to_dict()
    del data["anchors"][0]["action"]
    with pytest.raises(ValueError, match="malformed schedule table"):
        table_from_dict(json.loads(json.dumps(data)))


def test_a_zero_table_drills_exactly_as_its_base():
    zero = _table([Anchor("nominal", {}, NOMINAL, (0.0,) * 4), Anchor("f0", {}, (1.0, 0, 0, 0, 0), (0.0,) * 4)])
    env = gym.make("drillgym/UR5BoneDrill-v1", beta_deg=20.0)
    a = run_episode(env, zero.controller(), 3, keep_trace=False).metrics
    b = run_episode(env, make_controller("li2023_tuned"), 3, keep_trace=False).metrics
    env.close()
    assert a == b


def test_the_shipped_table_loads_and_names_its_tuning():
    table = load_table("shipped")
    assert table.anchors[0].name == "nominal" and len(table.anchors) == 11
    assert table.meta["seed_namespace"] == "tune"
    assert table.spec.base == "li2023_tuned"
