"""The decision (eval/diagnosis/verdict.py) on stub scores: which model is named, the guard, where the gap lies.

Scores are built by hand with chosen numbers (no simulator, no fit); the pair rule itself is tested in
test_diagnosis_pair_rule.py and test_diagnosis_second_effect.py, so here it is replaced by a recorder that says
which pairs beat the best single, and what the verdict asked it. The expected values are written out from
docs/diagnosis.md's rules, not computed with the code's helpers. Comparisons are exact: every number here is a
small sum of exactly representable values.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import drillgym.eval.diagnosis.verdict as rules
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import ModelScore

STABLE, ENTRY1 = STAGES.index("stable"), STAGES.index("entry1")
FZ, TX = ALL_CHANNELS.index("fz_n"), ALL_CHANNELS.index("tx_nm")
SIGNIFICANT = {"significant": True}


def _terms(cells: dict[tuple[int, int], tuple[float, float]]) -> Terms:
    """One episode's terms: ``{(stage, channel): (sum of terms, number of terms)}``, nothing elsewhere."""
    cell_sum, cell_n = np.zeros(N_CELLS), np.zeros(N_CELLS)
    for cell, (j, n) in cells.items():
        cell_sum[cell], cell_n[cell] = j, n
    return Terms(cell_sum, cell_n, np.zeros(N_CELLS))


BEFORE = [_terms({(STABLE, FZ): (60.0, 10.0)}), _terms({(STABLE, FZ): (40.0, 10.0)})]
"""Held-out episodes without a model: "no effect" scores Σ J = 100."""
NULL = [_terms({(STABLE, FZ): (2.0, 4.0)}), _terms({(STABLE, FZ): (2.0, 4.0)})]
"""The simulator's own level on them: Σ J / Σ N = 4 / 8 = 0.5."""
G_NULL = 0.5


def _data() -> SimpleNamespace:
    """All episodes (what an unexplained gap is located on): against a null level of 1 per term, 3 excess in
    (stable, fz_n) and 1 in (entry1, tx_nm), so the gap lies at fz_n, stable with 3 / 4 of the excess."""
    level = {(STABLE, FZ): (1.0, 1.0), (ENTRY1, TX): (1.0, 1.0)}
    real = {(STABLE, FZ): (4.0, 1.0), (ENTRY1, TX): (2.0, 1.0)}
    return SimpleNamespace(baseline_terms=[_terms(real)], null_terms=[_terms(level)])


LOCATION = {"channel": "fz_n", "stage": "stable", "share": 0.75}


def _model(names: tuple[str, ...], score: float, shrink: float = 0.8, ci_low: float = 0.6) -> ModelScore:
    """A scored model; nameable against "no effect" (100) unless ``shrink`` < 0.5, ``ci_low`` < 0.2 or score ≥ 100."""
    fit = FitResult(names=names, params=[{} for _ in names], n_params=len(names))
    return ModelScore(fit, before=5.0, after=1.0, shrink=shrink, ci_low=ci_low, ci_high=0.9, score=score)


class _PairRule:
    """Stands for ``pair_beats``: the pairs in ``beats`` beat the best single; every call is recorded."""

    def __init__(self, *beats: ModelScore) -> None:
        self.beats, self.calls = beats, []

    def __call__(self, *args: Any) -> bool:
        self.calls.append(args)
        return any(args[0] is p for p in self.beats)


def _verdict(monkeypatch, scores, *beats, contradicted=False, significance=SIGNIFICANT):
    rule = _PairRule(*beats)
    monkeypatch.setattr(rules, "pair_beats", rule)
    return rules.verdict(significance, scores, BEFORE, _data(), NULL, contradicted), rule


def test_no_significant_gap_is_no_gap_and_names_nothing(monkeypatch):
    single = _model(("a",), 10.0)
    pair = _model(("a", "b"), 5.0)
    (verdict, chosen, location), rule = _verdict(monkeypatch, [pair, single], pair, significance={"significant": False})
    assert (verdict, chosen, location) == ("no_gap", None, None)
    assert not single.named and not pair.named and rule.calls == []


def test_the_best_single_is_the_first_single_in_score_order_even_behind_a_pair(monkeypatch):
    pair, a, b = _model(("a", "b"), 5.0), _model(("a",), 10.0), _model(("b",), 20.0)
    (verdict, chosen, location), _ = _verdict(monkeypatch, [pair, a, b])
    assert (verdict, chosen, location) == ("explained", a, None)
    assert a.named and not b.named and not pair.named


def test_only_the_best_single_is_considered_a_nameable_runner_up_is_not_named(monkeypatch):
    weak = _model(("a",), 10.0, shrink=0.4)  # scores best but removes too little of the gap
    good = _model(("b",), 20.0)
    (verdict, chosen, location), _ = _verdict(monkeypatch, [weak, good])
    assert (verdict, chosen, location) == ("unexplained", None, LOCATION)
    assert not good.named and not weak.named


