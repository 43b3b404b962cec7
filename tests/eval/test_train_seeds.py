"""``drillgym train --seeds``: several seeds, each reproducible by its own command, judged in one report."""

import argparse
import json
import zipfile
from pathlib import Path

import pytest

from drillgym.eval.cli import main
from drillgym.eval.cli.train import _seeds, add_arguments, seed_command

SMOKE = Path(__file__).resolve().parents[2] / "training" / "configs" / "smoke.yaml"


def test_seed_lists_must_be_distinct_non_negative_integers():
    assert _seeds("0,1, 4") == [0, 1, 4]
    for bad in ("0,0", "-1", "a,b", ""):
        with pytest.raises(argparse.ArgumentTypeError):
            _seeds(bad)


def test_each_seed_runs_the_single_seed_command_into_its_own_folder(tmp_path):
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--config", str(SMOKE), "--out", str(tmp_path), "--seeds", "3,5", "--timesteps", "50"])
    cmd = seed_command(args, 5, tmp_path / "seed5")
    assert cmd[1:] == [
        "-m",
        "drillgym.eval.cli",
        "train",
        "--out",
        str(tmp_path / "seed5"),
        "--seed",
        "5",
        "--config",
        str(SMOKE),
        "--timesteps",
        "50",
        "--torch-threads",
        "1",
    ]


def test_the_env_workers_of_each_seed_are_passed_on_and_an_oversubscription_is_said(tmp_path, monkeypatch, capsys):
    from drillgym.eval.cli.train import _check

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    argv = ["--config", "residual_schedule_sac_fast", "--out", str(tmp_path), "--seeds", "0,1", "--jobs", "2"]
    args = parser.parse_args([*argv, "--env-workers", "2"])
    assert seed_command(args, 1, tmp_path / "seed1")[-4:-2] == ["--env-workers", "2"]
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    _check(args)  # 2 runs x 2 env processes on 2 CPUs
    assert "the seeds will share cores" in capsys.readouterr().err
    _check(parser.parse_args([*argv[:-1], "1"]))  # --jobs 1: 2 processes on 2 CPUs
    assert "share cores" not in capsys.readouterr().err


def _weights(policy_zip: Path) -> bytes:
    with zipfile.ZipFile(policy_zip) as z:
        return z.read("policy.pth")


@pytest.mark.expensive
def test_two_seeds_train_then_are_judged_against_the_baselines_and_reproduce_alone(tmp_path, capsys):
    out = tmp_path / "seeds"
    common = ["--config", str(SMOKE), "--timesteps", "300"]
    args = ["train", *common, "--out", str(out), "--seeds", "0,1", "--eval-seeds", "2", "--eval-suites", "paper"]
    assert main(args) == 0
    for seed in (0, 1):
        assert (out / f"seed{seed}" / "policy.zip").exists()
    for name in ("seed_report.md", "seed_report.json", "seed_report.png", "seed_episodes.csv"):
        assert (out / name).exists(), name
    report = json.loads((out / "seed_report.json").read_text())
    assert report  # the report module's own tests check its figures
    assert report["best_classical"]["chosen"] in {"li2023_tuned", "table:shipped"}  # the rule ran on the baselines
    assert [r["run"] for r in report["best_classical"]["candidates"]] == ["table:shipped"]
    assert report["ship"]["rule"] == "selection_deviation" and len(report["ship"]["seeds"]) == 2
    # seed 1 alone, with the single-seed command, gives the same weights
    alone = tmp_path / "alone"
    assert main(["train", *common, "--seed", "1", "--out", str(alone)]) == 0
    assert _weights(alone / "policy.zip") == _weights(out / "seed1" / "policy.zip")
    # running the same command again does not retrain: it judges the policies that are there
    capsys.readouterr()
    assert main(args) == 0
    assert "exists, not trained again" in capsys.readouterr().out


def test_bad_multi_seed_arguments_are_errors_before_any_training(tmp_path, capsys):
    base = ["train", "--config", str(SMOKE), "--out", str(tmp_path / "x"), "--seeds", "0,1"]
    assert main([*base, "--baselines", "li2023"]) == 2  # the best baseline must be among them
    assert main([*base, "--baselines", "li2023,li2023_slow_entry,nosuch"]) == 2
    assert main([*base, "--resume"]) == 2
    err = capsys.readouterr().err
    assert "li2023_slow_entry" in err and "nosuch" in err and "--resume" in err
    assert not (tmp_path / "x").exists()
