"""The link to a UR controller through ``ur_rtde``: state in, commands out, dry-run, clear errors.

``RTDEReceiveInterface`` streams the state (125 Hz on a CB3); ``RTDEControlInterface`` (default flags: it
uploads ``ur_rtde``'s control program) takes commands. In dry-run mode no control interface is created at
all, so nothing can move the robot: every command is written to the :class:`CommandLog` instead.
Every ``ur_rtde`` failure (exception, or a command it refuses) surfaces as :class:`LinkError` or ``False``.

Blocking commands (``servoStop``, ``moveL``, ...) wait inside ``ur_rtde`` for the program's "done" signal, up to
300 s, and on a silent link the cached state keeps saying "running": such a call would hang. They therefore run
on a helper thread with a deadline; a call that misses it marks the link *wedged* (no further command is tried)
and the control interface is kept alive (destroying it under the hung call would crash the process).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.real.command_log import CommandLog
from drillgym.envs.real.config import ServoParams

RTDE_STATE_VARIABLES = [
    "timestamp",
    "actual_q",
    "actual_TCP_pose",
    "target_TCP_pose",
    "robot_mode",
    "safety_mode",
    "runtime_state",
    "safety_status_bits",
]
"""What the env reads from the robot (a small recipe: less to parse at 125 Hz)."""


BLOCKING_TIMEOUT_S = 2.0
"""Deadline of a blocking command beyond its expected duration (s)."""
DISCONNECT_TIMEOUT_S = 3.0
"""Deadline of disconnecting from an unhealthy link (s)."""
_ABANDONED: list[Any] = []
"""Control interfaces with a command still hung inside them: kept alive until the process exits."""


class LinkError(RuntimeError):
    """The robot link failed (connection lost, refused, or ``ur_rtde`` raised)."""


@dataclass(frozen=True)
class RobotState:
    """One read of the robot state."""

    t_read_s: float
    """When it was read, ``time.monotonic()`` (s)."""
    timestamp_s: float
    """The controller's own clock (s since its start): advances every RTDE cycle."""
    q_rad: np.ndarray
    """Joint angles (rad, encoder side)."""
    tcp_pose: np.ndarray
    """TCP pose ``[x, y, z, rx, ry, rz]`` (m, rad; base frame)."""
    target_tcp_pose: np.ndarray
    """The controller's target TCP pose (m, rad; base frame)."""
    safety_status_bits: int
    runtime_state: int


