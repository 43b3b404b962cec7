"""Multi-hole runs from a plan file, ``drillgym run --plan FILE`` (issue 43, item 2).

The file's checks (every error names the file and the hole), the rule that refuses one entry point drilled twice on
both sides of its tolerance, the options that do not go with a plan, and, on the emulator, a plan drilled hole by
hole: each at its own entry point with its own log, with a confirmation before each hole.
"""

from __future__ import annotations

import io
import json
import math
import sys

import pytest
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.envs.real.emulator.process import free_loopback_host
from drillgym.eval.cli import main
from drillgym.eval.real.plan_file import axis_distance_m, far_transits, load_plan

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)

ENTRY = (-450.0, -110.0, 100.0)
"""The cell's default entry point (mm, UR base frame): ``CellParams.entry_point_base_m``."""
SHORT = {"feed_mm_s": 3.0, "depth_mm": 3.0}
"""A 3 s hole (approach 1.4 s, feed 1.1 s, retract 0.6 s), as the other CLI tests drill."""


def write_plan(tmp_path, holes, scenario=None, name="plan.yaml"):
    """A plan file; YAML unless ``name`` ends in .json (JSON is YAML too, so one writer serves both)."""
    data = {"holes": holes} if scenario is None else {"scenario": scenario, "holes": holes}
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def at(dx_mm=0.0, dy_mm=0.0, dz_mm=0.0):
    """The default entry point moved by (dx, dy, dz) mm in the base frame."""
    return [ENTRY[0] + dx_mm, ENTRY[1] + dy_mm, ENTRY[2] + dz_mm]


def test_a_plan_gives_each_hole_its_entry_point_in_m_its_scenario_and_a_seed(tmp_path):
    path = tmp_path / "plan.yaml"
    path.write_text(
        "scenario: {feed_mm_s: 1.0, depth_mm: 5}\n"
        "holes:\n"
        f"  - {{name: A1, entry_point_base_mm: {at()}}}\n"
        f"  - {{entry_point_base_mm: {at(dx_mm=4)}, scenario: {{depth_mm: 4}}}}\n"
        f"  - {{name: C, entry_point_base_mm: {at(dx_mm=8)}, seed: 42}}\n"
    )
    plan = load_plan(path, first_seed=10)
    a, b, _ = plan.holes
    assert [h.name for h in plan.holes] == ["A1", "hole2", "C"]
    assert a.entry_base_m == pytest.approx((-0.45, -0.11, 0.10), abs=1e-12)  # mm -> m, float rounding only
    assert (a.scenario.feed_mm_s, a.scenario.depth_mm, b.scenario.feed_mm_s, b.scenario.depth_mm) == (1.0, 5, 1.0, 4)
    assert [h.seed for h in plan.holes] == [10, 11, 42]  # --seed counts on with the hole's position
    assert b.label == "hole 2 (hole2)" and plan.to_json()["holes"][2]["entry_point_base_mm"] == at(dx_mm=8)


def test_a_json_plan_reads_as_the_yaml_one(tmp_path):
    holes = [{"name": "A1", "entry_point_base_mm": at()}, {"name": "A2", "entry_point_base_mm": at(dy_mm=3)}]
    from_json = load_plan(write_plan(tmp_path, holes, SHORT, name="plan.json"))
    from_yaml = load_plan(write_plan(tmp_path, holes, SHORT, name="plan.yml"))
    assert from_json.holes == from_yaml.holes


GOOD = {"name": "A1", "entry_point_base_mm": at()}


