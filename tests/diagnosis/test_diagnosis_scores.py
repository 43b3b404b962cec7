"""Held-out scores, the gap's significance, alternatives (rank.py) on hand-built episodes with hand-computed values.

Designs with two held-out episodes make the bootstrap's ends exact: with 1000 resamples of two episodes, about a
quarter draw the first episode twice and a quarter the second twice (binomial: never fewer than 26 in a thousand
at these sample sizes, P < 1e-60), so the 2.5 % and 97.5 % quantiles are each episode's value alone. Identical
episodes make every resample the same. Other comparisons are exact: the values are small ratios of exactly
representable numbers.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from diagnosis_stubs import stub_score

from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import ModelScore, alternatives, p_better, score_models
from drillgym.eval.diagnosis.where import gap_significance, locate


def _terms(j: float, n: float) -> Terms:
    """One episode: ``j`` summed over ``n`` terms, in one cell."""
    cell_sum, cell_n = np.zeros(N_CELLS), np.zeros(N_CELLS)
    cell_sum[4, 2], cell_n[4, 2] = j, n
    return Terms(cell_sum, cell_n, np.zeros(N_CELLS))


def _spread(level: float, n: int = 10) -> list[Terms]:
    """``n`` episodes of 10 terms at ``level`` times 1 to 3 per term, drawn: a spread each seed's resamples show."""
    return [_terms(level * 10.0 * u, 10.0) for u in np.random.default_rng(42).uniform(1.0, 3.0, n)]


# -- the gap's significance ------------------------------------------------------------------------------------------


def test_the_significance_of_identical_episodes_is_their_own_gap_null_ratio_and_excess():
    """Four episodes of 10 terms, 30 against the null's 10: gap 3, null 1, ratio 3, excess (30 − 10) / 10 = 2."""
    got = gap_significance([_terms(30.0, 10.0)] * 4, [_terms(10.0, 10.0)] * 4)
    assert got == {"gap": 3.0, "null": 1.0, "median_episode_ratio": 3.0, "excess_ci_low": 2.0, "significant": True}


def test_the_excess_interval_reaches_the_episode_with_the_least_excess():
    """Excess per term 0.2 (12 against 10 over 10 terms) and 4 (50 against 10): the low end is 0.2; the median
    ratio is that of the two episodes' (1.2 and 5) over the pooled null (1): 3.1."""
    got = gap_significance([_terms(12.0, 10.0), _terms(50.0, 10.0)], [_terms(10.0, 10.0), _terms(10.0, 10.0)])
    assert got["excess_ci_low"] == 0.2 and got["median_episode_ratio"] == 3.1 and got["gap"] == 3.1


def test_real_and_null_episodes_are_paired_one_to_one():
    with pytest.raises(ValueError, match="zip"):
        gap_significance([_terms(30.0, 10.0)] * 3, [_terms(10.0, 10.0)] * 4)


def test_the_significance_is_reproducible_from_its_seed_zero_by_default():
    """On spread episodes each seed draws other resamples (the low end moves); the same seed gives the same."""
    real, null = _spread(2.0), _spread(1.0)
    lows = {s: gap_significance(real, null, s)["excess_ci_low"] for s in (0, 1)}
    assert lows[0] != lows[1]
    assert gap_significance(real, null)["excess_ci_low"] == lows[0] == gap_significance(real, null, 0)["excess_ci_low"]


# -- held-out scores -------------------------------------------------------------------------------------------------

BEFORE = [_terms(50.0, 10.0), _terms(50.0, 10.0)]
"""Two held-out episodes at 5 per term before any model."""
NULL = [_terms(10.0, 10.0), _terms(10.0, 10.0)]
"""The simulator's own level: 1 per term."""


def _fit(name: str, after: tuple[float, float], k: int = 1, **kw) -> FitResult:
    """A fitted model whose held-out episodes sum to ``after`` over 10 terms each."""
    return FitResult((name,), [{}], k, ho_terms=[_terms(a, 10.0) for a in after], **kw)


