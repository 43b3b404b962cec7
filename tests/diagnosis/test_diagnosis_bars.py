"""The diagnosis's decision rules on both sides of each bar, with stub scores (no simulator).

The bars are written out as docs/diagnosis.md states them, not imported, so moving a threshold or flipping a
comparison fails here: a model is named when it removes ≥ 50 % of the held-out excess gap with the 95 %
interval's low end ≥ 20 % and beats "no effect" on the penalised score; a gap counts when the excess interval
is above 0 and the median episode is ≥ 1.1 × the simulator's own level; a single effect that fails the
before-contact guard is not named. "Just below" a bar is 1e-9 under it: far above float rounding of these
O(1) numbers (1e-16), far below any difference the rules are meant to resolve.
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from diagnosis_stubs import stub_score

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import baseline_score, nameable, score_models
from drillgym.eval.diagnosis.report import why_not_named
from drillgym.eval.diagnosis.verdict import verdict as verdict_on
from drillgym.eval.diagnosis.where import gap_significance

NAME_SHRINK = 0.5
NAME_CI_LOW = 0.2
GAP_RATIO = 1.1
EPS = 1e-9


def _scored(shrink: float, ci_low: float, score: float):
    s = stub_score(("a",), before=10.0, after=5.0, null_gap=0.0, score_draws=np.full(8, score))
    s.shrink, s.ci_low, s.ci_high, s.score = shrink, ci_low, max(ci_low, shrink), score
    return s


@pytest.mark.parametrize(
    ("shrink", "ci_low", "score", "named"),
    [
        (NAME_SHRINK, NAME_CI_LOW, 99.0, True),  # exactly on both bars: named (≥)
        (NAME_SHRINK - EPS, 0.4, 99.0, False),  # shrink just under 50 %
        (0.9, NAME_CI_LOW - EPS, 99.0, False),  # interval's low end just under 20 %
        (0.9, 0.4, 100.0 - EPS, True),  # just better than no effect (s0 = 100)
        (0.9, 0.4, 100.0, False),  # tied with no effect: not named (strictly better needed)
        (math.nan, 0.4, 99.0, False),  # no shrink at all
    ],
)
def test_the_naming_bar(shrink, ci_low, score, named):
    assert nameable(_scored(shrink, ci_low, score), s0=100.0) is named


@pytest.mark.parametrize(
    ("shrink", "ci_low", "below"),
    [(NAME_SHRINK, NAME_CI_LOW, False), (NAME_SHRINK - EPS, 0.4, True), (0.9, NAME_CI_LOW - EPS, True)],
)
def test_the_report_says_below_the_bar_on_the_same_side_as_the_rule(shrink, ci_low, below):
    """report.md's "named?" column and the verdict's rule must agree on which side of the bar a model is."""
    effect = {"name": "a", "effects": ["a"], "named": False, "shrink": shrink, "ci_low": ci_low}
    text = why_not_named(effect, {"effects": [effect], "verdict": "unexplained"})
    assert ("below the bar" in text) is below
    if below:
        assert "shrink ≥ 50%" in text and "CI low ≥ 20%" in text


def _terms(level: float, n: float = 1.0, hot: tuple[int, int] | None = None, extra: float = 0.0) -> Terms:
    """One episode: ``level`` in one (stage 4, channel 0) cell over ``n`` terms; ``extra`` more in ``hot``."""
    cell_sum, cell_n = np.zeros(N_CELLS), np.zeros(N_CELLS)
    cell_sum[4, 0], cell_n[4, 0] = level, n
    if hot is not None:
        cell_sum[hot] += extra
        cell_n[hot] += 1.0
    return Terms(cell_sum, cell_n, np.zeros(N_CELLS))


@pytest.mark.parametrize(("ratio", "significant"), [(GAP_RATIO, True), (GAP_RATIO - EPS, False), (3.0, True)])
def test_the_gap_bar_on_the_median_episode(ratio, significant):
    """Null level 1 in every episode; every real episode at ``ratio`` (so the excess interval is above 0)."""
    null = [_terms(1.0) for _ in range(6)]
    real = [_terms(ratio) for _ in range(6)]
    sig = gap_significance(real, null)
    assert sig["median_episode_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert sig["significant"] is significant


def test_the_gap_bar_needs_the_paired_excess_interval_above_zero():
    """Null levels 0.5, 0.5, 2, 2, 2 (pooled 1.4): equal real episodes have median ratio 2/1.4 ≥ 1.1 but no excess
    (interval low end exactly 0: not significant); 1e-6 more in each episode makes the interval's low end > 0."""
    levels = [0.5, 0.5, 2.0, 2.0, 2.0]
    null = [_terms(v) for v in levels]
    same = gap_significance([_terms(v) for v in levels], null)
    assert same["median_episode_ratio"] == pytest.approx(2.0 / 1.4, rel=1e-12)
    assert same["excess_ci_low"] == 0.0 and same["significant"] is False
    more = gap_significance([_terms(v + 1e-6) for v in levels], null)
    assert more["excess_ci_low"] > 0.0 and more["significant"] is True