@pytest.mark.parametrize(
    ("holes", "scenario", "message"),
    [
        ([{"name": "A1"}], None, "hole 1 (A1): missing key 'entry_point_base_mm'"),
        ([GOOD, {"name": "B", "entry": at(dx_mm=5)}], None, "hole 2 (B): unknown key(s) ['entry']"),
        ([{"name": "A1", "entry_point_base_mm": at()[:2]}], None, "hole 1 (A1): entry_point_base_mm must be [x, y, z]"),
        ([{"name": "A1", "entry_point_base_mm": [1, "2", 3]}], None, "must be [x, y, z] in mm"),
        ([{"name": "A1", "entry_point_base_mm": [-450, True, 100]}], None, "must be [x, y, z] in mm"),
        ([{"name": "A1", "entry_point_base_mm": [-0.45, -0.11, 0.1]}], None, "entry points are in mm, not m"),
        ([{"name": "A1", "entry_point_base_mm": [-900, 0, 100]}], None, "beyond the UR5's reach (850 mm)"),
        (
            [GOOD, {"name": "B", "entry_point_base_mm": at(5), "scenario": {"feed_mm_s": 5}}],
            None,
            "hole 2 (B): scenario: feed_mm_s=5",
        ),
        ([GOOD], {"beta_deg": 60}, "hole 1 (A1): scenario: beta_deg=60 is outside the allowed range"),
        ([GOOD], {"feed_mm_s": "fast"}, "hole 1 (A1): scenario: feed_mm_s='fast' must be a number"),
        ([GOOD], {"drill_size": 2}, "hole 1 (A1): scenario: unknown scenario argument(s) ['drill_size']"),
        ([GOOD], {"tracker": True}, "scenario: 'tracker' is not a plan value"),
        ([GOOD], ["feed_mm_s=1"], "scenario must be a mapping"),
        ([{"name": "A 1", "entry_point_base_mm": at()}], None, "hole 1: name 'A 1' must be 1-40 letters"),
        ([GOOD, {"name": "A1", "entry_point_base_mm": at(dx_mm=5)}], None, "holes 1 and 2 are both named 'A1'"),
        (
            [{"name": "A1", "entry_point_base_mm": at(), "seed": -1}],
            None,
            "hole 1 (A1): seed -1 must be a whole number",
        ),
        ([{"name": "A1", "entry_point_base_mm": at(), "seed": 1.5}], None, "seed 1.5 must be a whole number"),
        ([], None, "'holes' must be a non-empty list"),
        (["A1"], None, "hole 1: a hole is a mapping"),
    ],
)
def test_a_bad_plan_is_refused_naming_the_file_the_hole_and_the_value(tmp_path, holes, scenario, message):
    path = write_plan(tmp_path, holes, scenario)
    with pytest.raises(ValueError) as e:
        load_plan(path)
    assert str(e.value).startswith(f"{path}: ") and message in str(e.value), str(e.value)


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf"])
def test_a_nan_or_infinite_yaml_entry_point_is_refused(tmp_path, value):
    path = tmp_path / "plan.yaml"
    path.write_text(f"holes:\n  - {{name: A1, entry_point_base_mm: [-450, {value}, 100]}}\n")
    with pytest.raises(ValueError, match=r"hole 1 \(A1\): entry_point_base_mm .* must be finite numbers"):
        load_plan(path)


def test_a_nan_json_entry_point_and_a_nan_scenario_value_are_refused(tmp_path):
    path = tmp_path / "plan.json"
    path.write_text('{"holes": [{"name": "A1", "entry_point_base_mm": [-450, NaN, 100]}]}')
    with pytest.raises(ValueError, match="must be finite numbers"):
        load_plan(path)
    path.write_text('{"scenario": {"depth_mm": NaN}, "holes": [{"entry_point_base_mm": [-450, -110, 100]}]}')
    with pytest.raises(ValueError, match=r"hole 1 \(hole1\): scenario: depth_mm=nan is outside the allowed range"):
        load_plan(path)


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("plan.txt", "holes: []", "a plan file is YAML (.yaml, .yml) or JSON (.json)"),
        ("plan.yaml", "holes: [unclosed", "not valid YAML"),
        ("plan.json", "{holes: []}", "not valid JSON"),
        ("plan.yaml", "- a list", "a plan is a mapping with a 'holes' list"),
        ("plan.yaml", "scenario: {}", "missing key 'holes'"),
        ("plan.yaml", "holes: [{entry_point_base_mm: [-450, -110, 100]}]\nspeed: 3", "unknown key(s) ['speed']"),
    ],
)
def test_a_plan_file_that_is_not_a_plan_is_refused_naming_it(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError) as e:
        load_plan(path)
    assert str(e.value).startswith(f"{path}: ") and message in str(e.value)


@pytest.mark.parametrize(
    ("offset_mm", "drills_mm", "refused"),
    [
        ((1.49, 0.0, 0.0), (1.5, 1.5), True),  # axes 1.49 mm apart, one 1.5 mm drill: the bores would cut each other
        ((1.51, 0.0, 0.0), (1.5, 1.5), False),
        ((0.0, 1.0, 1.0), (1.5, 1.5), True),  # measured across the axis: 1 mm across, 1 mm along it
        ((0.0, 0.0, 8.0), (1.5, 1.5), True),  # the same axis, another height: the same hole
        ((2.2, 0.0, 0.0), (1.5, 3.0), True),  # two drills: the mean diameter, 2.25 mm
        ((2.3, 0.0, 0.0), (1.5, 3.0), False),
    ],
)
def test_a_plan_that_drills_one_entry_point_twice_is_refused_on_one_side_of_the_tolerance_only(
    tmp_path, offset_mm, drills_mm, refused
):
    """The tolerance is the mean of the two drill diameters (the drill diameter when both use one drill): axes
    closer than that would put the second bore into the first. The offsets sit 0.01-0.05 mm either side of it,
    far above float rounding (1e-12 mm)."""
    holes = [
        {"name": "A1", "entry_point_base_mm": at(), "scenario": {"drill_diameter_mm": drills_mm[0]}},
        {"name": "A2", "entry_point_base_mm": at(*offset_mm), "scenario": {"drill_diameter_mm": drills_mm[1]}},
    ]
    path = write_plan(tmp_path, holes, {"depth_mm": 10})
    if not refused:
        assert len(load_plan(path).holes) == 2
        return
    with pytest.raises(ValueError) as e:
        load_plan(path)
    text = str(e.value)
    assert text.startswith(f"{path}: hole 1 (A1) and hole 2 (A2) drill the same entry point")
    assert "each entry point is drilled once" in text


