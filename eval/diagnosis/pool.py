"""Run diagnosis jobs on every core (:mod:`drillgym.eval.pool`), each worker with its own simulator.

The workers start once per diagnosis (:class:`~drillgym.eval.pool.WorkerPool`) and serve every phase; this process
is one of them (it runs jobs while the others start, and imports and loads nothing again). Each round
of jobs hands the shared :class:`~drillgym.eval.diagnosis.context.DiagnosisData` over once, as a pickle file the
jobs name: a worker loads it before its first job of a round that names a new one, and keeps one env
(:class:`~drillgym.eval.diagnosis.replay.Replayer`) throughout. With one worker everything runs in this process.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.context import DiagnosisData, Evaluator, baseline_job
from drillgym.eval.diagnosis.fit import FitResult, fit_model, refit_jointly
from drillgym.eval.diagnosis.random_effects import fit_per_episode
from drillgym.eval.diagnosis.replay import Replayer
from drillgym.eval.pool import WorkerPool

_WORKER: dict[str, Any] = {}


def _init(data: DiagnosisData) -> None:
    replayer = _WORKER.get("replayer") or Replayer()
    _WORKER.update(data=data, replayer=replayer, evaluator=Evaluator(data, replayer) if data.nulls else None)


def _warm(owner_pid: int) -> None:
    """Load the compiled replay before a spawned worker's first job (its start, not a job, pays the fraction of a second).

    Nothing in the process running the diagnosis (``owner_pid``): it runs its first job at once, which loads it.
    """
    if os.getpid() == owner_pid:
        return
    env = UR5BoneDrillEnv(pybullet_world=False, ft_noise_n=0.0, tracker_noise_mm=0.0)
    env.reset(seed=0)
    env.replay_open_loop(np.zeros((2, ACTION_DIM)))
    env.close()


def _with_data(data_file: str | None) -> None:
    """Load the round's data in this worker unless it already holds it (``None``: in process, set by the runner)."""
    if data_file is not None and _WORKER.get("data_file") != data_file:
        _init(pickle.loads(Path(data_file).read_bytes()))
        _WORKER["data_file"] = data_file


def _baseline(job: tuple[str | None, int]) -> tuple[int, Any]:
    data_file, i = job
    _with_data(data_file)
    return i, baseline_job(_WORKER["replayer"], _WORKER["data"].episodes[i])


def _fit(job: tuple[str | None, int, tuple[str, ...], list[dict[str, float]] | None]) -> tuple[int, FitResult]:
    data_file, k, names, start = job
    _with_data(data_file)
    if len(names) == 1 and start is None and EFFECTS[names[0]].per_episode:
        return k, fit_per_episode(_WORKER["evaluator"], names[0])
    return k, fit_model(_WORKER["evaluator"], names, start)


def _refit(job: tuple[str | None, int, tuple[str, ...], list[list[dict[str, float]]]]) -> tuple[int, FitResult]:
    data_file, k, names, starts = job
    _with_data(data_file)
    return k, refit_jointly(_WORKER["evaluator"], names, starts)


class Runner:
    """Maps jobs over one pool of workers (or in process), yielding ``(index, result)`` as they finish.

    Use it as a context manager (or call :meth:`close`): leaving stops the workers and removes the data files.
    """

    def __init__(self, workers: int) -> None:
        self.workers = max(1, int(workers))
        self._pool = WorkerPool(self.workers, initializer=_warm, initargs=(os.getpid(),), here=True)  # this one too
        self._dir: Path | None = None
        self._files: dict[str, str] = {}

    def _data_file(self, data: DiagnosisData) -> str:
        """The file holding ``data`` as it is now (written once per distinct content)."""
        blob = pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)
        key = hashlib.sha1(blob).hexdigest()
        if key not in self._files:
            if self._dir is None:
                self._dir = Path(tempfile.mkdtemp(prefix="drillgym-diagnosis-"))
            path = self._dir / f"data-{len(self._files)}.pickle"
            path.write_bytes(blob)
            self._files[key] = str(path)
        return self._files[key]

    def _map(
        self, data: DiagnosisData, fn: Callable[[Any], tuple[int, Any]], jobs: list[Any]
    ) -> Iterator[tuple[int, Any]]:
        if self.workers == 1:  # in this process: the data as it is now, no copy
            _init(data)
            _WORKER["data_file"] = None
            for job in jobs:
                yield fn((None, *job) if isinstance(job, tuple) else (None, job))
            return
        name = self._data_file(data)
        if _WORKER.get("data_file") != name:  # this process runs jobs too: the data as it is, no copy
            _init(data)
            _WORKER["data_file"] = name
        full = [(name, *job) if isinstance(job, tuple) else (name, job) for job in jobs]
        for _, result in self._pool.map_unordered(fn, full):
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

    def close(self) -> None:
        """Stop the workers and remove the data files."""
        self._pool.close()
        _WORKER.pop("data_file", None)
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def __enter__(self) -> Runner:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
