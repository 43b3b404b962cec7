"""`drillgym bench-diagnosis --ray`: the same verdicts as the local run, case files written by the driver."""

import json
import os
import signal

import pytest

from drillgym.eval.cli import main
from drillgym.eval.diagnosis.bench.cases import QUICK_CANDIDATES, quick_cases

KEYS = ("case", "verdict", "named", "top_single", "location", "correct")


def _fits(diagnosis):
    return [{k: v for k, v in e.items() if k != "fit"} for e in diagnosis["effects"]]  # "fit" holds wall times


@pytest.mark.expensive
def test_ray_cases_give_the_local_verdicts_and_write_every_case_file(tmp_path, ray_local):
    assert (
        main(["bench-diagnosis", "--quick", "--out", str(tmp_path / "local"), "--workers", "1", "--no-progress"]) == 0
    )
    assert main(["bench-diagnosis", "--quick", "--ray", "--out", str(tmp_path / "ray"), "--no-progress"]) == 0
    local, remote = (json.loads((tmp_path / d / "bench.json").read_text()) for d in ("local", "ray"))
    assert [{k: r[k] for k in KEYS} for r in remote["rows"]] == [{k: r[k] for k in KEYS} for r in local["rows"]]
    assert remote["summary"]["figures"] == local["summary"]["figures"]
    for case in quick_cases():
        ray_diag = json.loads((tmp_path / "ray" / "cases" / case.name / "diagnosis.json").read_text())
        local_diag = json.loads((tmp_path / "local" / "cases" / case.name / "diagnosis.json").read_text())
        assert ray_diag["verdict"] == local_diag["verdict"]
        assert _fits(ray_diag) == _fits(local_diag)  # same fitted parameters and held-out scores


def test_a_case_whose_worker_dies_past_its_retries_is_an_error_row(ray_local):
    from drillgym.eval.diagnosis.bench.on_ray import ray_rows

    case = quick_cases()[1]  # clean data

    def die(job):
        os.kill(os.getpid(), signal.SIGKILL)

    import drillgym.eval.diagnosis.bench.on_ray as bench_ray

    real = bench_ray.run_case
    bench_ray.run_case = die
    try:
        rows = list(ray_rows([(case, 6, QUICK_CANDIDATES, False)], max_retries=0))
    finally:
        bench_ray.run_case = real
    assert len(rows) == 1 and rows[0]["verdict"] == "error" and "worker failed" in rows[0]["error"]
    assert rows[0]["case"] == case.name and rows[0]["correct"] is False


def test_an_unreachable_cluster_is_a_clear_error(tmp_path, capsys):
    pytest.importorskip("ray")
    args = ["bench-diagnosis", "--quick", "--out", str(tmp_path), "--address", "127.0.0.1:1", "--no-progress"]
    assert main(args) == 2
    assert "cannot connect to the Ray cluster" in capsys.readouterr().err