def test_held_out_shrink_and_penalised_score_are_the_documented_formulas():
    """Hand-computed: 4 held-out episodes of 10 terms, gap before 5 per term, after 2, the simulator's own 1:
    shrink = (5 − 2) / (5 − 1) = 0.75 in every resample (identical episodes: the interval is that point), and
    score = Σ J_after + k ln Σ N = 4·20 + 2 ln 40 for a 2-parameter fit."""
    before = [_terms(50.0, 10.0) for _ in range(4)]
    null = [_terms(10.0, 10.0) for _ in range(4)]
    fit = FitResult(("a",), [{}], 2, ho_terms=[_terms(20.0, 10.0) for _ in range(4)])
    (s,) = score_models([fit], before, null)
    assert s.before == pytest.approx(5.0) and s.after == pytest.approx(2.0)
    assert s.shrink == pytest.approx(0.75, rel=1e-12)
    assert s.ci_low == pytest.approx(0.75, rel=1e-12) and s.ci_high == pytest.approx(0.75, rel=1e-12)
    assert s.score == pytest.approx(80.0 + 2.0 * math.log(40.0), rel=1e-12)
    assert s.leftover_ratio == pytest.approx(2.0, rel=1e-12)
    assert baseline_score(before) == pytest.approx(200.0, rel=1e-12)


HOT = (STAGES.index("stable"), 3)


def _data() -> SimpleNamespace:
    """What ``verdict`` reads to locate an unexplained gap: the gap sits in the stable stage, channel 3."""
    return SimpleNamespace(
        baseline_terms=[_terms(1.0, hot=HOT, extra=9.0) for _ in range(4)], null_terms=[_terms(1.0) for _ in range(4)]
    )


def _single(score: float = 10.0):
    s = stub_score(("ft_drift",), before=10.0, after=2.0, null_gap=1.0, score_draws=np.full(8, score))
    s.ci_low = 0.6
    return s


SIGNIFICANT = {"significant": True}


def test_a_nameable_single_is_named_unless_it_fails_the_before_contact_guard():
    """The guard's use in the verdict: the same nameable single is named, or, contradicted before contact,
    not named, and the gap is located instead."""
    before = [_terms(100.0)]  # s0 = 100 > the single's score 10
    data = _data()
    verdict, chosen, location = verdict_on(SIGNIFICANT, [_single()], before, data, data.null_terms, False)
    assert verdict == "explained" and chosen is not None and chosen.name == "ft_drift" and chosen.named
    assert location is None
    verdict, chosen, location = verdict_on(SIGNIFICANT, [_single()], before, data, data.null_terms, True)
    assert verdict == "unexplained" and chosen is None
    assert location is not None and (location["stage"], location["channel"]) == ("stable", ALL_CHANNELS[3])


def test_no_significant_gap_names_nothing_however_good_the_model():
    data = _data()
    verdict, chosen, location = verdict_on({"significant": False}, [_single()], [_terms(100.0)], data, data.null_terms)
    assert (verdict, chosen, location) == ("no_gap", None, None)


@pytest.mark.parametrize(("score", "verdict"), [(100.0 - EPS, "explained"), (100.0, "unexplained")])
def test_the_verdict_names_a_single_only_when_it_beats_no_effect(score, verdict):
    data = _data()
    assert verdict_on(SIGNIFICANT, [_single(score)], [_terms(100.0)], data, data.null_terms)[0] == verdict
