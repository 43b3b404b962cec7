"""Run diagnosis jobs on every core (:mod:`drillgym.eval.pool`), each worker with its own simulator.

Workers receive the shared :class:`~drillgym.eval.diagnosis.context.DiagnosisData` once (pool initializer) and
keep one env (:class:`~drillgym.eval.diagnosis.replay.Replayer`). With one worker everything runs in this process.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.context import DiagnosisData, Evaluator, baseline_job
from drillgym.eval.diagnosis.fit import FitResult, fit_model, refit_jointly
from drillgym.eval.diagnosis.random_effects import fit_per_episode
from drillgym.eval.diagnosis.replay import Replayer
from drillgym.eval.pool import run_unordered

_WORKER: dict[str, Any] = {}


def _init(data: DiagnosisData) -> None:
    replayer = _WORKER.get("replayer") or Replayer()
    _WORKER.update(data=data, replayer=replayer, evaluator=Evaluator(data, replayer) if data.nulls else None)


def _baseline(i: int) -> tuple[int, Any]:
    return i, baseline_job(_WORKER["replayer"], _WORKER["data"].episodes[i])


def _fit(job: tuple[int, tuple[str, ...], list[dict[str, float]] | None]) -> tuple[int, FitResult]:
    k, names, start = job
    if len(names) == 1 and start is None and EFFECTS[names[0]].per_episode:
        return k, fit_per_episode(_WORKER["evaluator"], names[0])
    return k, fit_model(_WORKER["evaluator"], names, start)


def _refit(job: tuple[int, tuple[str, ...], list[list[dict[str, float]]]]) -> tuple[int, FitResult]:
    k, names, starts = job
    return k, refit_jointly(_WORKER["evaluator"], names, starts)


class Runner:
    """Maps jobs over a pool (or in process), yielding ``(index, result)`` as they finish."""

    def __init__(self, workers: int) -> None:
        self.workers = max(1, int(workers))

    def _map(
        self, data: DiagnosisData, fn: Callable[[Any], tuple[int, Any]], jobs: list[Any]
    ) -> Iterator[tuple[int, Any]]:
        for _, result in run_unordered(fn, jobs, self.workers, initializer=_init, initargs=(data,)):
            yield result

    def baselines(self, data: DiagnosisData) -> Iterable[tuple[int, Any]]:
        """Nominal and null replays of every episode."""
        return self._map(data, _baseline, list(range(len(data.episodes))))

    def fits(
        self, data: DiagnosisData, models: list[tuple[tuple[str, ...], list[dict[str, float]] | None]]
    ) -> Iterable[tuple[int, FitResult]]:
        """Fit each ``(names, start)``."""
        return self._map(data, _fit, [(k, names, start) for k, (names, start) in enumerate(models)])

    def refits(
        self, data: DiagnosisData, models: list[tuple[tuple[str, ...], list[list[dict[str, float]]]]]
    ) -> Iterable[tuple[int, FitResult]]:
        """Refit each ``(names, starts)`` with every parameter free (:func:`~drillgym.eval.diagnosis.fit.refit_jointly`)."""
        return self._map(data, _refit, [(k, names, starts) for k, (names, starts) in enumerate(models)])