def test_the_axis_distance_ignores_the_offset_along_the_drill_axis():
    """The drill axis is −z of the base: (3, 4, 12) mm apart is 5 mm across it. 1e-15 m: float rounding only."""
    assert axis_distance_m((0.0, 0.0, 0.0), (0.003, 0.004, 0.012)) == pytest.approx(0.005, abs=1e-15)


def test_far_transits_lists_consecutive_holes_farther_apart_than_a_reset_moves(tmp_path):
    holes = [
        {"entry_point_base_mm": at()},
        {"entry_point_base_mm": at(dx_mm=30)},
        {"entry_point_base_mm": at(dx_mm=90)},
    ]
    plan = load_plan(write_plan(tmp_path, holes))
    far = far_transits(plan.holes, 0.05)
    assert [(a.index, b.index) for a, b, _ in far] == [(2, 3)] and math.isclose(far[0][2], 0.06, abs_tol=1e-12)


# ------------------------------------------------------------------------------------------- the command line
NO_ROBOT = free_loopback_host()
"""A loopback address nothing listens on: a refusal must come before any connection."""


def _refused(argv, capsys, message):
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("drillgym run: error: "), err
    assert message in lines[0], err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--yes"], "--yes confirms a single-hole run; with --plan the run asks before each hole, or --yes-all"),
        (["--scenario", "depth_mm=4"], "--plan FILE holds the scenario"),
        (["--episodes", "2"], "--plan drills each of its holes once"),
    ],
)
def test_options_that_do_not_go_with_a_plan_are_refused_before_anything(tmp_path, capsys, extra, message):
    plan = write_plan(tmp_path, [GOOD])
    out = tmp_path / "out"
    _refused(["run", "--robot", NO_ROBOT, "--plan", str(plan), *extra, "--out", str(out)], capsys, message)
    assert not out.exists()


def test_yes_all_without_a_plan_is_refused(tmp_path, capsys):
    _refused(
        ["run", "--robot", NO_ROBOT, "--yes-all", "--out", str(tmp_path / "out")], capsys, "--yes-all is for --plan"
    )


def test_a_plan_that_drills_an_entry_point_twice_is_refused_before_anything(tmp_path, capsys):
    plan = write_plan(tmp_path, [GOOD, {"name": "B", "entry_point_base_mm": at(dy_mm=0.5)}])
    out = tmp_path / "out"
    argv = ["run", "--robot", NO_ROBOT, "--plan", str(plan), "--yes-all", "--out", str(out)]
    _refused(argv, capsys, f"{plan}: hole 1 (A1) and hole 2 (B) drill the same entry point")
    assert not out.exists()


def test_yes_all_refuses_a_next_hole_farther_than_a_reset_moves(tmp_path, capsys):
    plan = write_plan(tmp_path, [GOOD, {"name": "B", "entry_point_base_mm": at(dx_mm=60)}])
    argv = ["run", "--robot", NO_ROBOT, "--plan", str(plan), "--yes-all", "--out", str(tmp_path / "out")]
    _refused(argv, capsys, "hole 2 (B) is 60 mm from hole 1 (A1), farther than the 50 mm a reset moves")


