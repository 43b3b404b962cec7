"""The one process pool: run jobs on several cores, each worker a fresh ``spawn`` process.

``spawn`` (not ``fork``) because a worker builds its own PyBullet client, Pinocchio model and, for policies,
torch: none of them survives a fork safely. With one worker (or one job) everything runs in this process,
so a single-core run has no pool overhead and a traceback points at the job itself.
"""

from __future__ import annotations

import functools
import multiprocessing as mp
import os
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from drillgym.envs.errors import UserError
from drillgym.eval.shared_round import SharedRound, guarded, started

Job = TypeVar("Job")
Result = TypeVar("Result")


def run_unordered(
    fn: Callable[[Job], Result],
    jobs: Sequence[Job],
    workers: int,
    *,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
    on_error: Callable[[Job, Exception], Result] | None = None,
) -> Iterator[tuple[int, Result]]:
    """Yield ``(index in jobs, fn(job))`` as each job finishes.

    Args:
        fn: a module-level function (workers import it by name).
        jobs: its arguments, one per call.
        workers: processes at most (1: in this process, in order).
        initializer: run once per worker (and once here with one worker), e.g. to hand every worker
            shared data once instead of with each job.
        initargs: the initializer's arguments.
        on_error: turns a job whose worker failed (it raised, or its process died) into a result; without
            it the error is raised here.

    A ``KeyboardInterrupt`` (Ctrl-C reaches this process, not the workers) stops the running jobs, cancels the rest
    and is raised again. A worker whose parent is gone (killed, say, by a scheduler's ``SIGTERM``, which skips the
    pool's shutdown) exits within a second instead of finishing its job for nobody. For several rounds of jobs,
    :class:`WorkerPool` starts the workers once.
    """
    with WorkerPool(min(workers, max(len(jobs), 1)), initializer=initializer, initargs=initargs) as pool:
        yield from pool.map_unordered(fn, jobs, on_error=on_error)


class WorkerPool:
    """Worker processes kept over several rounds of jobs (:meth:`map_unordered`), started at the first round.

    A spawned worker imports the simulator (numba, PyBullet, SciPy) before its first job, seconds of start-up:
    a job runner with several phases (the diagnosis: replays, then single fits, pair fits and refits) pays it
    once instead of once per phase. With one worker, or while no worker has started and a round has one job,
    the jobs run in this process (the initializer runs here once, before the first of them).

    Use it as a context manager (or call :meth:`close`): leaving stops the workers.
    """

    def __init__(
        self,
        workers: int,
        *,
        initializer: Callable[..., None] | None = None,
        initargs: tuple[Any, ...] = (),
        here: bool = False,
    ) -> None:
        """``workers`` processes at most; ``initializer(*initargs)`` runs once in each before its first job.

        ``here``: this process is one of the ``workers``. It runs jobs beside ``workers - 1`` spawned ones, each
        process taking the next job as it comes free (:class:`~drillgym.eval.shared_round.SharedRound`). A process that has already imported and
        warmed what the jobs need then starts nothing for its own share, and its first jobs run while the others
        start. The jobs' results must not depend on the process that runs them.
        """
        if workers < 1:
            raise UserError(f"workers={workers} must be >= 1")
        self.workers = workers
        self._here = here
        self._initializer, self._initargs = initializer, initargs
        self._executor: ProcessPoolExecutor | None = None
        self._initialized_here = False

    def map_unordered(
        self,
        fn: Callable[[Job], Result],
        jobs: Sequence[Job],
        *,
        on_error: Callable[[Job, Exception], Result] | None = None,
    ) -> Iterator[tuple[int, Result]]:
        """Yield ``(index in jobs, fn(job))`` as each job finishes (see :func:`run_unordered` for the arguments)."""
        if self.workers == 1 or (self._executor is None and len(jobs) <= 1):
            self._init_here()
            for i, job in enumerate(jobs):
                yield i, guarded(functools.partial(fn, job), job, on_error)
            return
        if self._here:
            self._init_here()
            rounds = SharedRound(self._start(), self.workers - 1, fn, jobs, on_error).results()
        else:
            rounds = _submitted_round(self._start(), fn, jobs, on_error)
        try:
            broken = yield from rounds
        except BaseException:
            self.close(cancel=True)
            raise
        if broken:  # a worker died: the next round starts fresh workers
            self.close()

    def _init_here(self) -> None:
        """The initializer, once, before this process's first job."""
        if not self._initialized_here:
            self._initialized_here = True
            if self._initializer is not None:
                self._initializer(*self._initargs)

    def _start(self) -> ProcessPoolExecutor:
        if self._executor is None:
            spawned = self.workers - 1 if self._here else self.workers
            self._executor = ProcessPoolExecutor(
                max_workers=spawned,
                mp_context=mp.get_context("spawn"),
                initializer=_worker_start,
                initargs=(os.getpid(), self._initializer, self._initargs),
            )
            _spawn_deaf_to_ctrl_c(self._executor, spawned)
        return self._executor

    def close(self, cancel: bool = False) -> None:
        """Stop the workers: after their running jobs, or (``cancel``) at once, dropping the jobs not started.

        Cancelling (an interrupt, an error here) asks each worker to stop its job (``SIGTERM``, which it turns into
        ``SystemExit``: its job unwinds, ``finally`` blocks run) instead of waiting for it.
        """
        if self._executor is not None:
            if cancel:  # (the executor's own processes: a private map, which Python 3.14's terminate_workers wraps)
                for process in list(getattr(self._executor, "_processes", {}).values()):
                    if process.is_alive():
                        process.terminate()
            self._executor.shutdown(wait=True, cancel_futures=cancel)
            self._executor = None

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close(cancel=exc[0] is not None)