@pytest.mark.parametrize(("score", "named"), [(99.0, True), (100.0, False)])
def test_the_best_single_must_score_below_no_effect_summed_over_the_held_out_episodes(monkeypatch, score, named):
    """ "No effect" scores Σ J of the held-out episodes before any model: 60 + 40 = 100."""
    single = _model(("a",), score)
    (verdict, chosen, _), _ = _verdict(monkeypatch, [single])
    assert (verdict == "explained", chosen is single, single.named) == (named, named, named)


def test_a_contradicted_best_single_is_not_named_and_the_gap_is_located(monkeypatch):
    single = _model(("a",), 10.0)
    (verdict, chosen, location), _ = _verdict(monkeypatch, [single], contradicted=True)
    assert (verdict, chosen, location) == ("unexplained", None, LOCATION) and not single.named


def test_the_pair_rule_is_asked_with_the_best_single_the_pairs_roles_and_the_simulators_own_level(monkeypatch):
    """Pair (b, a) built on b; the single a scores better, so a is its first effect and b its second."""
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("b", "a"), 5.0)
    (verdict, chosen, _), rule = _verdict(monkeypatch, [pair, a, b], pair)
    assert (verdict, chosen) == ("explained", pair) and pair.named and not a.named
    ((got_pair, best, first, second, g_null, null),) = rule.calls
    assert (got_pair, best, first, second) == (pair, a, a, b)
    assert g_null == G_NULL and null is NULL


def test_a_pair_that_passes_the_pair_rule_is_named_over_the_named_single_even_scoring_worse(monkeypatch):
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("a", "b"), 15.0)  # listed after the single; the pair rule is what decides
    (verdict, chosen, _), _ = _verdict(monkeypatch, [a, pair, b], pair)
    assert (verdict, chosen) == ("explained", pair)


def test_a_pair_that_passes_the_pair_rule_is_named_when_the_single_is_contradicted(monkeypatch):
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("a", "b"), 5.0)
    (verdict, chosen, _), _ = _verdict(monkeypatch, [pair, a, b], pair, contradicted=True)
    assert (verdict, chosen) == ("explained", pair)


@pytest.mark.parametrize(("shrink", "ci_low", "score"), [(0.49, 0.6, 5.0), (0.8, 0.19, 5.0), (0.8, 0.6, 100.0)])
def test_a_pair_must_itself_be_nameable(monkeypatch, shrink, ci_low, score):
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("a", "b"), score, shrink=shrink, ci_low=ci_low)
    (verdict, chosen, _), _ = _verdict(monkeypatch, [pair, a, b], pair)
    assert (verdict, chosen) == ("explained", a) and not pair.named


def test_a_pair_that_fails_the_pair_rule_is_not_named(monkeypatch):
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("a", "b"), 5.0)
    (verdict, chosen, _), rule = _verdict(monkeypatch, [pair, a, b])
    assert (verdict, chosen) == ("explained", a) and len(rule.calls) == 1


def test_of_two_pairs_that_pass_the_lower_score_is_named_whichever_comes_first(monkeypatch):
    a, b, c = _model(("a",), 10.0), _model(("b",), 20.0), _model(("c",), 30.0)
    low, high = _model(("a", "b"), 4.0), _model(("a", "c"), 6.0)
    for order in ([high, low, a, b, c], [low, high, a, b, c]):
        (verdict, chosen, _), _ = _verdict(monkeypatch, order, low, high)
        assert (verdict, chosen) == ("explained", low)
    tie = _model(("a", "c"), 4.0)  # a tie keeps the first one found
    (_, chosen, _), _ = _verdict(monkeypatch, [low, tie, a, b, c], low, tie)
    assert chosen is low


def test_a_pair_without_its_singles_or_without_any_single_is_not_judged(monkeypatch):
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    orphan = _model(("x", "y"), 4.0)  # neither of its effects was fitted alone
    (verdict, chosen, _), rule = _verdict(monkeypatch, [orphan, a], orphan)
    assert (verdict, chosen) == ("explained", a) and rule.calls == []
    judged = _model(("a", "b"), 5.0)  # a pair after the orphan is still judged
    (verdict, chosen, _), rule = _verdict(monkeypatch, [orphan, judged, a, b], orphan, judged)
    assert (verdict, chosen) == ("explained", judged) and [c[0] for c in rule.calls] == [judged]
    pair = _model(("a", "b"), 5.0)
    (verdict, chosen, location), rule = _verdict(monkeypatch, [pair], pair)  # no single at all
    assert (verdict, chosen, location) == ("unexplained", None, LOCATION) and rule.calls == []


