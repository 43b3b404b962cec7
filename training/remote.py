"""An object kept in a worker process of its own, its methods called through a pipe.

:class:`Remote` spawns a process, builds ``factory(**kwargs)`` there and keeps it: a stateful part of a job (a
shard of a batched env) lives beside this process instead of being rebuilt for every call, which a pool of
stateless jobs would do. Calls are split in two (:meth:`Remote.send`, then :meth:`Remote.receive`) so that this
process can work while the worker does. The worker starts deaf to Ctrl-C (the interrupted parent stops it), ends when
its parent closes the pipe or dies, and sends back any error its object raises, re-raised here.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import signal
import threading
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from drillgym.envs.errors import UserError

CLOSE_TIMEOUT_S = 10.0
"""How long :meth:`Remote.close` waits for the worker to end before terminating it (s)."""


class Remote:
    """``factory(**kwargs)``, built and kept in a spawned worker process.

    Args:
        factory: a picklable callable (a class or a module-level function) building the object.
        kwargs: its picklable arguments.

    Raises:
        Whatever building the object raised in the worker (or ``RuntimeError`` if the worker died).
    """

    def __init__(self, factory: Callable[..., Any], kwargs: dict[str, Any]) -> None:
        ctx = mp.get_context("spawn")
        self._conn, child = ctx.Pipe()
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None  # a child inherits it ignored
        try:
            self._process = ctx.Process(target=_serve, args=(child, factory, kwargs), daemon=True)
            self._process.start()
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        child.close()
        try:
            self.receive()  # built (or its error)
        except BaseException:
            self.close()
            raise

    def send(self, method: str, *args: Any) -> None:
        """Ask the object to run ``method(*args)`` (the answer: :meth:`receive`)."""
        try:
            self._conn.send((method, args))
        except OSError as exc:  # a broken pipe: the worker is gone
            raise RuntimeError(f"the worker process ended (exit code {self._process.exitcode})") from exc

    def receive(self) -> Any:
        """The answer to the last :meth:`send`: its return value, or its error raised here."""
        try:
            ok, value = self._conn.recv()
        except (EOFError, OSError) as exc:
            raise RuntimeError(f"the worker process ended (exit code {self._process.exitcode})") from exc
        if not ok:
            raise value
        return value

    def call(self, method: str, *args: Any) -> Any:
        """``method(*args)`` on the object, waiting for the answer."""
        self.send(method, *args)
        return self.receive()

    def close(self) -> None:
        """End the worker (the object's ``close`` runs there first, if it has one); terminate it if it hangs."""
        if self._process.is_alive():
            try:
                self._conn.send(("__close__", ()))
            except (BrokenPipeError, OSError):
                pass
            self._process.join(CLOSE_TIMEOUT_S)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._conn.close()


def _serve(conn: Connection, factory: Callable[..., Any], kwargs: dict[str, Any]) -> None:
    """The worker: build the object, then answer calls until told to close or the parent goes."""
    try:
        obj = factory(**kwargs)
    except BaseException as exc:
        conn.send((False, _portable(exc)))
        return
    conn.send((True, None))
    try:
        while True:
            try:
                method, args = conn.recv()
            except (EOFError, OSError):  # the parent closed the pipe or died
                break
            if method == "__close__":
                break
            try:
                result = (True, getattr(obj, method)(*args))
            except Exception as exc:
                result = (False, _portable(exc))
            conn.send(result)
    finally:
        if hasattr(obj, "close"):
            obj.close()


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a ``RuntimeError`` (a ``UserError`` kept as one) with its traceback."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        text = "".join(traceback.format_exception(exc))
        return UserError(str(exc)) if isinstance(exc, UserError) else RuntimeError(f"in the worker process:\n{text}")
