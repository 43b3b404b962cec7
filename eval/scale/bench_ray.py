"""``drillgym bench --ray``: the episode grid as Ray tasks, streamed into the usual outputs.

One Ray task per episode (1 CPU each) runs :func:`drillgym.eval.bench.episode.run_job` in a Ray worker, which
keeps its envs and controllers cached between tasks like a pool worker does. A worker on the driver's
node writes the episode's log straight into the output folder, as a pool worker does; a worker on
another node writes it into node-local scratch space and returns the row together with the log's
bytes, which the driver writes, so a cluster needs no shared file system. A task whose worker
process dies (killed, out of memory, node lost) is run again by Ray, up to ``max_retries`` times; the
driver records only finished episodes, so nothing already recorded is lost or duplicated, and a
retried episode gives the same row (``reset(seed)`` replays an episode bit for bit).
"""

from __future__ import annotations

import hashlib
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import ray
from tqdm import tqdm

from drillgym.eval.bench.episode import EpisodeJob, run_job
from drillgym.eval.scale.cluster import RaySession, ray_session
from drillgym.eval.scale.sink import StreamingSink

MAX_RETRIES = 3
"""Times Ray re-runs an episode whose worker process died."""
Runner = Callable[[EpisodeJob], dict[str, Any]]


@dataclass
class RayBenchRun:
    """What a Ray benchmark run returns: the rows and where the time went."""

    rows: list[dict[str, Any]]
    session: RaySession
    warmup_s: float
    """Starting and importing one worker per cluster CPU (s)."""
    episodes_s: float
    """Submitting the grid until the last row was written (s)."""


