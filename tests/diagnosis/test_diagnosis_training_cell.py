"""A diagnosis's named effects as the cell a residual is trained for (``drillgym train --cell-from-diagnosis``)."""

import json

import pytest

from drillgym.envs.errors import UserError
from drillgym.eval.cli import main
from drillgym.eval.diagnosis.training_cell import cell_from_diagnosis, cell_overrides
from drillgym.training.config import load_config


def _diagnosis(named: list[str]) -> dict:
    """The parts of a diagnosis.json the conversion reads: a named pair and a single beside it."""
    friction = {"coulomb_rad": 1.5625e-4, "viscous_s": 0.0}
    latency = {"extra_latency_s": 0.034}
    interval = {"contains_off": False, "at_search_edge": False}
    return {
        "verdict": "explained" if named else "unexplained",
        "named": named,
        "effects": [
            {
                "effects": ["joint_friction", "latency"],
                "params": {"joint_friction": friction, "latency": latency},
                "param_intervals": {
                    "joint_friction": {
                        "coulomb_rad": {"low": 1.25e-4, "high": 1.86e-4, **interval},
                        "viscous_s": {"low": 0.0, "high": 0.0, **interval},  # zero width: not drawn
                    },
                    "latency": {"extra_latency_s": None},  # held fixed by the search: no interval
                },
            },
            {"effects": ["joint_friction"], "params": {"joint_friction": friction}, "param_intervals": {}},
        ],
    }


def test_the_named_model_becomes_the_cell_at_its_fitted_values_drawn_within_its_intervals(tmp_path):
    path = tmp_path / "diagnosis.json"
    path.write_text(json.dumps(_diagnosis(["joint_friction", "latency"])))
    cell = cell_from_diagnosis(path)
    assert cell.values == {
        "joint_friction": {"coulomb_rad": 1.5625e-4, "viscous_s": 0.0},
        "latency": {"extra_latency_s": 0.034},
    }
    assert cell.ranges == {"joint_friction.coulomb_rad": (1.25e-4, 1.86e-4)}
    cfg = load_config(None, cell_overrides(path))
    assert cfg.training_cell() == cell


def test_a_diagnosis_that_named_nothing_or_is_not_one_is_refused(tmp_path):
    nothing, other = tmp_path / "nothing.json", tmp_path / "other.json"
    nothing.write_text(json.dumps(_diagnosis([])))
    other.write_text(json.dumps({"hello": 1}))
    with pytest.raises(UserError, match="named no effect"):
        cell_from_diagnosis(nothing)
    with pytest.raises(UserError, match="not a drillgym diagnosis"):
        cell_from_diagnosis(other)


def test_train_refuses_a_bad_diagnosis_on_one_line(tmp_path, capsys):
    path = tmp_path / "diagnosis.json"
    path.write_text(json.dumps(_diagnosis([])))
    code = main(["train", "--out", str(tmp_path / "run"), "--cell-from-diagnosis", str(path), "--seeds", "0,1"])
    err = capsys.readouterr().err
    assert code == 2 and "named no effect" in err and len(err.strip().splitlines()) == 1


def test_the_seeds_of_a_cell_run_are_judged_in_that_cell(tmp_path, monkeypatch):
    import argparse

    from drillgym.eval.bench import jobs
    from drillgym.eval.cli.train import add_arguments, judge

    path = tmp_path / "diagnosis.json"
    path.write_text(json.dumps(_diagnosis(["joint_friction", "latency"])))
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--out", str(tmp_path), "--seeds", "0", "--cell-from-diagnosis", str(path)])
    seen = []

    class Stop(Exception):
        pass

    def capture(grid, workers, desc=""):
        seen.extend(grid)
        raise Stop

    monkeypatch.setattr(jobs, "run_jobs", capture)
    with pytest.raises(Stop):
        judge(args, tmp_path, ["li2023_tuned"])
    cell = cell_from_diagnosis(path).nominal_spec()
    assert seen and all(job.effects.startswith(cell) for job in seen)
