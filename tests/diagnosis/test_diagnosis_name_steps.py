"""The naming steps of diagnose.py (``_name``): decide, refine the named model, decide again, bound, the off-point rule.

Each step is replaced by a recorder (the steps themselves are tested in test_diagnosis_verdict.py,
test_diagnosis_search_helpers.py and test_diagnosis_interval_edges.py), so what is checked is the order of the steps,
what each is given (the diagnosis's own runner, data, held-out terms, seed and bar, passed through untouched), the
progress bar's count, and what comes back. Which decision each step returns is scripted.
"""

from __future__ import annotations

import importlib
from types import SimpleNamespace
from typing import Any

import pytest

from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.rank import RESCUE_CI_LOW_MIN, ModelScore

dg = importlib.import_module("drillgym.eval.diagnosis.diagnose")  # the module (the package exports the function)

RUNNER, DATA, BEFORE, NULL = (SimpleNamespace(stands_for=n) for n in ("runner", "data", "before", "null"))
SIGNIFICANCE = {"significant": True}
SEED = 11
GUARD = {"effect": "ft_drift", "contradicted": False}
LOCATION = {"channel": "fz_n", "stage": "stable", "share": 0.9}
SINGLE, PAIR = ("ft_drift",), ("ft_drift", "latency")


class _Bar:
    """A progress bar that already counts 3 steps (the fits before the naming)."""

    def __init__(self) -> None:
        self.total, self.postfix = 3, []

    def set_postfix_str(self, text: str) -> None:
        self.postfix.append(text)

    def update(self, n: int = 1) -> None:
        pass


def _interval(contains_off: bool) -> dict[str, Any]:
    return {"low": 0.0, "high": 1.0, "contains_off": contains_off}


