"""The 125 Hz servo loop in a process of its own, at real-time priority where the OS allows it.

Why: in the agent's process the servo thread shares the GIL with the policy (torch, numpy, Python code) and a
busy interpreter delays its wake-ups; under CPU load that meant missed cycles and ``watchdog_cycle`` /
``rtde_stale`` faults. Here a child process (``multiprocessing``, spawn) owns everything the loop touches: the
``ur_rtde`` interfaces (:class:`drillgym.envs.real.robot_link.RobotLink`), the Net F/T stream and the loop itself
(:class:`drillgym.envs.real.servo.ServoLoop`, unchanged: the same checks, the same named faults).

* Priority: the child asks for ``SCHED_FIFO`` (:data:`RT_PRIORITY`) before it opens anything, so ``ur_rtde``'s and
  the F/T receive threads inherit it; where that is refused it tries ``nice`` :data:`NICE_FALLBACK`, and says
  which it got (:attr:`ServoProcess.scheduling`, logged at WARNING when it is not real-time).
  ``DRILLGYM_SERVO_PRIORITY=normal`` in the environment leaves it at ordinary priority (for comparisons).
* Garbage collection: once the devices are open, the child freezes its objects (``gc.freeze``): a full
  collection of the imported modules' objects takes about 30 ms (measured with ``gc.collect()`` after importing
  the real env's modules), several lost cycles, and the loop itself allocates few container objects.
* The agent's process talks to it through a pipe (commands such as ``moveL``, the episode's start and stop,
  a snapshot of the stream's state once per agent step) and shared memory for what changes at the stream's
  rate: the commanded correction (:class:`drillgym.envs.real.servo_shared.SharedCommandSlot`), the F/T records
  (:class:`drillgym.envs.real.servo_shared.SharedFTRing`) and the end-of-stream event.
* Safety does not depend on the agent's process: if it stops stepping, the loop's ``agent_timeout`` check stops
  the robot; if it dies, the child notices the closed pipe, stops streaming (``servoStop``) and exits; SIGINT
  (Ctrl-C in the terminal) is left to the agent's process, which closes the env; SIGTERM stops it the same way.

Scripts that build the real env at import time need the usual ``if __name__ == "__main__":`` guard (spawn
imports the main module); ``servo_process=False`` keeps the loop as a thread in the agent's process.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.real import safety
from drillgym.envs.real.command_log import CommandLog
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.netft import FTRecord, NetFTCalibration, NetFTClient
from drillgym.envs.real.robot_link import BLOCKING_TIMEOUT_S, LinkError, RobotLink, RobotState
from drillgym.envs.real.servo import CellGeometry, ServoLoop, ServoStats
from drillgym.envs.real.servo_shared import HeldCommand, SharedCommandSlot, SharedFTRing
from drillgym.envs.task import DrillPath

LOG = logging.getLogger(__name__)

RT_PRIORITY = 20
"""``SCHED_FIFO`` priority of the servo process (1..99; above ordinary processes, below the kernel's own)."""
NICE_FALLBACK = -10
"""Niceness asked for where ``SCHED_FIFO`` is refused."""
SWITCH_INTERVAL_S = 0.0005
"""The child's GIL switch interval (s; Python's default is 5 ms): the loop gets the interpreter back quickly from
the pipe and F/T threads."""
START_TIMEOUT_S = 60.0
"""How long the child may take to import, connect and receive its first F/T record (s)."""
CALL_TIMEOUT_S = BLOCKING_TIMEOUT_S + 5.0
"""Deadline of a call to the child beyond the child's own deadline for it (s)."""

LINK_METHODS = frozenset(
    {
        "state",
        "connected",
        "restart_program",
        "set_tcp",
        "move_l",
        "set_watchdog",
        "servo_stop",
        "stop_script",
        "program_running",
        "healthy",
        "wedged",
    }
)
"""What the agent's process may ask of the link (``wedged`` is an attribute)."""


@dataclass(frozen=True)
class ServoProcessSpec:
    """What the child opens (picklable)."""

    robot_host: str
    servo: ServoParams
    dry_run: bool
    command_log_path: str | None
    ft_address: tuple[str, int] | None
    """``(host, port)`` of the Net F/T's RDT stream, or None (no F/T: ``bench-rtde``)."""
    calibration: NetFTCalibration
    rt_priority: int = RT_PRIORITY
    first_record_timeout_s: float = 2.0


def raise_priority(rt_priority: int) -> tuple[str, bool]:
    """Make this process real-time (``SCHED_FIFO``) if allowed, else as nice as allowed; ``(what, realtime)``."""
    if os.environ.get("DRILLGYM_SERVO_PRIORITY") == "normal":
        return f"SCHED_OTHER nice {os.nice(0)} (DRILLGYM_SERVO_PRIORITY=normal)", False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt_priority))
        return f"SCHED_FIFO priority {rt_priority}", True
    except (OSError, AttributeError) as e:
        refused = f"SCHED_FIFO refused ({e})"
    try:
        os.nice(NICE_FALLBACK - os.nice(0))
        return f"SCHED_OTHER nice {os.nice(0)}; {refused}", False
    except OSError as e:
        return f"SCHED_OTHER nice {os.nice(0)}; {refused}; a lower niceness refused ({e})", False


