"""Benchmark episodes: build (or reuse) the env, run a controller on it, optionally log it.

:func:`run_batch` is what a worker process runs: the seeds of one (scenario, controller, cell) on the batched
engine (:func:`drillgym.controllers.rollout.run_episodes`, one controller copy per episode; the same rows as on
the single env, bit for bit), or episode by episode (:func:`run_job`) where the cell has effects the compiled step
does not run, or where the batch fails (so that each episode's error is its own). Neither raises (an error becomes
the row's ``error``), so one bad episode does not stop a benchmark. Single envs and controllers are cached per
process (an env costs ~0.15 s to build, an episode ~0.1 s), which is safe because ``reset(seed)`` replays an episode
bit for bit whatever ran before, and ``set_plan`` resets a controller.
"""

from __future__ import annotations

import json
import math
import time
import traceback
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.controllers.base import Controller
from drillgym.controllers.rollout import EpisodeResult, run_episode, run_episodes
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.effects import build_effects
from drillgym.envs.effects.registry import runs_compiled
from drillgym.envs.metrics import METRIC_NAMES
from drillgym.envs.scenario import Scenario
from drillgym.envs.seeds import Purpose, episode_seed
from drillgym.eval.bench.suites import suite_scenarios
from drillgym.eval.logs import EpisodeLogger, build_header
from drillgym.eval.logs.batch_logger import BatchLogger

ENV_ID = SIM_ENV_ID
ENV_CACHE_SIZE = 2
"""Envs kept per process (jobs arrive scenario by scenario, so two cover a switch)."""


@dataclass(frozen=True)
class EpisodeJob:
    """One episode of the benchmark grid."""

    suite: str
    scenario: str
    kwargs: dict[str, Any] = field(hash=False)
    controller: str
    seed: int
    log_path: Path | None = None
    """``<out>/logs/<...>.parquet``, or None for no log."""
    log_name: str = ""
    """``log_path`` as written in ``episodes.csv`` (relative to the output folder)."""
    effects: str = ""
    """Effect spec of the cell (:data:`drillgym.envs.effects.cells.CELLS`); empty: the ideal cell."""
    reality: str = ""
    """Spec of reality-library effects (:func:`drillgym.eval.diagnosis.reality.generate.build_reality`) on top of
    the cell's, seeded by the episode's seed (the same draws for every controller); empty: none."""

    @property
    def key(self) -> tuple[str, str, str, int]:
        """Sort key: (suite, scenario, controller, seed)."""
        return (self.suite, self.scenario, self.controller, self.seed)


def grid_jobs(
    suites: list[str], specs: list[str], seeds: int, purpose: Purpose = Purpose.JUDGE, cell: str = ""
) -> list[EpisodeJob]:
    """Every (suite scenario, controller spec, seed) episode, without logs.

    The seeds are episodes 0..seeds-1 of ``purpose``'s namespace (:mod:`drillgym.envs.seeds`): the judge's are
    plain 0..seeds-1, a tuner's never meet them. ``cell``: an effect spec on every episode, before the scenario's own.
    """
    jobs = []
    for suite in suites:
        for sc in suite_scenarios(suite):
            for spec in specs:
                for i in range(seeds):
                    seed = episode_seed(purpose, i)
                    jobs.append(
                        EpisodeJob(suite, sc.name, sc.kwargs, spec, seed, effects=sc.episode_effects(seed, cell))
                    )
    return jobs


_envs: OrderedDict[str, gym.Env] = OrderedDict()
_controllers: dict[str, Controller] = {}


def _env(kwargs: dict[str, Any]) -> gym.Env:
    key = json.dumps(kwargs, sort_keys=True)
    if key in _envs:
        _envs.move_to_end(key)
        return _envs[key]
    env = gym.make(ENV_ID, **kwargs)
    _envs[key] = env
    while len(_envs) > ENV_CACHE_SIZE:
        _envs.popitem(last=False)[1].close()
    return env


def _drop_env(kwargs: dict[str, Any]) -> None:
    env = _envs.pop(json.dumps(kwargs, sort_keys=True), None)
    if env is not None:
        env.close()


def close_cached() -> None:
    """Close this process's cached envs and forget its controllers (after an in-process run)."""
    while _envs:
        _envs.popitem()[1].close()
    _controllers.clear()


def _controller(spec: str) -> Controller:
    if spec not in _controllers:
        _controllers[spec] = make_controller(spec)
    return _controllers[spec]


def run_controller_episode(env: gym.Env, controller: Controller, seed: int) -> dict[str, Any]:
    """Reset with ``seed``, hand the controller the plan, run to the end.

    Returns:
        The episode metrics (:data:`drillgym.envs.metrics.METRIC_NAMES`) plus ``steps``, ``sim_time_s`` and
        ``failure`` (``""``, ``"force_limit"`` or ``"truncated"``).
    """
    return run_episode(env, controller, seed, keep_trace=False).row()


def _blank_row(job: EpisodeJob) -> dict[str, Any]:
    """The row of ``episodes.csv`` before the episode ran: its identity, metrics NaN, no error."""
    row: dict[str, Any] = {"suite": job.suite, "scenario": job.scenario}
    try:
        row.update(Scenario.from_kwargs(**job.kwargs).to_dict())
    except (TypeError, ValueError):
        row.update(job.kwargs)
    row.update({"controller": job.controller, "seed": job.seed})
    row.update(dict.fromkeys(METRIC_NAMES, math.nan))
    row.update({"steps": 0, "sim_time_s": math.nan, "failure": "", "error": "", "log": job.log_name})
    return row