def test_a_pair_is_judged_with_its_first_effect_as_given_when_only_that_single_exists(monkeypatch):
    """pair_roles keeps the pair's own order when a single is missing: first = a, second = None."""
    a = _model(("a",), 10.0)
    pair = _model(("a", "b"), 5.0)
    (_, chosen, _), rule = _verdict(monkeypatch, [pair, a], pair)
    assert chosen is pair and [c[2:4] for c in rule.calls] == [(a, None)]


def test_three_effect_models_are_neither_singles_nor_pairs(monkeypatch):
    triple = _model(("a", "b", "c"), 1.0)
    (verdict, chosen, _), rule = _verdict(monkeypatch, [triple], triple)
    assert (verdict, chosen) == ("unexplained", None) and rule.calls == []


def test_an_unexplained_gap_is_located_at_the_cell_with_the_most_excess_and_its_share():
    assert rules.gap_location(_data()) == LOCATION


class _Guard:
    """Stands for ``single_contradicted``: answers ``contradicted``; every call is recorded."""

    def __init__(self, contradicted: bool) -> None:
        self.contradicted, self.calls = contradicted, []

    def __call__(self, *args: Any) -> bool:
        self.calls.append(args)
        return self.contradicted


@pytest.mark.parametrize("contradicted", [False, True])
def test_the_before_contact_guard_is_judged_on_the_nameable_best_single_and_decides_whether_it_is_named(
    monkeypatch, contradicted
):
    guard = _Guard(contradicted)
    monkeypatch.setattr(rules, "single_contradicted", guard)
    monkeypatch.setattr(rules, "pair_beats", _PairRule())
    a, b = _model(("a",), 10.0), _model(("b",), 20.0)
    pair = _model(("a", "b"), 5.0)
    verdict, chosen, location, single_guard = rules.decide(SIGNIFICANT, [pair, a, b], BEFORE, _data(), NULL)
    assert single_guard == {"effect": "a", "contradicted": contradicted}
    assert len(guard.calls) == 1 and guard.calls[0][0] is a
    assert guard.calls[0][1] is BEFORE and guard.calls[0][2] is NULL
    if contradicted:
        assert (verdict, chosen, location) == ("unexplained", None, LOCATION)
    else:
        assert (verdict, chosen, location) == ("explained", a, None)


@pytest.mark.parametrize(("score", "judged"), [(99.0, True), (100.0, False)])
def test_the_guard_is_not_judged_on_a_best_single_that_is_not_nameable(monkeypatch, score, judged):
    """Nameable against "no effect", Σ J before = 100: a single scoring 100 is not, and has no guard."""
    guard = _Guard(True)
    monkeypatch.setattr(rules, "single_contradicted", guard)
    single = _model(("a",), score)
    *_, single_guard = rules.decide(SIGNIFICANT, [single], BEFORE, _data(), NULL)
    assert (single_guard is not None, len(guard.calls)) == (judged, int(judged))
    if not judged:
        assert single_guard is None


def test_without_any_single_there_is_no_guard(monkeypatch):
    monkeypatch.setattr(rules, "pair_beats", _PairRule())
    verdict, chosen, location, single_guard = rules.decide(
        SIGNIFICANT, [_model(("a", "b"), 5.0)], BEFORE, _data(), NULL
    )
    assert (verdict, chosen, location, single_guard) == ("unexplained", None, LOCATION, None)


def test_the_guard_on_real_terms_refuses_a_drift_predicting_a_force_before_contact():
    """No stand-in: ft_drift acts on the force before contact; its held-out terms there are 4 per term in every
    episode against the data's 1 (the gap without a model), so it surely worsens them and is not named."""
    approach = STAGES.index("approach")
    before = [_terms({(STABLE, FZ): (50.0, 10.0), (approach, FZ): (1.0, 1.0)}) for _ in range(4)]
    null = [_terms({(STABLE, FZ): (10.0, 10.0), (approach, FZ): (1.0, 1.0)}) for _ in range(4)]
    drift_terms = [_terms({(STABLE, FZ): (10.0, 10.0), (approach, FZ): (4.0, 1.0)}) for _ in range(4)]
    fit = FitResult(("ft_drift",), [{}], 1, ho_terms=drift_terms)
    drift = ModelScore(fit, before=5.0, after=14 / 11, shrink=0.9, ci_low=0.8, ci_high=1.0, score=60.0)
    verdict, chosen, _, single_guard = rules.decide(SIGNIFICANT, [drift], before, _data(), null)
    assert single_guard == {"effect": "ft_drift", "contradicted": True}
    assert (verdict, chosen) == ("unexplained", None)


SINGLE_TEXT = "explained by a: held-out gap shrinks by 80 % (60 % to 90 %)"


def _named(shrink: float = 0.8, ci_low: float = 0.6, ci_high: float = 0.9, before: float = 5.0, after: float = 1.0):
    s = _model(("a",), 10.0, shrink=shrink, ci_low=ci_low)
    s.ci_high, s.before, s.after = ci_high, before, after
    return s