def _portable(error: BaseException) -> BaseException:
    """``error`` if it survives pickling as itself, else a :class:`LinkError` with its text."""
    if isinstance(error, LinkError | ValueError | RuntimeError | OSError | TimeoutError):
        return type(error)(*error.args) if isinstance(error, LinkError) else error
    return LinkError(f"servo process: {type(error).__name__}: {error}")


# ---------------------------------------------------------------------------------------------------- child
class _Host:
    """The child's objects and what the agent's process may ask of them."""

    def __init__(self, spec: ServoProcessSpec, slot: SharedCommandSlot, ring: SharedFTRing, ended: Any) -> None:
        self.slot, self.ring, self.ended = slot, ring, ended
        self.link: RobotLink | None = None
        self.ft: NetFTClient | None = None
        self.loop: ServoLoop | None = None
        self.link = RobotLink(spec.robot_host, spec.servo, spec.dry_run, CommandLog(spec.command_log_path))
        try:
            if spec.ft_address is not None:
                self.ft = self._open_ft(spec, ring)
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _open_ft(spec: ServoProcessSpec, ring: SharedFTRing) -> NetFTClient:
        assert spec.ft_address is not None
        host, port = spec.ft_address
        ft = NetFTClient(host, port, spec.calibration, on_record=ring.append)
        deadline = time.monotonic() + spec.first_record_timeout_s
        while ft.latest() is None:
            if time.monotonic() > deadline:
                ft.close()
                raise LinkError(f"no record from the Net F/T at {host}:{port} within {spec.first_record_timeout_s} s")
            time.sleep(0.005)
        return ft

    def dispatch(self, target: str, method: str, args: tuple[Any, ...]) -> Any:
        if target == "link" and method in LINK_METHODS:
            attr = getattr(self.link, method)
            return attr if method == "wedged" else attr(*args)
        if target == "servo":
            return getattr(self, f"servo_{method}")(*args)
        if target == "bench" and method == "stream":
            from drillgym.envs.real.servo_bench import stream_coded_targets

            assert self.link is not None
            return stream_coded_targets(self.link.control, *args)
        if target == "bench" and method == "floor":
            from drillgym.envs.real.servo_bench import sleep_floor

            return sleep_floor(*args)
        raise LookupError(f"the servo process has no {target}.{method}")

    def servo_create(self, kwargs: dict[str, Any]) -> dict[str, Any]:
        if self.loop is not None and not self.loop.ended.is_set():
            self.loop.stop()
        assert self.link is not None and self.ft is not None
        self.loop = ServoLoop(self.link, self.ft, command_slot=self.slot, ended=self.ended, **kwargs)
        return self.loop.snapshot()

    def servo_start(self) -> None:
        assert self.loop is not None
        self.loop.start()

    def servo_snapshot(self, history_from: int) -> dict[str, Any]:
        assert self.loop is not None and self.link is not None
        snap = self.loop.snapshot(history_from)
        try:  # a fresh state in the same round trip: one wake-up of the agent's process per step, not two
            snap["read_state"] = self.link.state()
        except LinkError as e:
            snap["read_state"] = e
        return snap

    def servo_stop(self, timeout_s: float, history_from: int) -> dict[str, Any]:
        assert self.loop is not None
        self.loop.stop(timeout_s)
        return self.loop.snapshot(history_from)

    def close(self, exiting: bool = False) -> None:
        """Stop streaming, close the F/T stream and the robot link (``exiting``: see :meth:`RobotLink.close`)."""
        if self.loop is not None:
            self.loop.stop()
        if self.ft is not None:
            self.ft.close()
        if self.link is not None:
            self.link.close(exiting=exiting)