PARENT_POLL_S = 1.0
"""How often a worker checks that the process that started it is still there (s)."""


def _submitted_round(
    pool: ProcessPoolExecutor,
    fn: Callable[[Job], Result],
    jobs: Sequence[Job],
    on_error: Callable[[Job, Exception], Result] | None,
) -> Generator[tuple[int, Result], None, bool]:
    """``(index in jobs, result)`` of every job submitted to ``pool`` at once, as each finishes.

    Returns whether the pool broke (a worker died).
    """
    futures: dict[Future, int] = {pool.submit(fn, job): i for i, job in enumerate(jobs)}
    broken = False
    for fut in as_completed(futures):
        i = futures[fut]
        broken = broken or isinstance(fut.exception(), BrokenProcessPool)
        yield i, guarded(fut.result, jobs[i], on_error)
    return broken


def _spawn_deaf_to_ctrl_c(pool: ProcessPoolExecutor, n: int) -> None:
    """Start the pool's ``n`` workers now, ignoring ``SIGINT``; without a main thread here, on demand as they are.

    Ctrl-C in a terminal signals every process of its group: each worker would print the traceback of wherever it
    was (its imports, its job) under this process's one line. This process handles the interrupt and stops them
    (:meth:`WorkerPool.close` with ``cancel``). A child inherits an ignored ``SIGINT`` and Python leaves it so, and
    only the main thread may change it: the pool starts a worker for each call submitted while none is idle.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        for _ in range(n):
            pool.submit(started)
    finally:
        signal.signal(signal.SIGINT, previous)


def _stop_job(signum: int, frame: object) -> None:
    """A worker's ``SIGTERM`` (:meth:`WorkerPool.close` cancelling): unwind the job as an exit would."""
    raise SystemExit(128 + signum)


def _worker_start(parent_pid: int, initializer: Callable[..., None] | None, initargs: tuple[Any, ...]) -> None:
    """In each worker: watch the parent (a daemon thread), run the caller's initializer, then stop on ``SIGTERM``.

    From then on ``SIGTERM`` unwinds the running job (:func:`_stop_job`); before, it ends the worker at once (no job
    to unwind, and an initializer's exception would be logged as a failure).
    """
    threading.Thread(target=_exit_when_orphaned, args=(parent_pid,), daemon=True).start()
    if initializer is not None:
        initializer(*initargs)
    signal.signal(signal.SIGTERM, _stop_job)


def _exit_when_orphaned(parent_pid: int) -> None:
    """Exit this worker at once when its parent has died (it is re-parented: the parent id changes)."""
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def run_ordered(fn: Callable[[Job], Result], jobs: Sequence[Job], workers: int, **kwargs: Any) -> list[Result]:
    """:func:`run_unordered`'s results in the order of ``jobs``."""
    out: dict[int, Result] = dict(run_unordered(fn, jobs, workers, **kwargs))
    return [out[i] for i in range(len(jobs))]