class RobotLink:
    """``ur_rtde`` interfaces to one robot (``dry_run``: receive only, commands logged, never sent)."""

    def __init__(
        self, host: str, servo: ServoParams, dry_run: bool = False, command_log: CommandLog | None = None
    ) -> None:
        import rtde_control
        import rtde_receive

        self.host = host
        self.servo = servo
        self.dry_run = dry_run
        self.log = command_log or CommandLog()
        self._lock = threading.Lock()
        self.wedged = False
        """A blocking command never returned: nothing more is sent (see the module docstring)."""
        self.receive: Any = None
        self.control: Any = None
        try:
            self.receive = rtde_receive.RTDEReceiveInterface(host, servo.rate_hz, RTDE_STATE_VARIABLES)
            if not dry_run:
                self.control = rtde_control.RTDEControlInterface(host, servo.rate_hz)
        except RuntimeError as e:
            self.close()
            raise LinkError(f"cannot connect to the UR controller at {host}: {e}") from e

    # ------------------------------------------------------------------ state
    def connected(self) -> bool:
        """Both interfaces still connected (dry-run: the receive interface)."""
        try:
            ok = bool(self.receive.isConnected())
            return ok and (self.control is None or bool(self.control.isConnected()))
        except RuntimeError:
            return False

    def state(self) -> RobotState:
        """The newest robot state; ``LinkError`` if it cannot be read."""
        r = self.receive
        try:
            return RobotState(
                time.monotonic(),
                float(r.getTimestamp()),
                np.asarray(r.getActualQ(), dtype=float),
                np.asarray(r.getActualTCPPose(), dtype=float),
                np.asarray(r.getTargetTCPPose(), dtype=float),
                int(r.getSafetyStatusBits()),
                int(r.getRuntimeState()),
            )
        except RuntimeError as e:
            raise LinkError(f"reading the robot state from {self.host} failed: {e}") from e

    # ------------------------------------------------------------------ timing
    def init_period(self) -> Any:
        """Start of a streaming cycle (``ur_rtde``'s ``initPeriod``)."""
        if self.control is not None:
            return self.control.initPeriod()
        return time.perf_counter()

    def wait_period(self, t_cycle: Any) -> None:
        """Sleep to the end of the cycle (``waitPeriod``)."""
        if self.control is not None:
            self.control.waitPeriod(t_cycle)
            return
        rest = self.servo.period_s - (time.perf_counter() - t_cycle)
        if rest > 0:
            time.sleep(rest)

    # ------------------------------------------------------------------ commands
    def _call(self, name: str, *args: Any, deadline_s: float | None = None) -> bool:
        """Call ``ur_rtde``; with ``deadline_s`` on a helper thread that may not take longer (s)."""
        self.log.add(name, args=[np.asarray(a, dtype=float).tolist() for a in args], sent=not self.dry_run)
        if self.control is None:
            return True
        if self.wedged:
            raise LinkError(f"{name} not sent: an earlier command to {self.host} never answered")
        if not self._lock.acquire(timeout=BLOCKING_TIMEOUT_S if deadline_s is None else deadline_s):
            raise LinkError(f"{name} not sent: the link to {self.host} is busy with a command that does not return")
        try:
            if deadline_s is None:
                return bool(getattr(self.control, name)(*args))
            return self._call_with_deadline(name, args, deadline_s)
        except RuntimeError as e:
            raise LinkError(f"{name} to {self.host} failed: {e}") from e
        finally:
            if not self.wedged:
                self._lock.release()

    def _call_with_deadline(self, name: str, args: tuple[Any, ...], deadline_s: float) -> bool:
        box: dict[str, Any] = {}

        def target() -> None:
            try:
                box["result"] = getattr(self.control, name)(*args)
            except RuntimeError as e:
                box["error"] = e

        worker = threading.Thread(target=target, name=f"ur_rtde-{name}", daemon=True)
        worker.start()
        worker.join(deadline_s)
        if worker.is_alive():
            self.wedged = True
            raise LinkError(f"{name} to {self.host}: no answer within {deadline_s:.1f} s (link lost?)")
        if "error" in box:
            raise box["error"]
        return bool(box.get("result", True))

    def servo_l(self, pose: np.ndarray) -> bool:
        """One ``servoL`` to ``pose`` (m, rad; base frame); False if the controller refused it."""
        p = np.asarray(pose, dtype=float)
        if p.shape != (6,) or not np.all(np.isfinite(p)):
            raise UserError(f"servoL pose must be 6 finite values, got {p.tolist()}; nothing sent")
        s = self.servo
        return self._call("servoL", p, s.speed, s.acceleration, s.period_s, s.lookahead_time_s, s.gain)

    def move_l(self, pose: np.ndarray, speed_m_s: float, acceleration_m_s2: float = 0.5) -> bool:
        """Blocking straight move to ``pose`` (m, rad; base frame)."""
        p = np.asarray(pose, dtype=float)
        if p.shape != (6,) or not np.all(np.isfinite(p)):
            raise UserError(f"moveL pose must be 6 finite values, got {p.tolist()}; nothing sent")
        distance = float(np.linalg.norm(p[:3] - self.state().tcp_pose[:3]))
        expected_s = distance / max(speed_m_s, 1e-6)
        return self._call("moveL", p, speed_m_s, acceleration_m_s2, deadline_s=expected_s + BLOCKING_TIMEOUT_S + 1.0)

    def set_tcp(self, tcp_offset_pose: np.ndarray) -> bool:
        """Configure the TCP (pose in the flange frame, m, rad)."""
        return self._call("setTcp", np.asarray(tcp_offset_pose, dtype=float), deadline_s=BLOCKING_TIMEOUT_S)

    def set_watchdog(self, min_frequency_hz: float) -> bool:
        """Robot-side RTDE watchdog: the program stops if inputs pause longer than 1/``min_frequency_hz``."""
        return self._call("setWatchdog", min_frequency_hz, deadline_s=BLOCKING_TIMEOUT_S)

    def servo_stop(self) -> bool:
        """End servoing, decelerating at ``servo.stop_deceleration_m_s2``."""
        return self._call("servoStop", self.servo.stop_deceleration_m_s2, deadline_s=BLOCKING_TIMEOUT_S)

    def stop_script(self) -> None:
        """Stop the control program (``stopScript``; ur_rtde returns nothing)."""
        self._call("stopScript", deadline_s=BLOCKING_TIMEOUT_S)

    def program_running(self) -> bool:
        """Whether ur_rtde's control program runs (dry-run: True)."""
        if self.control is None:
            return True
        try:
            return bool(self.control.isProgramRunning())
        except RuntimeError as e:
            raise LinkError(f"{self.host}: {e}") from e

    def restart_program(self, timeout_s: float = 5.0) -> None:
        """Stop ur_rtde's control program if it runs, upload it again and wait until it runs.

        A fresh program has no RTDE watchdog armed (an armed one would stop a long ``moveL``).
        """
        if self.control is None:
            return
        self._call("reuploadScript", deadline_s=2.0 * BLOCKING_TIMEOUT_S)
        deadline = time.monotonic() + timeout_s
        while not self.program_running():
            if time.monotonic() > deadline:
                raise LinkError(f"the control program did not start on {self.host} within {timeout_s} s")
            time.sleep(0.01)

    def healthy(self, within_s: float = 0.1) -> bool:
        """Connected, and the robot state advances (a new RTDE timestamp within ``within_s``)."""
        if self.receive is None or not self.connected():
            return False
        try:
            t0 = self.receive.getTimestamp()
            deadline = time.monotonic() + within_s
            while time.monotonic() < deadline:
                if self.receive.getTimestamp() != t0:
                    return True
                time.sleep(0.002)
        except RuntimeError:
            return False
        return False

    def close(self, exiting: bool = False) -> None:
        """Disconnect both interfaces.

        On a healthy link ``ur_rtde``'s destructors disconnect (0.5 s each); releasing the objects is enough. On
        an unhealthy one ``ur_rtde`` may be stuck reconnecting and its destructor would wait for it forever:
        ``disconnect()`` runs on a helper thread with a deadline, and interfaces that do not finish are kept
        alive (never destroyed) instead.

        ``exiting``: the process ends right after without running destructors (``os._exit``, the servo
        process): a healthy link's interfaces disconnect at once, each on a helper thread (``ur_rtde`` releases
        the GIL in ``disconnect``), and are kept; 0.5 s in all instead of 0.5 s each.
        """
        interfaces = [i for i in (self.control, self.receive) if i is not None]
        healthy = not self.wedged and self.healthy()
        self.control = self.receive = None
        self.log.close()
        if healthy or not interfaces:
            if exiting and interfaces:
                _ABANDONED.extend(interfaces)
                _disconnect_each(interfaces, DISCONNECT_TIMEOUT_S)
            return
        if not self.wedged:
            worker = threading.Thread(
                target=_disconnect_all, args=(interfaces,), name="ur_rtde-disconnect", daemon=True
            )
            worker.start()
            worker.join(DISCONNECT_TIMEOUT_S)
            if not worker.is_alive():
                return
        _ABANDONED.extend(interfaces)


def _disconnect_all(interfaces: list[Any]) -> None:
    for iface in interfaces:
        try:
            iface.disconnect()
        except RuntimeError:
            pass


def _disconnect_each(interfaces: list[Any], timeout_s: float) -> None:
    """``disconnect()`` every interface on a thread of its own, all within ``timeout_s`` (s)."""
    workers = [
        threading.Thread(target=_disconnect_all, args=([iface],), name="ur_rtde-disconnect", daemon=True)
        for iface in interfaces
    ]
    for worker in workers:
        worker.start()
    deadline = time.monotonic() + timeout_s
    for worker in workers:
        worker.join(max(0.0, deadline - time.monotonic()))
