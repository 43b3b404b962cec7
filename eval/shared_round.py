"""One round of jobs shared by this process and a pool's workers, each taking the next job as it comes free.

:class:`~drillgym.eval.pool.WorkerPool` uses it when this process counts as one of its workers (``here=True``).
"""

from __future__ import annotations

import functools
import queue
import threading
from collections.abc import Callable, Generator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from concurrent.futures.process import BrokenProcessPool
from typing import Generic, TypeVar

Job = TypeVar("Job")
Result = TypeVar("Result")


class SharedRound(Generic[Job, Result]):
    """Every job of ``jobs`` run once, by this thread or by one of the ``spawned`` workers of ``pool``.

    One thread per worker hands it the next job whenever its last is done, from the moment a worker has started
    (its initializer run); this thread runs the next job itself and passes on the workers' results between its
    own jobs (:meth:`results`). A worker that dies fails the job it held, as
    :meth:`~drillgym.eval.pool.WorkerPool.map_unordered` does; the jobs left run here and in the other workers.
    """

    def __init__(
        self,
        pool: ProcessPoolExecutor,
        spawned: int,
        fn: Callable[[Job], Result],
        jobs: Sequence[Job],
        on_error: Callable[[Job, Exception], Result] | None,
    ) -> None:
        self.pool, self.spawned, self.fn, self.jobs, self.on_error = pool, spawned, fn, jobs, on_error
        self._lock = threading.Lock()
        self._order = iter(range(len(jobs)))
        self._back: list[int] = []  # jobs a broken pool refused: they run elsewhere
        self._stop = threading.Event()
        self._broke = threading.Event()
        self._done: queue.SimpleQueue[tuple[int, Future[Result]] | None] = queue.SimpleQueue()

    def results(self) -> Generator[tuple[int, Result], None, bool]:
        """``(index in jobs, result)`` of every job as it finishes; returns whether the pool broke."""
        feeders = [threading.Thread(target=self._feed, daemon=True) for _ in range(self.spawned)]
        for t in feeders:
            t.start()
        running = len(feeders)
        try:
            while True:
                i = self._take()
                if i is not None:  # run the next job here, then pass on what the workers finished meanwhile
                    yield i, guarded(functools.partial(self.fn, self.jobs[i]), self.jobs[i], self.on_error)
                elif not running:
                    break
                wait = i is None  # nothing left to take: wait for a worker's result
                while running and (wait or not self._done.empty()):
                    wait = False
                    item = self._done.get()
                    if item is None:
                        running -= 1
                    else:
                        yield self._finished(*item)
        finally:
            self._stop.set()
        return self._broke.is_set()

    def _take(self) -> int | None:
        with self._lock:
            if self._stop.is_set():
                return None
            return self._back.pop() if self._back else next(self._order, None)

    def _feed(self) -> None:
        """One worker's thread: wait for a started worker, then hand it one job at a time."""
        try:
            # A job handed to a worker still starting might end after this thread has run every other job.
            ready = self.pool.submit(started)
            futures_wait([ready])
            if ready.exception() is not None:  # it could not start: its share runs here and in the others
                self._broke.set()
                return
            while (i := self._take()) is not None:
                try:
                    fut = self.pool.submit(self.fn, self.jobs[i])
                except BrokenProcessPool:  # broken since this worker's last job: this one runs elsewhere
                    with self._lock:
                        self._back.append(i)
                    raise
                futures_wait([fut])
                self._done.put((i, fut))
                if isinstance(fut.exception(), BrokenProcessPool):
                    return
        except Exception:  # the pool broke or was shut down: the jobs left run here
            self._broke.set()
        finally:
            self._done.put(None)

    def _finished(self, i: int, fut: Future[Result]) -> tuple[int, Result]:
        if isinstance(fut.exception(), BrokenProcessPool):
            self._broke.set()
        return i, guarded(fut.result, self.jobs[i], self.on_error)


def guarded(get: Callable[[], Result], job: Job, on_error: Callable[[Job, Exception], Result] | None) -> Result:
    """``get()``; with ``on_error``, a job that raised becomes ``on_error(job, error)``."""
    if on_error is None:
        return get()
    try:
        return get()
    except Exception as e:
        return on_error(job, e)


def started() -> None:
    """A call that returns once a worker has started (its initializer run)."""
