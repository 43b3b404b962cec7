"""``drillgym bench --reality``: controllers judged in a simulated reality (the reality library's effects)."""

import json

import pandas as pd
import pytest

from drillgym.eval.cli import main

FRICTION = "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4"


def test_a_reality_changes_every_episode_and_is_recorded_with_the_run(tmp_path):
    argv = ["bench", "--suite", "paper", "--controllers", "none,li2023", "--seeds", "2", "--no-logs"]
    assert main([*argv, "--out", str(tmp_path / "ideal")]) == 0
    assert main([*argv, "--reality", FRICTION, "--out", str(tmp_path / "real")]) == 0
    ideal, real = (
        pd.read_csv(tmp_path / d / "episodes.csv").set_index(["controller", "seed"]) for d in ("ideal", "real")
    )
    assert real["error"].isna().all()
    assert (real["deviation_mean_mm"] != ideal["deviation_mean_mm"]).all()  # every episode drilled in the reality
    assert json.loads((tmp_path / "real" / "run.json").read_text())["reality"] == FRICTION
    assert "Reality: `stribeck_friction" in (tmp_path / "real" / "summary.md").read_text()
    # the same reality again: the same numbers (its draws are seeded by the episode's seed)
    assert main([*argv, "--reality", FRICTION, "--out", str(tmp_path / "again")]) == 0
    again = pd.read_csv(tmp_path / "again" / "episodes.csv").set_index(["controller", "seed"])
    assert again["deviation_mean_mm"].equals(real["deviation_mean_mm"])


def test_a_bad_reality_is_one_line_before_anything_runs(tmp_path, capsys):
    code = main(
        ["bench", "--suite", "paper", "--controllers", "none", "--reality", "no_such:x=1", "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2 and "unknown reality effect 'no_such'" in err
    assert not (tmp_path / "episodes.csv").exists()


@pytest.mark.parametrize("flag", [[], ["--reality", FRICTION]])
def test_resume_needs_the_same_reality(tmp_path, capsys, flag):
    argv = ["bench", "--suite", "paper", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", str(tmp_path)]
    assert main([*argv, "--reality", "joint_offsets:dq0_rad=0.001"]) == 0
    code = main([*argv, *flag, "--resume"])
    assert code == 2 and "reality" in capsys.readouterr().err