def test_the_shrinks_interval_spans_each_held_out_episode_alone():
    """After the model 4 and 1 per term: shrink (5 − 4) / 4 = 0.25 and (5 − 1) / 4 = 1 alone, 0.625 pooled."""
    (s,) = score_models([_fit("a", (40.0, 10.0))], BEFORE, NULL)
    assert (s.shrink, s.ci_low, s.ci_high) == (0.625, 0.25, 1.0)
    assert (s.before, s.after, s.leftover_ratio) == (5.0, 2.5, 2.5)


def test_the_best_model_in_each_resample_gives_its_probability_of_being_best():
    """a is better on the first episode, b on the second; a tie (one of each) goes to the model listed first.
    So a is best in the resamples with the first episode at least once: 3/4 of them (±0.05: five binomial standard
    deviations of 1000 resamples); together the probabilities are 1."""
    a, b = score_models([_fit("a", (10.0, 40.0)), _fit("b", (40.0, 10.0))], BEFORE, NULL)
    assert (a.name, b.name) == ("a", "b") and a.score == b.score
    assert a.p_best + b.p_best == 1.0 and abs(a.p_best - 0.75) < 0.05
    assert type(a.p_best) is float


def test_a_model_with_more_parameters_pays_k_ln_n_in_every_resample():
    """The same held-out terms with 1 and 3 parameters: the penalty (k ln 20) makes the 1-parameter model the best in
    every resample, and its score 50 + ln 20 against 50 + 3 ln 20."""
    one, three = score_models([_fit("three", (40.0, 10.0), k=3), _fit("one", (40.0, 10.0), k=1)], BEFORE, NULL)
    assert (one.name, one.score, one.p_best) == ("one", 50.0 + math.log(20.0), 1.0)
    assert (three.score, three.p_best) == (50.0 + 3.0 * math.log(20.0), 0.0)


def test_a_random_effect_is_penalised_by_its_effective_parameter_count():
    (s,) = score_models([_fit("a", (40.0, 10.0), k=5, penalty_params=1.5)], BEFORE, NULL)
    assert s.score == 50.0 + 1.5 * math.log(20.0)


def test_the_penalty_counts_at_least_two_terms():
    """One held-out episode of a single term: k ln max(1, 2) = ln 2 (ln 1 = 0 would make parameters free)."""
    fit = FitResult(("a",), [{}], 1, ho_terms=[_terms(0.5, 1.0)])
    (s,) = score_models([fit], [_terms(5.0, 1.0)], [_terms(1.0, 1.0)])
    assert s.score == 0.5 + math.log(2.0)


def test_failed_fits_and_fits_without_every_held_out_episode_are_left_out_the_rest_sorted_best_first():
    failed = _fit("failed", (10.0, 10.0), error="replay failed")
    short = FitResult(("short",), [{}], 1, ho_terms=[_terms(10.0, 10.0)])
    worse, better = _fit("worse", (40.0, 40.0)), _fit("better", (10.0, 10.0))
    scores = score_models([failed, worse, short, better], BEFORE, NULL)
    assert [s.name for s in scores] == ["better", "worse"]