def test_a_plan_without_a_terminal_to_ask_on_moves_nothing(tmp_path, capsys, monkeypatch):
    """stdin not a terminal and no --yes-all: refused before the calibration read or any connection."""
    monkeypatch.setattr(sys, "stdin", io.StringIO("yes\n"))
    plan = write_plan(tmp_path, [GOOD])
    out = tmp_path / "out"
    assert main(["run", "--robot", NO_ROBOT, "--plan", str(plan), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert "pass --yes-all" in captured.err and "not confirmed; nothing moved" in captured.out
    assert "hole 1 (A1): entry point (-450.0, -110.0, 100.0) mm" in captured.out  # the plan was shown
    assert not out.exists()


# ------------------------------------------------------------------------------------------- on the emulator
def _answers(monkeypatch, *answers):
    """A terminal on stdin that answers the confirmations in order; returns the prompts it was shown."""
    prompts: list[str] = []
    replies = list(answers)

    def fake_input(prompt=""):
        prompts.append(prompt)
        return replies.pop(0)

    monkeypatch.setattr(sys, "stdin", type("Tty", (io.StringIO,), {"isatty": lambda self: True})())
    monkeypatch.setattr("builtins.input", fake_input)
    return prompts


def _reach(commands, entry_mm):
    """The commanded targets of a command log measured from ``entry_mm`` (the cell's drill axis)."""
    from drillgym.envs.cell_params import R_BASE_TASK
    from drillgym.eval.real.dry_run import target_reach

    T = [[*R_BASE_TASK[i], entry_mm[i] * 1e-3] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
    return target_reach(commands, T, SHORT["depth_mm"] * 1e-3)


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_a_plan_drills_each_hole_at_its_entry_point_with_its_own_log(start_emulator, tmp_path, capsys):
    """Two holes 4 mm apart across the plane of inclination (+x of the base), --yes-all: each hole's start pose is
    its own entry point's (the moveL target on its axis, within 0.01 mm: the emulator's poses are exact to far
    less) and about 4 mm from the other's axis."""
    from drillgym.eval.logs import read_episode_log

    emu = start_emulator(scenario=SHORT)
    holes = [{"name": "A1", "entry_point_base_mm": at()}, {"name": "A2", "entry_point_base_mm": at(dx_mm=4.0)}]
    plan = write_plan(tmp_path, holes, SHORT)
    out = tmp_path / "out"
    argv = ["run", "--robot", emu.host, "--plan", str(plan), "--yes-all", "--max-gap-ms", "500", "--seed", "3"]
    assert main([*argv, "--out", str(out)]) == 0
    console = capsys.readouterr().out
    results = json.loads((out / "metrics.json").read_text())
    assert [(r["hole"], r["name"], r["seed"], r["failure"]) for r in results] == [
        (1, "A1", 3, None),
        (2, "A2", 4, None),
    ]
    for k, hole in enumerate(holes):
        name = hole["name"]
        assert f"hole {k + 1} ({name}) of 2 (li2023, log {out / 'logs' / f'real__li2023__{name}.parquet'}):" in console
        header, frame = read_episode_log(out / results[k]["log"])
        assert header["run"]["hole"] == {
            "index": k + 1,
            "of": 2,
            "name": name,
            "entry_point_base_mm": hole["entry_point_base_mm"],
        }
        assert [row[3] * 1e3 for row in header["plan"]["T_base_task"][:3]] == pytest.approx(hole["entry_point_base_mm"])
        own = _reach(out / "commands" / f"{name}.jsonl", hole["entry_point_base_mm"])
        other = _reach(out / "commands" / f"{name}.jsonl", holes[1 - k]["entry_point_base_mm"])
        assert own["start_pose"]["lateral_mm"] < 0.01 and 3.99 < other["start_pose"]["lateral_mm"] < 4.01
        assert len(frame) > 250 and results[k]["servo_timing"]["cycles"] > 100
    assert console.count("  servo loop: ") == 2
    assert json.loads((out / "plan.json").read_text())["holes"][1]["entry_point_base_mm"] == at(dx_mm=4.0)


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_a_plan_asks_before_each_hole_and_stops_at_the_first_no(start_emulator, tmp_path, capsys, monkeypatch):
    emu = start_emulator(scenario=SHORT)
    holes = [
        {"name": "A1", "entry_point_base_mm": at()},
        {"name": "A2", "entry_point_base_mm": at(dx_mm=4.0)},
        {"name": "A3", "entry_point_base_mm": at(dx_mm=8.0)},
    ]
    plan = write_plan(tmp_path, holes, SHORT)
    out = tmp_path / "out"
    prompts = _answers(monkeypatch, "yes", "no")
    assert main(["run", "--robot", emu.host, "--plan", str(plan), "--max-gap-ms", "500", "--out", str(out)]) == 2
    console = capsys.readouterr().out
    assert prompts == [
        "Type 'yes' to drill hole 1 (A1) (anything else stops the plan here): ",
        "Type 'yes' to drill hole 2 (A2) (anything else stops the plan here): ",
    ]
    assert "4.0 mm away: check that this line clears the bone" in console  # hole 2's prompt: the move between holes
    assert (
        "hole 2 (A2) not confirmed: it and the holes after it were not drilled; hole 1 (A1) was the last one" in console
    )
    assert [r["name"] for r in json.loads((out / "metrics.json").read_text())] == ["A1"]
    assert sorted(p.name for p in (out / "logs").iterdir()) == ["real__li2023__A1.parquet"]
    assert sorted(p.name for p in (out / "commands").iterdir()) == ["A1.jsonl"]
