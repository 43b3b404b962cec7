"""``drillgym tune-entry``: the candidate grid, the selection rule, and a tiny real run."""

import json

import pandas as pd
import pytest

from drillgym.eval.bench.tune_entry import best_candidate, candidate_specs, grid_table
from drillgym.eval.cli import main


def test_candidates_are_the_base_then_every_schedule_of_the_grid():
    specs = candidate_specs("li2023", [0.5, 0.7], [1.0])
    assert specs == [
        "li2023",
        "li2023:entry_feed_scale=0.5,entry_depth_mm=1",
        "li2023:entry_feed_scale=0.7,entry_depth_mm=1",
    ]
    assert candidate_specs("li2023:kp=1", [0.5], [2.0])[1] == "li2023:kp=1,entry_feed_scale=0.5,entry_depth_mm=2"


def test_with_gains_every_schedule_is_tried_at_every_gain_after_the_base_alone():
    specs = candidate_specs("li2023", [0.5], [1.0, 2.0], kps=[2.0, 3.0])
    assert specs == [
        "li2023",
        "li2023:kp=2,entry_feed_scale=0.5,entry_depth_mm=1",
        "li2023:kp=2,entry_feed_scale=0.5,entry_depth_mm=2",
        "li2023:kp=3,entry_feed_scale=0.5,entry_depth_mm=1",
        "li2023:kp=3,entry_feed_scale=0.5,entry_depth_mm=2",
    ]


def test_y_gains_multiply_the_gain_settings_kp_first():
    specs = candidate_specs("li2023", [0.5], [1.0], kps=[3.0], y_gains=[1.0, 1.4])
    assert specs == [
        "li2023",
        "li2023:kp=3,y_gain=1,entry_feed_scale=0.5,entry_depth_mm=1",
        "li2023:kp=3,y_gain=1.4,entry_feed_scale=0.5,entry_depth_mm=1",
    ]


def _episodes(rows):
    cols = ["controller", "suite", "deviation_mean_mm", "lateral_force_max_n", "drill_time_s"]
    return pd.DataFrame(rows, columns=cols)


def test_the_lowest_deviation_wins_only_if_it_keeps_the_force_and_time_limits():
    episodes = _episodes(
        [
            ("base", "paper", 0.15, 1.2, 12.0),
            ("base", "sweep", 0.20, 1.8, 11.0),
            ("forceful", "paper", 0.04, 1.5, 13.0),  # lowest deviation, higher peak force: infeasible
            ("forceful", "sweep", 0.05, 1.9, 12.0),
            ("slow", "paper", 0.05, 1.0, 16.0),  # +33 % drill time: infeasible at 30 %
            ("slow", "sweep", 0.06, 1.5, 15.0),
            ("good", "paper", 0.07, 1.1, 14.0),
            ("good", "sweep", 0.08, 1.7, 13.0),
        ]
    )
    grid = grid_table(episodes, "base", ["paper", "sweep"], 0.3).set_index("controller")
    assert grid.loc["good", "objective_mm"] == pytest.approx(0.075)
    assert list(grid["feasible"]) == [True, False, False, True]
    assert best_candidate(grid.reset_index()) == "good"


def test_tune_entry_runs_the_grid_and_names_the_best(tmp_path):
    out = tmp_path / "tune"
    rc = main(
        ["tune-entry", "--suites", "paper", "--seeds", "1", "--scales", "0.5", "--depths-mm", "1", "--out", str(out)]
    )
    assert rc == 0
    grid = pd.read_csv(out / "grid.csv")
    assert list(grid["controller"]) == ["li2023", "li2023:entry_feed_scale=0.5,entry_depth_mm=1"]
    best = json.loads((out / "best.json").read_text())["best"]
    assert best in set(grid["controller"])
    assert (out / "tune_entry.png").stat().st_size > 0
    slow = grid.set_index("controller").iloc[1]
    assert slow["paper_drill_time_s"] > grid.set_index("controller").iloc[0]["paper_drill_time_s"]


def test_tune_entry_rejects_the_judge_only_suites_typos_and_bad_schedules(tmp_path, capsys):
    assert main(["tune-entry", "--suites", "papr", "--out", str(tmp_path)]) == 2
    for judged in ("heldout", "generalisation"):
        assert main(["tune-entry", "--suites", f"paper,{judged}", "--out", str(tmp_path)]) == 2
        assert f"the {judged} suite(s) judge tuned and learnt controllers" in capsys.readouterr().err
    assert main(["tune-entry", "--scales", "2", "--out", str(tmp_path)]) == 2
    assert "never speeds up" in capsys.readouterr().err
    assert main(["tune-entry", "--base", "li2023:kp=2", "--kps", "3", "--out", str(tmp_path)]) == 2
    assert "leave kp out of --base" in capsys.readouterr().err


def test_a_gain_grid_plots_one_panel_per_gain(tmp_path):
    out = tmp_path / "tune"
    argv = ["tune-entry", "--suites", "paper", "--seeds", "1", "--scales", "0.5", "--depths-mm", "1"]
    assert main([*argv, "--kps", "3,4", "--out", str(out)]) == 0
    grid = pd.read_csv(out / "grid.csv")
    assert list(grid["controller"])[1:] == [
        "li2023:kp=3,entry_feed_scale=0.5,entry_depth_mm=1",
        "li2023:kp=4,entry_feed_scale=0.5,entry_depth_mm=1",
    ]
    # kp=4 is li2023's own gain: the same episodes as the plain schedule
    plain = main([*argv, "--out", str(tmp_path / "plain")])
    assert plain == 0
    one = pd.read_csv(tmp_path / "plain" / "grid.csv").iloc[1]
    assert grid.iloc[2]["paper_deviation_mean_mm"] == one["paper_deviation_mean_mm"]
