"""``drillgym tune-table``: a table tuned on tuning episodes only, written once, loadable as a controller."""

import json

import pandas as pd
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.schedule_table import load_table
from drillgym.envs.seeds import Purpose, purpose_of
from drillgym.eval.bench.tune_table import anchor_jobs, anchor_scenarios, tune_anchor
from drillgym.eval.cli import main


def test_the_anchors_are_the_nominal_plan_each_range_end_and_each_other_bone():
    names = [name for name, _ in anchor_scenarios()]
    assert names[0] == "nominal" and len(names) == 11
    assert "beta_deg=15" in names and "feed_mm_s=1" in names and "bone=porcine_femur" in names
    assert all(len(sc) == 1 for _, sc in anchor_scenarios()[1:])  # each moves one plan feature


def test_anchor_jobs_use_tuning_seeds_and_refuse_bad_budgets():
    jobs = anchor_jobs(seeds=3, evals=5, seed_offset=7)
    assert {purpose_of(s) for job in jobs for s in job.seeds} == {Purpose.TUNE}
    with pytest.raises(ValueError, match="seeds >= 2"):
        anchor_jobs(seeds=1)


def test_an_anchor_search_starts_at_the_base_and_never_keeps_a_worse_tuning():
    job = anchor_jobs(seeds=2, evals=4)[0]
    result = tune_anchor(job)
    first = result["evaluations"][0]
    assert first["action"] == [0.0] * 4 and first["reward"] == 0.0  # the base against itself
    assert len(result["evaluations"]) <= 4
    best = max(e["reward"] for e in result["evaluations"])
    assert result["reward"] == max(best, 0.0)
    if best <= 0.0:
        assert result["action"] == [0.0] * 4


def test_tune_table_writes_a_table_that_loads_and_never_overwrites_it(tmp_path, capsys):
    out = tmp_path / "tt"
    argv = ["tune-table", "--seeds", "2", "--evals", "2", "--out", str(out)]
    assert main(argv) == 0
    table = load_table(str(out / "table.json"))
    assert len(table.anchors) == 11 and table.meta["seed_namespace"] == "tune"
    assert make_controller(f"table:{out / 'table.json'}").spec.base == "li2023_tuned"
    evaluations = pd.read_csv(out / "evaluations.csv")
    assert set(evaluations["anchor"]) == {a.name for a in table.anchors}
    assert json.loads((out / "table.json").read_text())["meta"]["holes"] == 11 * 2 * 3
    assert (out / "tune_table.png").stat().st_size > 0
    assert main(argv) == 2
    assert "never overwritten" in capsys.readouterr().err


def test_an_anchor_search_is_reproducible():
    """The table is reproducible from its command: the episodes are fixed and Nelder–Mead is deterministic."""
    job = anchor_jobs(seeds=2, evals=3)[3]
    assert tune_anchor(job) == tune_anchor(job)
