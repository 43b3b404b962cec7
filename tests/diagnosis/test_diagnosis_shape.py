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

import drillgym.eval.diagnosis.shape as shape
import drillgym.eval.diagnosis.verdict as rules
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import ModelScore
from drillgym.eval.diagnosis.report import shape_lines, why_not_named
from drillgym.eval.diagnosis.shape import SHAPE_REMOVE_MIN, SHAPE_SHARE_MIN, shape_test

APPROACH, STABLE = STAGES.index("approach"), STAGES.index("stable")
FZ, FY, FY_HF = ALL_CHANNELS.index("fz_n"), ALL_CHANNELS.index("fy_n"), ALL_CHANNELS.index("fy_hf_n")


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


def test_each_region_is_one_stage_group_crossed_with_one_channel_group():
    masks = shape.region_masks()
    assert len(masks) == 7 * 4 and masks.keys() == shape.REGIONS.keys()
    expected = {
        "thrust, entry": [(s, "fz_n") for s in ("entry1", "entry2", "entry3")],
        "lateral force, before contact": [("approach", "fx_n"), ("approach", "fy_n")],
        "thrust HF, retract": [("retract", "fz_hf_n")],
        "tracker, stable": [("stable", f"tracker_{a}_task_m") for a in "xyz"],
        "joint angles, entry": [(s, f"q{j}_rad") for s in ("entry1", "entry2", "entry3") for j in range(6)],
    }
    for name, cells in expected.items():
        want = np.zeros((len(STAGES), len(ALL_CHANNELS)), dtype=bool)
        for stage, channel in cells:
            want[STAGES.index(stage), ALL_CHANNELS.index(channel)] = True
        assert masks[name].dtype == bool and np.array_equal(masks[name], want), name
    covered = sum(m.astype(int) for m in masks.values())
    assert covered.max() == 1 and covered.sum() == len(STAGES) * len(ALL_CHANNELS)  # a partition of the cells


def test_a_gap_with_no_excess_has_no_region_to_explain():
    result = shape_test(_model({}), [_terms({})], NULL)
    assert result == {"name": "an_effect", "passes": True, "regions": [], "reason": None}


def test_a_small_gap_is_judged_by_its_shares_not_its_size():
    """Excess 0.3 + 0.2 (total below 1): the untouched 40 % region still refuses the model."""
    before = [_terms({(STABLE, FZ): 0.3, (STABLE, FY): 0.2})]
    result = shape_test(_model({(STABLE, FY): 0.2}), before, NULL)
    assert not result["passes"] and result["reason"].startswith(
        "the gap has 40 % of its excess at lateral force, stable"
    )


def test_the_reason_names_the_largest_failing_region_first_and_rounds_to_whole_percent():
    """Thrust, stable (60 %, 10.45 % removed) and lateral force, stable (40 %, none removed) both fail; the larger is
    named, though its name sorts after the other's."""
    before = [_terms({(STABLE, FZ): 60.0, (STABLE, FY): 40.0})]
    result = shape_test(_model({(STABLE, FZ): 60.0 - 0.1045 * 60.0, (STABLE, FY): 40.0}), before, NULL)
    assert [r["region"] for r in result["regions"]] == ["thrust, stable", "lateral force, stable"]
    assert result["reason"] == "the gap has 60 % of its excess at thrust, stable; the model removes 10 % of it"


def _raw_data(raw: dict[tuple[int, int], float]) -> SimpleNamespace:
    """Raw terms of one held-out episode; the simulator's own raw level is 1 per term (10 per cell of 10 terms)."""
    own = {(s, c): 10.0 for s in range(len(STAGES)) for c in range(len(ALL_CHANNELS))}
    return SimpleNamespace(ho=[0], raw_terms=[_terms(own | raw)], null_raw_terms=[_terms(own)])


def _model_raw(after: dict[tuple[int, int], float], raw_after: dict[tuple[int, int], float]) -> ModelScore:
    m = _model(after)
    own = {(s, c): 10.0 for s in range(len(STAGES)) for c in range(len(ALL_CHANNELS))}
    m.fit.ho_raw_terms = [_terms(own | raw_after)]
    return m


def test_the_second_half_bars_hold_at_their_values():
    assert (shape.CREATED_MODEL_MIN, shape.CREATED_RATIO_MIN) == (10.0, 5.0)


@pytest.mark.parametrize(
    ("data_fz", "model_fz", "passes"),
    [
        (20.0, 100.0, False),  # 2x in the data, 10x under the model: exactly on both bars
        (20.0, 99.0, True),  # just under 10x
        (5.0, 100.0, False),  # below the simulator's own level in the data: counted as 1x
        (30.0, 150.0, False),  # 3x in the data, 15x under the model: five times the data's
        (30.0, 149.0, True),  # just under five times the data's
        (1.0, 95.0, True),  # fifty times the data's but under 10x the simulator's own level
    ],
)
def test_a_model_that_makes_a_gap_where_the_raw_data_have_none_is_refused(data_fz, model_fz, passes):
    """A torque gap (stable) the model removes in full, so the first half passes; on the raw gap the stable thrust is
    at ``data_fz / 10`` times the simulator's own level in the data and ``model_fz / 10`` under the model. Refused
    where the model leaves 10 times that level or more and five times the data's (the data's taken as at least 1)."""
    ty = ALL_CHANNELS.index("ty_nm")
    before = [_terms({(STABLE, ty): 100.0})]
    data = _raw_data({(STABLE, ty): 500.0, (STABLE, FZ): data_fz})
    model = _model_raw({}, {(STABLE, FZ): model_fz})
    result = shape_test(model, before, NULL, data)
    assert result["regions"][0]["passes"]  # the first half alone would name it
    assert result["passes"] is passes
    top = result["created"][0]
    assert top["region"] == "thrust, stable"
    assert top["before"] == pytest.approx(data_fz / 10) and top["after"] == pytest.approx(model_fz / 10)
    if (data_fz, model_fz) == (20.0, 100.0):
        assert result["reason"] == (
            "the model makes a gap 10 times the simulator's own level at thrust, stable, where the data have 2 times "
            "it (raw, before the per-specimen fit)"
        )


def test_without_the_models_raw_terms_only_the_first_half_is_judged():
    before = [_terms({(STABLE, FZ): 100.0})]
    data = _raw_data({(STABLE, FZ): 500.0})
    result = shape_test(_model({}), before, NULL, data)
    assert result["passes"] and "created" not in result