def _serve(conn: Any, spec: ServoProcessSpec, slot: SharedCommandSlot, ring: SharedFTRing, ended: Any) -> None:
    """The child's main: raise the priority, open the devices, answer calls until closed or orphaned."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the agent's: it closes the env, which closes us

    def _terminate(signum: int, frame: Any) -> None:
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, _terminate)
    scheduling, _ = raise_priority(spec.rt_priority)
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    host: _Host | None = None
    try:
        try:
            host = _Host(spec, slot, ring, ended)
        except BaseException as e:
            conn.send(("error", _portable(e)))
            return
        gc.collect()
        gc.freeze()  # what is there now is never scanned again: a full collection of it took ~30 ms (a lost cycle)
        conn.send(("ready", scheduling))
        while True:
            try:
                message = conn.recv()
            except EOFError:  # the agent's process is gone
                return
            if message[0] == "close":
                return
            call_id, target, method, args = message
            try:
                reply = (call_id, True, host.dispatch(target, method, args))
            except BaseException as e:
                reply = (call_id, False, _portable(e))
            conn.send(reply)
    finally:
        if host is not None:
            host.close(exiting=True)
        with contextlib.suppress(OSError):
            conn.close()
        # The devices are closed; end here, without ur_rtde's destructors (0.5 s of sleep per interface).
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        logging.shutdown()
        os._exit(0)


# ---------------------------------------------------------------------------------------------------- parent
class ServoProcess:
    """The servo process, seen from the agent's process: start it, call it, close it."""

    def __init__(self, spec: ServoProcessSpec, start_timeout_s: float = START_TIMEOUT_S) -> None:
        ctx = multiprocessing.get_context("spawn")
        self.spec = spec
        self.slot = SharedCommandSlot(ctx)
        self.ring = SharedFTRing(context=ctx)
        self.ended = ctx.Event()
        self._lock = threading.Lock()
        self._next_id = 0
        self.closed = False
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=_serve, args=(child, spec, self.slot, self.ring, self.ended), name="drillgym-servo", daemon=True
        )
        self.proc.start()
        child.close()
        self.scheduling = "unknown"
        """How the child is scheduled, e.g. ``SCHED_FIFO priority 20`` (what :func:`raise_priority` got)."""
        self.realtime = False
        try:
            kind, value = self._receive(start_timeout_s, "starting")
        except BaseException:
            self._end_process()
            raise
        if kind == "error":
            self._end_process()
            raise value
        self.scheduling = str(value)
        self.realtime = self.scheduling.startswith("SCHED_FIFO")
        if not self.realtime:
            LOG.warning("servo process for %s is not real-time: %s", spec.robot_host, self.scheduling)

    @property
    def pid(self) -> int | None:
        """The child's process id."""
        return self.proc.pid

    def _receive(self, timeout_s: float, what: str) -> Any:
        if not self.conn.poll(timeout_s):
            raise LinkError(
                f"the servo process for {self.spec.robot_host} did not answer {what} within {timeout_s:.1f} s"
            )
        try:
            return self.conn.recv()
        except (EOFError, OSError) as e:
            self.proc.join(1.0)
            hint = (
                ' (a script that builds the real env at import time needs the `if __name__ == "__main__":` guard)'
                if what == "starting"
                else ""
            )
            raise LinkError(
                f"the servo process for {self.spec.robot_host} ended (exit code {self.proc.exitcode}) while {what}{hint}"
            ) from e

    def call(self, target: str, method: str, *args: Any, timeout_s: float = CALL_TIMEOUT_S) -> Any:
        """``target.method(*args)`` in the child; its exception is raised here; ``LinkError`` past ``timeout_s``."""
        if self.closed:
            raise LinkError(f"{method} not sent: the servo process for {self.spec.robot_host} is closed")
        with self._lock:
            self._next_id += 1
            call_id = self._next_id
            try:
                self.conn.send((call_id, target, method, args))
            except OSError as e:
                raise LinkError(f"{method}: the servo process for {self.spec.robot_host} is gone ({e})") from e
            deadline = time.monotonic() + timeout_s
            while True:
                reply = self._receive(max(deadline - time.monotonic(), 0.0), method)
                if reply[0] == call_id:  # an earlier call that timed out may answer late: skip it
                    break
        _, ok, value = reply
        if not ok:
            raise value
        return value

    def close(self, timeout_s: float = 10.0) -> None:
        """Stop streaming, disconnect and end the child (idempotent)."""
        if self.closed:
            return
        self.closed = True
        with contextlib.suppress(OSError):
            self.conn.send(("close",))
        self.proc.join(timeout_s)
        self._end_process()

    def _end_process(self) -> None:
        if self.proc.is_alive():
            self.proc.terminate()  # SIGTERM: the child stops streaming on its way out
            self.proc.join(3.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(1.0)
        with contextlib.suppress(OSError):
            self.conn.close()


class RemoteLink:
    """:class:`RobotLink`'s interface, answered by the servo process."""

    def __init__(self, process: ServoProcess) -> None:
        self.process = process
        self.host = process.spec.robot_host
        self.dry_run = process.spec.dry_run

    def _call(self, method: str, *args: Any, timeout_s: float = CALL_TIMEOUT_S) -> Any:
        return self.process.call("link", method, *args, timeout_s=timeout_s)

    @property
    def wedged(self) -> bool:
        """A blocking command never returned in the child (see :class:`RobotLink`)."""
        if self.process.closed:
            return False
        try:
            return bool(self._call("wedged"))
        except LinkError:
            return True

    def state(self) -> RobotState:
        """The newest robot state; ``LinkError`` if it cannot be read."""
        return self._call("state")

    def connected(self) -> bool:
        """Both interfaces still connected (False when the servo process cannot answer)."""
        try:
            return bool(self._call("connected"))
        except LinkError:
            return False

    def healthy(self, within_s: float = 0.1) -> bool:
        """Connected and the state advances (see :meth:`RobotLink.healthy`)."""
        try:
            return bool(self._call("healthy", within_s))
        except LinkError:
            return False

    def restart_program(self, timeout_s: float = 5.0) -> None:
        """See :meth:`RobotLink.restart_program`."""
        self._call("restart_program", timeout_s, timeout_s=timeout_s + 2 * BLOCKING_TIMEOUT_S + CALL_TIMEOUT_S)

    def move_l(self, pose: np.ndarray, speed_m_s: float, acceleration_m_s2: float = 0.5) -> bool:
        """Blocking straight move (see :meth:`RobotLink.move_l`)."""
        p = np.asarray(pose, dtype=float)
        if p.shape != (6,) or not np.all(np.isfinite(p)):
            raise UserError(f"moveL pose must be 6 finite values, got {p.tolist()}; nothing sent")
        expected_s = float(np.linalg.norm(p[:3] - self.state().tcp_pose[:3])) / max(speed_m_s, 1e-6)
        timeout_s = expected_s + BLOCKING_TIMEOUT_S + 1.0 + CALL_TIMEOUT_S
        return bool(self._call("move_l", p, speed_m_s, acceleration_m_s2, timeout_s=timeout_s))

    def set_tcp(self, tcp_offset_pose: np.ndarray) -> bool:
        """See :meth:`RobotLink.set_tcp`."""
        return bool(self._call("set_tcp", np.asarray(tcp_offset_pose, dtype=float)))

    def set_watchdog(self, min_frequency_hz: float) -> bool:
        """See :meth:`RobotLink.set_watchdog`."""
        return bool(self._call("set_watchdog", min_frequency_hz))

    def servo_stop(self) -> bool:
        """See :meth:`RobotLink.servo_stop`."""
        return bool(self._call("servo_stop"))

    def stop_script(self) -> None:
        """See :meth:`RobotLink.stop_script`."""
        self._call("stop_script")

    def program_running(self) -> bool:
        """See :meth:`RobotLink.program_running`."""
        return bool(self._call("program_running"))

    def close(self) -> None:
        """End the servo process (it stops streaming and disconnects)."""
        self.process.close()


class RemoteFT:
    """:class:`NetFTClient`'s reading interface, on the records the servo process shares."""

    def __init__(self, process: ServoProcess, calibration: NetFTCalibration) -> None:
        self.ring = process.ring
        self.calibration = calibration
        self.address = process.spec.ft_address

    def latest(self) -> FTRecord | None:
        """The newest record, or None before the first."""
        return self.ring.latest()

    def since(self, t_start_s: float) -> list[FTRecord]:
        """Records that arrived at or after ``t_start_s`` (monotonic clock), oldest first."""
        return self.ring.since(t_start_s)

    @property
    def received(self) -> int:
        """Records received so far."""
        return self.ring.count

    def close(self) -> None:
        """Nothing to do: the servo process owns the stream."""


class RemoteServo(HeldCommand):
    """:class:`ServoLoop`'s agent side, for a loop running in the servo process.

    ``command`` writes the shared slot (no call); ``sync`` (once per agent step) fetches the fault, the end,
    the statistics and the new path history; ``stop`` ends the stream and fetches the final ones.
    """

    def __init__(
        self,
        process: ServoProcess,
        ft_bias: np.ndarray,
        geometry: CellGeometry,
        path: DrillPath,
        limits: SafetyLimits,
        servo: ServoParams,
        force_limit_n: float,
        t0: float,
    ) -> None:
        self.process, self.geo, self.limits, self.servo, self.t0 = process, geometry, limits, servo, t0
        self.slot, self.ended = process.slot, process.ended
        self.fault: safety.Fault | None = None
        self.done_t_s: float | None = None
        self.stats = ServoStats()
        self.history_t: list[float] = []
        self.history_s: list[float] = []
        self.history_phase: list[int] = []
        self._started = self._stopped = False
        self._read_state: RobotState | LinkError | None = None
        kwargs = {
            "ft_bias": np.asarray(ft_bias, dtype=float),
            "geometry": geometry,
            "path": path,
            "limits": limits,
            "servo": servo,
            "force_limit_n": force_limit_n,
            "t0": t0,
        }
        snap = process.call("servo", "create", kwargs)
        self.state: RobotState = snap["state"]

    def start(self) -> None:
        """Start streaming."""
        self.process.call("servo", "start")
        self._started = True

    def sync(self) -> None:
        """Fetch the stream's fault, end, statistics, state, new path history and a fresh robot state."""
        if self._started and not self._stopped:
            snap = self.process.call("servo", "snapshot", len(self.history_t))
            self._read_state = snap["read_state"]
            self._apply(snap)

    def robot_state(self) -> RobotState:
        """The robot state read at the last :meth:`sync` (``LinkError`` if it could not be read), else a fresh one."""
        read, self._read_state = self._read_state, None
        if read is None:
            return RemoteLink(self.process).state()
        if isinstance(read, LinkError):
            raise read
        return read

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop streaming (``servoStop``) and fetch the final figures."""
        if not self._started or self._stopped:
            return
        self._stopped = True
        try:
            snap = self.process.call(
                "servo", "stop", timeout_s, len(self.history_t), timeout_s=timeout_s + CALL_TIMEOUT_S
            )
        except LinkError as e:
            if self.fault is None:
                self.fault = safety.Fault("link_lost", str(e), time.monotonic() - self.t0)
            return
        self._apply(snap)

    def _apply(self, snap: dict[str, Any]) -> None:
        self.fault, self.done_t_s, self.stats, self.state = (
            snap["fault"],
            snap["done_t_s"],
            snap["stats"],
            snap["state"],
        )
        t, s, phase = snap["history"]
        self.history_t.extend(t)
        self.history_s.extend(s)
        self.history_phase.extend(phase)
