"""The leftover search (eval/diagnosis/leftover.py) on hand-built terms: is what the named effect leaves structured,
and which second effect takes it or why none fits.

The simulator's own level is 0 on every cell (null terms with nothing in them), so a region's excess is its sum of
terms; the pairs' bootstrap draws are set so that the pair rule's outcome is known from docs/diagnosis.md's rules.
"""

from __future__ import annotations

import numpy as np

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.leftover import leftover_search
from drillgym.eval.diagnosis.rank import ModelScore

STABLE, ENTRY1 = STAGES.index("stable"), STAGES.index("entry1")
TRACKER_Y, FZ = ALL_CHANNELS.index("tracker_y_task_m"), ALL_CHANNELS.index("fz_n")
NULL = [Terms(np.zeros(N_CELLS), np.full(N_CELLS, 10.0), np.zeros(N_CELLS))]


def _terms(cells: dict[tuple[int, int], float]) -> list[Terms]:
    cell_sum = np.zeros(N_CELLS)
    for cell, j in cells.items():
        cell_sum[cell] = j
    return [Terms(cell_sum, np.full(N_CELLS, 10.0), np.zeros(N_CELLS))]


def _model(names, left, after, draws, ratio=10.0):
    fit = FitResult(names=names, params=[{} for _ in names], n_params=len(names), ho_terms=_terms(left))
    return ModelScore(
        fit,
        before=5.0,
        after=after,
        shrink=0.8,
        ci_low=0.6,
        ci_high=0.9,
        score=float(np.mean(draws)),
        score_draws=np.asarray(draws, float),
        leftover_ratio=ratio,
    )


NAMED = _model(("a",), {(STABLE, TRACKER_Y): 80.0, (ENTRY1, FZ): 20.0}, after=1.0, draws=[10.0, 10.0])


def test_a_leftover_concentrated_in_one_region_is_structured_and_its_best_second_effect_is_reported_with_why():
    """The pair takes 50 % of the leftover at tracker, stable, but scores better in only half the resamples (the
    pair rule asks for 95 %): not surely better."""
    pair = _model(("a", "b"), {(STABLE, TRACKER_Y): 40.0, (ENTRY1, FZ): 20.0}, after=0.6, draws=[9.0, 11.0])
    out = leftover_search(NAMED, [NAMED, pair], NULL)
    assert out["structured"] and out["region"] == "tracker, stable" and out["share"] == 0.8 and out["pairs"] == 1
    assert out["best"] == {"name": "a+b", "removed": 0.5, "why_not": "not surely better than the named effect alone"}
    assert "the best second effect there is `a+b` (it removes 50 % of it)" in out["note"]


def test_when_no_pair_takes_a_fifth_of_the_structured_leftover_none_fits():
    pair = _model(("a", "b"), {(STABLE, TRACKER_Y): 70.0, (ENTRY1, FZ): 20.0}, after=0.9, draws=[9.0, 9.0])
    out = leftover_search(NAMED, [NAMED, pair], NULL)
    assert out["best"]["removed"] == 0.125 and out["best"]["why_not"].endswith("none fits")
    out = leftover_search(NAMED, [NAMED], NULL)
    assert out["best"] is None and out["note"].endswith("no pair with it was fitted")


def test_a_leftover_near_the_simulators_level_or_spread_out_is_not_structured():
    small = _model(("a",), {(STABLE, TRACKER_Y): 80.0}, after=1.0, draws=[1.0], ratio=2.9)
    assert not leftover_search(small, [small], NULL)["structured"]
    spread = {(s, c): 1.0 for s in range(len(STAGES)) for c in range(len(ALL_CHANNELS))}  # 6 × 18 cells alike
    flat = _model(("a",), spread, after=1.0, draws=[1.0])
    out = leftover_search(flat, [flat], NULL)
    assert not out["structured"] and out["share"] < 0.25 and out["best"] is None


def test_a_named_pair_has_no_leftover_search():
    pair = _model(("a", "b"), {}, after=0.5, draws=[1.0])
    assert leftover_search(pair, [pair], NULL) is None