def run_job(job: EpisodeJob) -> dict[str, Any]:
    """Run one job on a single env; the row of ``episodes.csv`` (metrics NaN and ``error`` set if it raised)."""
    row = _blank_row(job)
    t0 = time.perf_counter()
    try:
        row.update(_run(job))
    except Exception as e:  # one bad episode must not stop the benchmark
        row["error"] = f"{type(e).__name__}: {e}"
        row["traceback"] = traceback.format_exc()
        _drop_env(job.kwargs)
    row["wall_time_s"] = time.perf_counter() - t0
    return row


def _run(job: EpisodeJob) -> dict[str, Any]:

    env = _env(job.kwargs)
    effects: list[Any] = build_effects(job.effects) if job.effects else []
    if job.reality:  # drawn for the episode from its seed: the same reality for every controller on a seed
        from drillgym.eval.diagnosis.reality.generate import episode_reality

        effects += episode_reality(job.reality, np.random.default_rng([job.seed, REALITY_STREAM]))
    env.unwrapped.set_effects(effects or None)  # type: ignore[attr-defined]
    controller = _controller(job.controller)
    if job.log_path is None:
        return run_controller_episode(env, controller, job.seed)
    extra = {"suite": job.suite, "scenario": job.scenario, "controller_spec": job.controller, "effects": job.effects}
    if job.reality:
        extra["reality"] = job.reality
    header = build_header(env, controller.describe(), job.seed, extra=extra)
    logger = EpisodeLogger(env, job.log_path, header, overwrite=True)
    try:
        result = run_controller_episode(logger, controller, job.seed)
    except BaseException:
        logger.abandon_log()  # keep what was recorded, as a crash would
        raise
    logger.close_log()  # not logger.close(): the cached env stays open
    return result


BATCH_MAX = 64
"""Episodes per batched call at most (the batched engine's throughput is flat beyond ~16)."""


def batch_key(job: EpisodeJob) -> tuple[str, str, str, str, str, str]:
    """What the episodes of one batch share: suite, scenario, its arguments, controller, cell and reality.

    A cell the batched engine runs is not shared: each slot takes its own (a cell drawn per episode, as the robustness
    suite's ``*_drawn`` scenarios draw it), so such episodes batch together whatever their draws.
    """
    cell = "" if batchable(job) else job.effects
    return (job.suite, job.scenario, json.dumps(job.kwargs, sort_keys=True), job.controller, cell, job.reality)


REALITY_STREAM = 7
"""Key of a reality's per-episode draws beside the episode's seed."""


def batchable(job: EpisodeJob) -> bool:
    """Whether the job's cell runs on the batched engine (no effects, or compiled ones only; no reality)."""
    if job.reality:
        return False
    try:
        return runs_compiled(job.effects)
    except ValueError:
        return False  # a bad spec: the single env reports it, episode by episode


def run_batch(jobs: list[EpisodeJob]) -> list[dict[str, Any]]:
    """Run jobs that share a :func:`batch_key` together on the batched engine; their rows, in order.

    Each row's ``wall_time_s`` is the batch's wall time over its episodes. Falls back to :func:`run_job`, episode by
    episode, for a cell the batched engine does not run or when the batch raised.
    """
    if len({batch_key(j) for j in jobs}) != 1:
        raise ValueError("run_batch takes the jobs of one (suite, scenario, kwargs, controller, cell)")
    first = jobs[0]
    if len(jobs) == 1 or not batchable(first):
        return [run_job(j) for j in jobs]
    t0 = time.perf_counter()
    try:
        results = _run_batched(jobs)
    except Exception:  # attribute the error to its episode: run them one by one
        return [run_job(j) for j in jobs]
    wall_s = (time.perf_counter() - t0) / len(jobs)
    return [{**_blank_row(j), **r.row(), "wall_time_s": wall_s} for j, r in zip(jobs, results, strict=True)]


def _run_batched(jobs: list[EpisodeJob]) -> list[EpisodeResult]:
    """The batch's episodes on the batched engine, logged where the jobs ask for logs."""
    first = jobs[0]
    seeds = [j.seed for j in jobs]

    def make() -> Controller:
        return make_controller(first.controller)

    effects = [j.effects for j in jobs]  # each episode's own cell (the same text for a fixed cell)
    if all(j.log_path is None for j in jobs):
        return run_episodes(make, seeds, first.kwargs, effects)
    logger: list[BatchLogger] = []  # made once the batch is reset

    def log(batch: Any) -> BatchLogger:
        extra = {"suite": first.suite, "scenario": first.scenario, "controller_spec": first.controller}
        paths = [j.log_path for j in jobs]
        extras = [{**extra, "effects": j.effects} for j in jobs]
        logger.append(BatchLogger(batch, paths, seeds, make().describe(), extras))
        return logger[0]

    try:
        results = run_episodes(make, seeds, first.kwargs, effects, log=log)
    except BaseException:
        for lg in logger:
            lg.abandon()  # keep what was recorded, as a crash would
        raise
    for lg in logger:
        lg.close()
    return results