class _Steps:
    """Recorders for the steps; ``decisions`` are the names of the models ``decide`` names, in turn (None: none)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, decisions: list[tuple[str, ...] | None], intervals) -> None:
        self.decisions, self.intervals, self.calls = list(decisions), intervals, []
        self.scores: dict[tuple[str, ...], ModelScore] = {}
        for name in ("decide", "_polish", "score_models", "_bound", "gap_location"):
            monkeypatch.setattr(dg, name, getattr(self, name.lstrip("_")))

    def score_of(self, fit: FitResult) -> ModelScore:
        """One ModelScore per model, kept across rescoring (so a flag set on it stays visible)."""
        if fit.names not in self.scores:
            self.scores[fit.names] = ModelScore(fit, 1.0, 0.2, 0.8, 0.7, 0.9, 0.8, intervals=self.intervals[fit.names])
        return self.scores[fit.names]

    def decide(self, significance, scores, before, data, null):
        self.calls.append(("decide", significance, [s.fit.names for s in scores], before, data, null))
        names = self.decisions.pop(0)
        if names is None:
            return "unexplained", None, LOCATION, None
        chosen = next(s for s in scores if s.fit.names == names)
        chosen.named = True
        return "explained", chosen, None, GUARD

    def polish(self, runner, data, fit, fits, bar):
        self.calls.append(("polish", runner, data, fit.names, [f.names for f in fits], bar))
        bar.update()
        return fit

    def score_models(self, fits, before, null, seed):
        self.calls.append(("score_models", [f.names for f in fits], before, null, seed))
        return [self.score_of(f) for f in fits]

    def bound(self, scores, seed):
        self.calls.append(("bound", [s.fit.names for s in scores], seed))

    def location(self, data):
        self.calls.append(("gap_location", data))
        return LOCATION

    gap_location = location


def _name(steps: _Steps, fits: list[FitResult], bar: _Bar):
    scores = [steps.score_of(f) for f in fits]
    return dg._name(RUNNER, DATA, SIGNIFICANCE, fits, scores, BEFORE, NULL, SEED, bar)  # type: ignore[arg-type]


def _single_refined_calls(bar: _Bar) -> list[tuple[Any, ...]]:
    """The steps of deciding, refining the one single fit, rescoring, deciding again and bounding."""
    decided = ("decide", SIGNIFICANCE, [SINGLE], BEFORE, DATA, NULL)
    return [
        decided,
        ("polish", RUNNER, DATA, SINGLE, [SINGLE], bar),
        ("score_models", [SINGLE], BEFORE, NULL, SEED),
        decided,
        ("bound", [SINGLE], SEED),
    ]


def test_a_named_model_is_refined_rescored_decided_on_again_and_bounded(monkeypatch):
    steps = _Steps(monkeypatch, [SINGLE, SINGLE], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}}})
    fits, bar = [FitResult(SINGLE, [{}], 1)], _Bar()
    decision = _name(steps, fits, bar)
    named = steps.scores[SINGLE]
    assert decision == ("explained", named, None, GUARD, [], [named], None) and named.named
    assert steps.calls == _single_refined_calls(bar)
    assert bar.total == 3 + 1 and bar.postfix == ["refining the named model"]


def test_a_random_effect_is_not_refined(monkeypatch):
    steps = _Steps(monkeypatch, [SINGLE], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}}})
    fit = FitResult(SINGLE, [{}], 1, per_episode={"spread": {}})
    bar = _Bar()
    decision = _name(steps, [fit], bar)
    assert decision.verdict == "explained" and [c[0] for c in steps.calls] == ["decide", "bound"]
    assert bar.total == 3


def test_nothing_named_refines_the_best_single_decides_again_and_skips_the_off_point_rule(monkeypatch):
    steps = _Steps(monkeypatch, [None, None], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(True)}}})
    bar = _Bar()
    decision = _name(steps, [FitResult(SINGLE, [{}], 1)], bar)
    rescue = {"effect": "ft_drift", "decided": None, "named": False, "reason": None}
    assert decision == ("unexplained", None, LOCATION, None, [], [steps.scores[SINGLE]], rescue)
    assert steps.calls == _single_refined_calls(bar)
    assert bar.total == 3 + 1 and bar.postfix == ["refining the best single"]


def test_a_single_refined_after_nothing_was_named_is_named_when_its_interval_clears_the_rescue_bar(monkeypatch):
    steps = _Steps(monkeypatch, [None, SINGLE], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}}})
    fit = FitResult(SINGLE, [{}], 1)
    steps.score_of(fit).ci_low = RESCUE_CI_LOW_MIN  # the bar itself passes
    decision = _name(steps, [fit], _Bar())
    assert decision.verdict == "explained" and decision.chosen is steps.scores[SINGLE] and decision.chosen.named
    assert decision.rescue == {"effect": "ft_drift", "decided": "ft_drift", "named": True, "reason": None}


def test_a_single_refined_after_nothing_was_named_is_refused_below_the_rescue_bar_and_the_gap_located(monkeypatch):
    steps = _Steps(monkeypatch, [None, SINGLE], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}}})
    fit = FitResult(SINGLE, [{}], 1)
    steps.score_of(fit).ci_low = 0.3  # above the usual 20 %, under the rescue's 50 %
    decision = _name(steps, [fit], _Bar())
    assert (decision.verdict, decision.chosen, decision.location) == ("unexplained", None, LOCATION)
    assert not steps.scores[SINGLE].named and ("gap_location", DATA) in steps.calls
    assert decision.rescue is not None and decision.rescue["decided"] == "ft_drift" and not decision.rescue["named"]
    assert "starts at 30 %, under the 50 %" in decision.rescue["reason"]


def test_a_random_best_single_is_not_refined_when_nothing_is_named(monkeypatch):
    steps = _Steps(monkeypatch, [None], {SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}}})
    decision = _name(steps, [FitResult(SINGLE, [{}], 1, per_episode={"spread": {}})], _Bar())
    assert decision.verdict == "unexplained" and decision.rescue is None
    assert [c[0] for c in steps.calls] == ["decide", "bound"]


PAIR_INTERVALS = {
    SINGLE: {"ft_drift": {"fz_rate_n_s": _interval(False)}},
    PAIR: {"ft_drift": {"fz_rate_n_s": _interval(False)}, "latency": {"extra_latency_s": _interval(True)}},
}


def test_a_refused_pair_falls_back_to_its_first_effect_with_every_step_given_the_diagnosis_own_inputs(monkeypatch):
    steps = _Steps(monkeypatch, [PAIR, PAIR, SINGLE], PAIR_INTERVALS)
    fits, bar = [FitResult(PAIR, [{}, {}], 2), FitResult(SINGLE, [{}], 1)], _Bar()
    decision = _name(steps, fits, bar)
    single, pair = steps.scores[SINGLE], steps.scores[PAIR]
    assert decision == ("explained", single, None, GUARD, ["latency"], [pair, single], None)
    assert single.named and not pair.named  # the refused pair is marked as not named
    assert steps.calls[1] == ("polish", RUNNER, DATA, PAIR, [PAIR, SINGLE], bar)
    assert steps.calls[5:] == [
        ("polish", RUNNER, DATA, SINGLE, [PAIR, SINGLE], bar),
        ("score_models", [PAIR, SINGLE], BEFORE, NULL, SEED),
        ("decide", SIGNIFICANCE, [SINGLE], BEFORE, DATA, NULL),  # without the refused pair
        ("bound", [PAIR, SINGLE], SEED),
    ]
    assert bar.total == 3 + 2


def test_a_refused_pair_without_a_fit_of_its_other_effect_alone_leaves_the_gap_unexplained_and_located(monkeypatch):
    steps = _Steps(monkeypatch, [PAIR, PAIR], PAIR_INTERVALS)
    decision = _name(steps, [FitResult(PAIR, [{}, {}], 2)], _Bar())
    assert (decision.verdict, decision.chosen, decision.location, decision.off_point) == (
        "unexplained",
        None,
        LOCATION,
        ["latency"],
    )
    assert steps.calls[-1] == ("gap_location", DATA) and not steps.scores[PAIR].named