def _scratch(job: EpisodeJob) -> Path:
    """Node-local folder for one episode's log (the same for every attempt, so a retry clears it)."""
    key = hashlib.sha1(str(job.log_path).encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / "drillgym-bench" / key


def run_episode_task(
    job: EpisodeJob, runner: Runner = run_job, driver_node: str | None = None
) -> tuple[dict[str, Any], dict[str, bytes]]:
    """Run one episode in a Ray worker.

    Args:
        job: the episode.
        runner: what runs it.
        driver_node: the driver's Ray node id. A worker on that node writes the log straight into the
            output folder, as a pool worker does; a worker on another node writes it into scratch space
            and returns its bytes.

    Returns:
        The ``episodes.csv`` row and the files of its log, ``{path relative to the output folder: bytes}``
        (a finished ``logs/NAME.parquet``, or the ``logs/NAME/`` parts of an episode that raised); no
        files when the log was written in place.
    """
    if job.log_path is None or (driver_node is not None and ray.get_runtime_context().get_node_id() == driver_node):
        return runner(job), {}
    scratch = _scratch(job)
    shutil.rmtree(scratch, ignore_errors=True)
    try:
        row = runner(replace(job, log_path=scratch / job.log_name))
        files = {p.relative_to(scratch).as_posix(): p.read_bytes() for p in sorted(scratch.rglob("*")) if p.is_file()}
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return row, files


def run_chunk_task(
    jobs: Sequence[EpisodeJob], runner: Runner = run_job, driver_node: str | None = None
) -> list[tuple[dict[str, Any], dict[str, bytes]]]:
    """Run a few episodes one after another in one Ray task (see :func:`run_episode_task`).

    Episodes of ~0.1 s cost Ray ~10 ms each to schedule and return; a chunk pays that once.
    """
    return [run_episode_task(job, runner, driver_node) for job in jobs]


def chunk_size_for(n_jobs: int, cpus: int, chunks_per_cpu: int = 4, max_size: int = 8) -> int:
    """Episodes per task: about ``chunks_per_cpu`` tasks per CPU (for balance), at most ``max_size``."""
    return max(1, min(max_size, n_jobs // max(1, cpus * chunks_per_cpu)))


def _import_worker() -> int:
    """Warm-up task: import the episode code (PyBullet, Pinocchio, controllers) in a worker."""
    return 0


def _failed_row(job: EpisodeJob, error: BaseException) -> dict[str, Any]:
    row = {"suite": job.suite, "scenario": job.scenario, "controller": job.controller, "seed": job.seed}
    return {**row, "error": f"worker failed: {type(error).__name__}: {error}", "log": job.log_name}


def _collect(ref: Any, chunk: list[EpisodeJob]) -> list[tuple[dict[str, Any], dict[str, bytes]]]:
    """A finished task's rows and log files; a task that failed past its retries gives error rows."""
    try:
        return ray.get(ref)
    except (ray.exceptions.RayError, OSError) as e:
        return [(_failed_row(job, e), {}) for job in chunk]


def _groups(jobs: Sequence[EpisodeJob], done: Sequence[dict[str, Any]] = ()) -> list[tuple[str, str, str]]:
    keys = [(r["suite"], r["scenario"], r["controller"]) for r in done]
    return list(dict.fromkeys([*keys, *((j.suite, j.scenario, j.controller) for j in jobs)]))


def run_jobs_ray(
    jobs: Sequence[EpisodeJob],
    out: Path,
    address: str | None = None,
    desc: str = "bench",
    runner: Runner = run_job,
    max_retries: int = MAX_RETRIES,
    num_cpus: int | None = None,
    chunk_size: int | None = None,
    done_rows: Sequence[dict[str, Any]] = (),
) -> RayBenchRun:
    """Run every job as a Ray task, writing rows and logs into ``out`` as they complete.

    Args:
        jobs: the episode grid.
        out: output folder; ``episodes.csv`` (completion order), ``logs/`` and ``summary.csv`` stream in.
        address: Ray address (see :func:`drillgym.eval.scale.cluster.ray_session`); None starts a local instance.
        desc: progress-bar label.
        runner: what a task runs on a job (tests swap in one that crashes its worker).
        max_retries: re-runs of a task whose worker died; after that the episode is an error row.
        num_cpus: CPUs of a local instance (default: the machine's).
        chunk_size: episodes per Ray task (default :func:`chunk_size_for`); a chunk's rows arrive together.
        done_rows: rows of episodes that finished before (``drillgym bench --resume``), not among ``jobs``: written
            into ``episodes.csv`` first, and returned with the new ones.

    Returns:
        Rows in completion order (``done_rows`` first), and the timings.
    """
    task = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=False)(run_chunk_task)
    with ray_session(address, num_cpus) as session:
        print(session.describe())
        t0 = time.perf_counter()
        warm = ray.remote(num_cpus=1)(_import_worker)
        ray.get([warm.remote() for _ in range(max(session.cpus, 1))])
        warmup_s = time.perf_counter() - t0
        print(f"ray: {session.cpus} workers started and warmed up in {warmup_s:.1f} s")
        sink = StreamingSink(out, _groups(jobs, done_rows))
        sink.extend([(row, {}) for row in done_rows])
        t0 = time.perf_counter()
        driver_node = ray.get_runtime_context().get_node_id()
        size = chunk_size or chunk_size_for(len(jobs), session.cpus)
        chunks = [list(jobs[i : i + size]) for i in range(0, len(jobs), size)]
        jobs_of = {task.remote(chunk, runner, driver_node): chunk for chunk in chunks}
        waiting = list(jobs_of)
        with tqdm(total=len(jobs), desc=desc, unit="ep", disable=None) as bar:
            while waiting:
                done, waiting = ray.wait(waiting, num_returns=1)  # block for one, then take all that are ready
                more, waiting = ray.wait(waiting, num_returns=len(waiting), timeout=0) if waiting else ([], [])
                for ref in done + more:
                    results = _collect(ref, jobs_of.pop(ref))
                    sink.extend(results)
                    bar.update(len(results))
        sink.write_summary()
        episodes_s = time.perf_counter() - t0
    print(f"ray: {len(jobs)} episodes in {episodes_s:.1f} s")
    return RayBenchRun(sink.rows, session, warmup_s, episodes_s)
