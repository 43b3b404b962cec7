"""The shape test (eval/diagnosis/shape.py) on hand-built terms: a model must explain every large region of the gap.

The simulator's own level is 0 on every cell here (null terms with nothing in them), so a cell's excess is its sum
of terms and each share below is a ratio of small integers, exact in floating point where the test compares
exactly. The bars (SHAPE_SHARE_MIN = 25 % of the excess, SHAPE_REMOVE_MIN = 20 % of it removed) are tested on both
sides.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import drillgym.eval.diagnosis.verdict as rules
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import ModelScore
from drillgym.eval.diagnosis.report import shape_lines, why_not_named
from drillgym.eval.diagnosis.shape import SHAPE_REMOVE_MIN, SHAPE_SHARE_MIN, shape_test

APPROACH, STABLE = STAGES.index("approach"), STAGES.index("stable")
FZ, FY_HF = ALL_CHANNELS.index("fz_n"), ALL_CHANNELS.index("fy_hf_n")


def _terms(cells: dict[tuple[int, int], float]) -> Terms:
    """One episode's terms: ``{(stage, channel): sum of terms}`` over 10 terms per cell, nothing elsewhere."""
    cell_sum, cell_n = np.zeros(N_CELLS), np.zeros(N_CELLS)
    for cell, j in cells.items():
        cell_sum[cell], cell_n[cell] = j, 10.0
    return Terms(cell_sum, cell_n, np.zeros(N_CELLS))


NULL = [_terms({})]


def _model(after: dict[tuple[int, int], float], score: float = 10.0) -> ModelScore:
    fit = FitResult(names=("an_effect",), params=[{}], n_params=1, ho_terms=[_terms(after)])
    return ModelScore(fit, before=5.0, after=1.0, shrink=0.8, ci_low=0.6, ci_high=0.9, score=score)


def test_the_bars_hold_at_their_values():
    assert (SHAPE_SHARE_MIN, SHAPE_REMOVE_MIN) == (0.25, 0.2)


@pytest.mark.parametrize(("after_x", "passes"), [(20.0, True), (20.25, False)])
def test_a_region_with_a_quarter_of_the_excess_must_lose_a_fifth_of_it(after_x, passes):
    """Before contact holds 25 of 100 (the bar exactly); 5 removed is 20 % (passes), 4.75 is 19 % (refused)."""
    before = [_terms({(APPROACH, FZ): 25.0, (STABLE, FZ): 75.0})]
    result = shape_test(_model({(APPROACH, FZ): after_x}), before, NULL)
    assert result["passes"] is passes
    regions = {r["region"]: r for r in result["regions"]}
    assert set(regions) == {"thrust, before contact", "thrust, stable"}
    assert regions["thrust, before contact"]["share"] == 0.25 and regions["thrust, stable"]["removed"] == 1.0
    if not passes:
        assert (
            result["reason"] == "the gap has 25 % of its excess at thrust, before contact; the model removes 19 % of it"
        )


def test_a_region_below_a_quarter_of_the_excess_may_stay_untouched():
    before = [_terms({(APPROACH, FZ): 24.0, (STABLE, FZ): 76.0})]
    result = shape_test(_model({(APPROACH, FZ): 24.0}), before, NULL)
    assert result["passes"] and [r["region"] for r in result["regions"]] == ["thrust, stable"]


def test_a_once_per_turn_force_fitted_to_a_broadband_gap_is_refused_for_the_band_it_leaves():
    """A gap split 60 / 40 between the stable LF force and its HF power; the model takes the LF part and makes the HF
    worse: refused on the HF region, named in words."""
    before = [_terms({(STABLE, FZ): 60.0, (STABLE, FY_HF): 40.0})]
    result = shape_test(_model({(STABLE, FY_HF): 44.0}), before, NULL)
    assert not result["passes"]
    assert result["reason"] == "the gap has 40 % of its excess at lateral force HF, stable; the model makes it worse"


def test_decide_names_a_nameable_single_only_with_the_gaps_shape_and_says_why_not_otherwise():
    before = [_terms({(APPROACH, FZ): 40.0, (STABLE, FZ): 60.0})]  # "no effect" scores 100
    data = SimpleNamespace(baseline_terms=before, null_terms=NULL)
    good = _model({(APPROACH, FZ): 8.0})
    verdict, chosen, location, _ = rules.decide({"significant": True}, [good], before, data, NULL)
    assert verdict == "explained" and chosen is good and good.shape is not None and good.shape["passes"]
    cutting_only = _model({(APPROACH, FZ): 40.0})  # removes the stable 60 %, leaves the 40 % before contact
    verdict, chosen, location, _ = rules.decide({"significant": True}, [cutting_only], before, data, NULL)
    assert verdict == "unexplained" and chosen is None and location["channel"] == "fz_n"
    entry = cutting_only.to_json()
    assert (
        entry["shape"]["reason"]
        == "the gap has 40 % of its excess at thrust, before contact; the model removes 0 % of it"
    )
    res = {"effects": [entry], "verdict": verdict}
    assert why_not_named(entry, res) == f"no: not the gap's shape ({entry['shape']['reason']})"
    text = "\n".join(shape_lines(res))
    assert "`an_effect` **refused** — the gap has 40 % of its excess at thrust, before contact" in text


def test_a_model_that_is_not_nameable_is_not_shape_tested():
    before = [_terms({(STABLE, FZ): 100.0})]
    weak = _model({}, score=100.0)  # scores no better than "no effect"
    rules.decide({"significant": True}, [weak], before, SimpleNamespace(baseline_terms=before, null_terms=NULL), NULL)
    assert weak.shape is None and weak.to_json()["shape"] is None