def test_the_summary_of_no_gap_and_of_an_unexplained_gap():
    assert rules.summary("no_gap", None, None, [], []) == (
        "no significant gap: the simulator explains these episodes within its own noise and specimen scatter"
    )
    assert rules.summary("unexplained", None, LOCATION, [], []) == "unexplained — located at fz_n, stable"


def test_the_summary_names_every_effect_of_the_model_with_its_shrink_and_interval():
    pair = _model(("a", "b"), 5.0, shrink=0.5, ci_low=0.25)
    pair.ci_high = 0.754
    text = rules.summary("explained", pair, None, [], [])
    assert text == "explained by a + b: held-out gap shrinks by 50 % (25 % to 75 %)"
    assert rules.summary("explained", _named(), None, [], [], None) == SINGLE_TEXT


@pytest.mark.parametrize(
    ("share", "text"),
    [
        (0.9949, "99 %"),  # whole per cent below 99.5 %
        (0.995, "99.5 %"),  # a tenth from 99.5 % on
        (0.9999, "100.0 %"),  # still a tenth: "100 %" is kept for a shrink of exactly 1
        (1.0, "100 %"),
        (1.2, "120 %"),
        (float("nan"), "nan"),
        (float("inf"), "nan"),
    ],
)
def test_the_summary_gives_shares_in_whole_per_cent_but_a_tenth_from_99_5_up_to_100(share, text):
    named = _named(shrink=share)
    assert rules.summary("explained", named, None, [], []) == (
        f"explained by a: held-out gap shrinks by {text} (60 % to 90 %)"
    )


def _leftover(ratio: float, cells: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    return {
        "ratio": ratio,
        "cells": [LOCATION, {"channel": "tx_nm", "stage": "entry1", "share": 0.1}] if cells is None else cells,
    }


def test_the_summary_reports_the_rest_above_three_times_the_simulators_level_and_what_it_was_before():
    """Ratio 12 after a gap of 1 that was 5: before it was 12 · 5 / 1 = 60 times the simulator's level."""
    text = rules.summary("explained", _named(), None, [], [], _leftover(12.0))
    assert text == (
        SINGLE_TEXT + "; what is left is still 12x the simulator's own level (it was 60x before), most of it at "
        "fz_n, stable (75 %)"
    )


@pytest.mark.parametrize("ratio", [3.0, 2.0])
def test_the_summary_leaves_out_a_rest_of_three_times_the_simulators_level_or_less(ratio):
    assert rules.summary("explained", _named(), None, [], [], _leftover(ratio)) == SINGLE_TEXT


def test_the_summary_leaves_out_a_rest_it_cannot_place():
    assert rules.summary("explained", _named(), None, [], [], _leftover(12.0, cells=[])) == SINGLE_TEXT


@pytest.mark.parametrize(("before", "after"), [(5.0, 0.0), (float("inf"), 1.0), (float("nan"), 1.0)])
def test_the_summary_says_no_gap_before_where_it_cannot_be_computed(before, after):
    text = rules.summary("explained", _named(before=before, after=after), None, [], [], _leftover(3.5))
    assert (
        text
        == SINGLE_TEXT + "; what is left is still 3.5x the simulator's own level, most of it at fz_n, stable (75 %)"
    )


def test_the_rest_and_the_gap_before_are_given_to_three_significant_figures():
    text = rules.summary("explained", _named(before=1.0, after=3.0), None, [], [], _leftover(1234.5))
    assert "still 1.23e+03x the simulator's own level (it was 412x before)" in text


def test_the_summary_lists_at_most_three_alternatives_and_three_possible_second_effects():
    alts = [{"name": n, "p_better": p} for n, p in (("b", 0.4), ("c", 0.2), ("d", 0.999), ("e", 0.5))]
    seconds = [{"second": n} for n in ("x", "y", "z", "w")]
    text = rules.summary("explained", _named(), None, alts, seconds)
    assert text == (
        SINGLE_TEXT + "; not ruled out: b (better in 40 %), c (better in 20 %), d (better in 99.9 %)"
        "; a second effect may be present (x, y, z: better on top, not shown to act alone)"
    )
    one = rules.summary("explained", _named(), None, alts[:1], seconds[:1])
    assert one == (
        SINGLE_TEXT + "; not ruled out: b (better in 40 %)"
        "; a second effect may be present (x: better on top, not shown to act alone)"
    )


def test_a_decision_holds_the_verdict_and_what_it_rests_on():
    d = rules.Decision("explained", None, None, None, ["latency"], [])
    assert (d.verdict, d.chosen, d.location, d.guard, d.off_point, d.scores) == (
        "explained",
        None,
        None,
        None,
        ["latency"],
        [],
    )
