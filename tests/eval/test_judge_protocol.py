"""The judge's fixed rules: which classical baseline a policy faces, and which training seed ships."""

import json

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.learning.best_classical import choose_best_classical, describe
from drillgym.eval.learning.ship_rule import selection_rows, ship_seed

DEFAULT, REF = "li2023_tuned", "li2023"


def _frame(shift: dict[str, float], noise: float = 0.01, seeds: int = 20) -> pd.DataFrame:
    """li2023 (+0.1 mm), li2023_tuned and candidates (li2023_tuned + shift per suite, same force and time)."""
    rng = np.random.default_rng(0)
    rows = []
    cells = [("paper", "paper"), ("generalisation", "g01"), ("generalisation", "g02"), ("heldout", "h1")]
    for suite, scenario in cells:
        for seed in range(seeds):
            dev = 0.04 + rng.normal(0, 0.005)
            common = {"run": "", "suite": suite, "scenario": scenario, "seed": seed, "lateral_force_max_n": 1.0,
                      "drill_time_s": 15.0}  # fmt: skip
            rows.append({**common, "controller": REF, "deviation_mean_mm": dev + 0.1})
            rows.append({**common, "controller": DEFAULT, "deviation_mean_mm": dev})
            for name, by_suite in shift.items():
                d = by_suite.get(suite, by_suite["*"]) + rng.normal(0, noise)
                rows.append({**common, "controller": name, "deviation_mean_mm": dev + d})
    return pd.DataFrame(rows)


def test_a_candidate_that_beats_the_default_on_every_check_becomes_the_best_baseline():
    frame = _frame({"table:a": {"*": -0.004}, "table:b": {"*": -0.008}}, noise=0.002)
    best, rows = choose_best_classical(frame, ["li2023", "table:a", "table:b", DEFAULT], DEFAULT, REF)
    assert best == "table:b"  # both pass; b has the lower deviation
    assert [r["run"] for r in rows if r["passes"]] == ["table:a", "table:b"]
    assert "**Best classical baseline: `table:b`**" in "\n".join(describe(best, DEFAULT, rows))


def test_a_candidate_whose_generalisation_gain_is_not_significant_leaves_the_default():
    frame = _frame({"table:a": {"*": -0.004, "generalisation": 0.0}}, noise=0.002)
    best, rows = choose_best_classical(frame, ["table:a"], DEFAULT, REF)
    assert best == DEFAULT
    assert not rows[0]["generalisation_better"] and rows[0]["paper_better"]


def test_a_candidate_missing_from_the_judge_is_an_error():
    with pytest.raises(ValueError, match="no judge episodes"):
        choose_best_classical(_frame({}), ["table:zzz"], DEFAULT, REF)


def _selection(folder, chosen: str, deviation: float, better: bool, feasible: bool = True) -> None:
    folder.mkdir(parents=True)
    row = {"candidate": chosen, "deviation_mean_mm": deviation, "d_deviation_mm": -0.001, "better": better,
           "feasible": feasible}  # fmt: skip
    other = {**row, "candidate": "checkpoint_1000", "deviation_mean_mm": 0.0}  # never the chosen one
    (folder / "selection.json").write_text(json.dumps({"chosen": chosen, "episodes": 40, "candidates": [other, row]}))


def test_the_ship_rule_takes_the_lowest_held_in_deviation_among_seeds_that_beat_the_base(tmp_path):
    _selection(tmp_path / "seed0", "final", 0.030, better=False)  # lowest, but did not beat the base
    _selection(tmp_path / "seed1", "checkpoint_5000", 0.034, better=True)
    _selection(tmp_path / "seed2", "final", 0.033, better=True, feasible=True)
    _selection(tmp_path / "seed3", "final", 0.033, better=True)  # ties go to the lower seed
    rows = selection_rows(tmp_path, [0, 1, 2, 3, 4])
    assert [r["found"] for r in rows] == [True, True, True, True, False]
    assert ship_seed(rows, "selection_deviation") == 2
    assert ship_seed(rows, "none") is None
    for r in rows[1:4]:
        r["beats_base"] = False
    assert ship_seed(rows, "selection_deviation") == 0  # none beat the base: the lowest of all
    with pytest.raises(ValueError, match="unknown ship rule"):
        ship_seed(rows, "best_on_judge")


def test_every_seed_is_compared_with_every_classical_baseline_whatever_the_rule_chose():
    from drillgym.eval.learning.best_classical import against_each, describe_against_each

    frame = _frame({"table:a": {"*": -0.004}, "policy": {"*": -0.01}}, noise=0.002)
    frame.loc[frame["controller"] == "policy", "run"] = "seed0"
    rows = against_each(frame, [DEFAULT, "table:a"], ["paper", "generalisation"])
    assert [(r["run"], r["baseline"]) for r in rows] == [("seed0", DEFAULT), ("seed0", "table:a")]
    assert rows[0]["paper_mean"] == pytest.approx(-0.01, abs=0.002)
    assert rows[1]["paper_mean"] == pytest.approx(-0.006, abs=0.002)
    assert rows[0]["paper_high"] < 0.0
    assert "**" in "\n".join(describe_against_each(rows, ["paper", "generalisation"]))
