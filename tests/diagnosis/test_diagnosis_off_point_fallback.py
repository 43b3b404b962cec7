"""The off-point rule's fallback: a pair whose second effect is not told apart from its absence.

The physics no longer produces such a pair on the benchmark's cases, so the decision is driven here with
fitted models whose scores and intervals are given: what is checked is what the diagnosis does with them.
"""

from __future__ import annotations

import importlib
from typing import Any

import pytest
from tqdm import tqdm

from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.rank import ModelScore

dg = importlib.import_module("drillgym.eval.diagnosis.diagnose")  # the module (the package exports the function)
SINGLE = ("ft_drift",)
PAIR = ("ft_drift", "latency")
LOCATION = {"channel": "fz_n", "stage": "stable", "share": 0.9}


def _interval(contains_off: bool) -> dict[str, Any]:
    return {"low": 0.0, "high": 1.0, "contains_off": contains_off}


def _drive(monkeypatch: pytest.MonkeyPatch, single_off: bool) -> tuple[Any, list[str]]:
    """Run the decision with the pair named first; latency's interval holds its off point, ft_drift's as given."""
    intervals = {
        SINGLE: {"ft_drift": {"fz_rate": _interval(single_off)}},
        PAIR: {"ft_drift": {"fz_rate": _interval(False)}, "latency": {"delay_s": _interval(True)}},
    }
    polished: list[tuple[str, ...]] = []

    def polish(runner: Any, data: Any, fit: FitResult, fits: list[FitResult], bar: tqdm) -> FitResult:
        polished.append(fit.names)
        return fit

    def score_models(fits: list[FitResult], before: Any, null: Any, seed: int) -> list[ModelScore]:
        return [ModelScore(f, 1.0, 0.2, 0.8, 0.7, 0.9, 0.8, intervals=intervals[f.names]) for f in fits]

    def decide(significance: Any, scores: list[ModelScore], before: Any, data: Any, null: Any) -> tuple:
        chosen = next(s for s in scores if s.fit.names in (PAIR, SINGLE))  # the pair while it is offered
        chosen.named = True
        return "explained", chosen, None, None

    monkeypatch.setattr(dg, "_polish", polish)
    monkeypatch.setattr(dg, "score_models", score_models)
    monkeypatch.setattr(dg, "decide", decide)
    monkeypatch.setattr(dg, "_bound", lambda scores, seed: None)
    monkeypatch.setattr(dg, "gap_location", lambda data: LOCATION)
    fits = [FitResult(PAIR, [{}, {}], 2), FitResult(SINGLE, [{}], 1)]
    scores = score_models(fits, None, None, 0)
    with tqdm(total=0, disable=True) as bar:
        decision = dg._name(None, None, {}, fits, scores, [], [], 0, bar)  # type: ignore[arg-type]
    return decision, [".".join(n) for n in polished]


def test_a_pair_whose_second_effect_holds_its_off_point_falls_back_to_its_first_effect_alone(monkeypatch):
    decision, polished = _drive(monkeypatch, single_off=False)
    assert decision.verdict == "explained"
    assert decision.chosen is not None and decision.chosen.fit.names == SINGLE and decision.chosen.named
    assert decision.off_point == ["latency"]  # why the pair was refused
    pair = next(s for s in decision.scores if s.fit.names == PAIR)
    assert not pair.named
    assert polished == ["ft_drift.latency", "ft_drift"]  # the pair refined first, then the single it falls back to


def test_the_fallback_single_is_not_named_either_when_it_too_holds_its_off_point(monkeypatch):
    decision, _ = _drive(monkeypatch, single_off=True)
    assert decision.verdict == "unexplained" and decision.chosen is None
    assert decision.location == LOCATION
    assert not any(s.named for s in decision.scores)