def test_without_an_excess_gap_the_shrink_and_its_interval_are_nan_without_a_warning():
    """Before = the simulator's own level: there is nothing to shrink (no division by 0, no warning printed), whether
    the model lowers the gap (x / 0) or not (0 / 0)."""
    for after in ((5.0, 5.0), (10.0, 10.0)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            (s,) = score_models([_fit("a", after)], NULL, NULL)
        assert math.isnan(s.shrink) and math.isnan(s.ci_low) and math.isnan(s.ci_high)


def test_the_leftover_ratio_is_the_gap_after_over_the_simulators_own_level():
    """After 2.5 per term against a null level of 2 (20 over 10 terms): 1.25."""
    (s,) = score_models([_fit("a", (40.0, 10.0))], BEFORE, [_terms(20.0, 10.0)] * 2)
    assert s.leftover_ratio == 1.25


def test_without_a_null_level_there_is_no_leftover_ratio():
    zero = [_terms(0.0, 10.0), _terms(0.0, 10.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (s,) = score_models([_fit("a", (10.0, 10.0))], BEFORE, zero)
    assert math.isnan(s.leftover_ratio) and s.shrink == 0.8


def test_the_scores_are_reproducible_from_their_seed_zero_by_default():
    before, null = _spread(3.0), _spread(1.0)
    fit = FitResult(("a",), [{}], 1, ho_terms=_spread(1.5)[::-1])
    lows = {seed: score_models([fit], before, null, seed)[0].ci_low for seed in (0, 1)}
    assert lows[0] != lows[1]
    assert score_models([fit], before, null)[0].ci_low == lows[0] == score_models([fit], before, null, 0)[0].ci_low


# -- p_better and alternatives ---------------------------------------------------------------------------------------


def _model(names: tuple[str, ...], draws: np.ndarray, shrink: float = 0.8) -> ModelScore:
    s = stub_score(names, 5.0, 1.0, 1.0, draws)
    s.shrink, s.ci_low = shrink, 0.5
    return s


def test_a_model_is_better_in_a_resample_only_when_it_scores_strictly_lower():
    draws = np.arange(100.0)
    assert p_better(_model(("a",), draws), _model(("b",), draws)) == 0.0
    assert p_better(_model(("a",), draws - 0.5), _model(("b",), draws)) == 1.0


NAMED_DRAWS = np.full(100, 50.0)


def _better_in(share: int) -> np.ndarray:
    """Score draws better (lower) than the named model's in ``share`` of 100 resamples."""
    return np.where(np.arange(100) < share, 40.0, 60.0)


def test_an_alternative_is_better_in_at_least_5_percent_of_the_resamples():
    named = _model(("a",), NAMED_DRAWS)
    at, below = _model(("b",), _better_in(5)), _model(("c",), _better_in(4))
    assert alternatives([named, at, below], named, s0=100.0) == [{"name": "b", "effects": ["b"], "p_better": 0.05}]


def test_alternatives_are_listed_most_likely_first():
    named = _model(("a",), NAMED_DRAWS)
    b, c, d = (_model((n,), _better_in(k)) for n, k in (("b", 10), ("c", 40), ("d", 20)))
    assert [x["name"] for x in alternatives([named, b, c, d], named, 100.0)] == ["c", "d", "b"]


def test_the_named_pair_in_the_other_order_is_not_an_alternative_to_itself():
    named = _model(("a", "b"), NAMED_DRAWS)
    other_order = _model(("b", "a"), _better_in(50))
    swap = _model(("a", "c"), _better_in(30))
    assert [x["name"] for x in alternatives([named, other_order, swap], named, 100.0)] == ["a+c"]


def test_a_pair_is_not_an_alternative_when_one_of_its_effects_is_one_alone():
    named = _model(("a",), NAMED_DRAWS)
    c, cd = _model(("c",), _better_in(30)), _model(("c", "d"), _better_in(60))
    assert [x["name"] for x in alternatives([named, cd, c], named, 100.0)] == ["c"]


def test_an_alternative_must_itself_be_nameable():
    named = _model(("a",), NAMED_DRAWS)
    weak = _model(("b",), _better_in(50), shrink=0.4)
    assert alternatives([named, weak], named, 100.0) == []


# -- where the gap lies, without warnings ----------------------------------------------------------------------------


def test_cells_without_null_terms_are_located_without_a_warning():
    """Cells the null never reaches (0 / 0) count at a null level of 0 there, silently."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        top = locate([_terms(5.0, 1.0)], [_terms(0.0, 0.0)], top=1)
    assert top == [{"channel": "fz_n", "stage": "stable", "share": 1.0}]
