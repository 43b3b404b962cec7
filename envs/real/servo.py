"""The 125 Hz servo stream of the real cell: nominal path + latest correction, checked, then ``servoL``.

A background thread owns the robot while an episode runs: in the agent's process, or (the real env's default)
in a servo process of its own (:mod:`drillgym.envs.real.servo_process`), where the agent's compute cannot delay it. Every cycle (``initPeriod`` / ``waitPeriod``)
it advances the nominal path (:class:`drillgym.envs.task.DrillPath`) by the elapsed time at the commanded feed
override, adds the latest correction the agent commanded (held between agent steps), rate-limits the
target, checks every safety condition (:mod:`drillgym.envs.real.safety`) and streams ``servoL``. On any fault it
commands ``servoStop`` (and, if the link is lost, tries ``stopScript``) and ends; at the end of the
path it stops servoing. The agent side reads the fault, the timing statistics and the path history.

The path advances with the episode's clock (``time.monotonic() - t0``, the clock of the agent's 50 ms windows), not
with the servo cycles that ran, so a stream that starts late or a late cycle does not shift the path against the
agent's steps (after a late cycle the rate limit lets the target catch up over a few cycles). A controller that acts
on its step count (li2023 updates its compensation every 12 steps) then meets the bone at the same step as in the
sim. Counted from the first cycle instead, the path lagged by the servo process's start (up to 124 ms in loaded
test runs): the contact moved by 2.5 steps and li2023's entry peak lateral force from 1.22 to 1.58 N.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym.envs.real import safety
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.netft import NetFTClient
from drillgym.envs.real.poses import matrix_to_rotvec
from drillgym.envs.real.robot_link import LinkError, RobotLink, RobotState
from drillgym.envs.real.servo_shared import CommandSlot, HeldCommand
from drillgym.envs.task import DrillPath, Phase

REFUSAL_STATE_WAIT_S = 0.05
"""After a refused ``servoL``, how long to watch the RTDE state for a safety stop behind it (s): 6 RTDE cycles."""
REFUSAL_POLL_S = 0.002
"""Poll period of that watch (s)."""

BLIND_FAULTS = ("link_lost", "rtde_stale")
"""Faults after which no blocking command is tried (see :meth:`ServoLoop._try_stop`)."""
MAX_CYCLES = 10_000_000
"""Hard bound on the loop (about 22 h at 125 Hz)."""


@dataclass
class ServoStats:
    """Timing of the stream (client side)."""

    cycles: int = 0
    missed_cycles: int = 0
    """Periods in which no command was sent (a late cycle counts the periods it skipped)."""
    max_gap_s: float = 0.0
    """Longest time between two commands (s)."""
    servo_call_max_s: float = 0.0
    """Longest ``servoL`` call (s)."""
    stop_result: str = ""
    """What the stop at the end returned (``servoStop`` True/False, or the error)."""
    gaps_s: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class CellGeometry:
    """Where the hole is: the frames the stream needs (SI, base frame)."""

    entry_base_m: np.ndarray
    R_base_task: np.ndarray
    depth_m: float

    @property
    def tool_rotvec(self) -> np.ndarray:
        """TCP orientation along the planned drill axis (rotation vector, rad)."""
        return matrix_to_rotvec(self.R_base_task)

    def to_task(self, p_base_m: np.ndarray) -> np.ndarray:
        """A base-frame point in the task frame (m)."""
        return self.R_base_task.T @ (np.asarray(p_base_m, dtype=float) - self.entry_base_m)

    def to_base(self, p_task_m: np.ndarray) -> np.ndarray:
        """A task-frame point in the base frame (m)."""
        return self.entry_base_m + self.R_base_task @ np.asarray(p_task_m, dtype=float)


class ServoLoop(HeldCommand):
    """Streams one episode's path; one instance per episode (``start`` once, ``stop`` when done)."""

    def __init__(
        self,
        link: RobotLink,
        ft: NetFTClient,
        ft_bias: np.ndarray,
        geometry: CellGeometry,
        path: DrillPath,
        limits: SafetyLimits,
        servo: ServoParams,
        force_limit_n: float,
        t0: float,
        command_slot: CommandSlot | None = None,
        ended: Any = None,
    ) -> None:
        """One episode's stream (nothing is sent before :meth:`start`).

        ``command_slot`` and ``ended`` (an ``Event``): shared with the agent's process when this runs in a servo
        process (:mod:`drillgym.envs.real.servo_process`); by default made here.
        """
        self.link, self.ft, self.ft_bias = link, ft, np.asarray(ft_bias, dtype=float)
        self.geo, self.path, self.limits, self.servo = geometry, path, limits, servo
        self.force_limit_n = force_limit_n
        self.t0 = t0
        self.slot = command_slot or CommandSlot()
        self.slot.write(np.zeros(3), 1.0, t0)
        self.history_t: list[float] = []
        self.history_s: list[float] = []
        self.history_phase: list[int] = []
        self.fault: safety.Fault | None = None
        self.done_t_s: float | None = None
        self.ended = ended if ended is not None else threading.Event()
        self.ended.clear()
        self.stats = ServoStats()
        self.state = link.state()
        self.target_base_m = np.asarray(self.state.tcp_pose[:3], dtype=float)
        self._stop_requested = threading.Event()
        self._thread = threading.Thread(target=self._run, name="servo-loop", daemon=True)

    # ------------------------------------------------------------------ agent side
    def start(self) -> None:
        """Start streaming."""
        self._thread.start()

    def sync(self) -> None:
        """Bring the agent's view up to date (nothing to do in one process; see the servo process's proxy)."""

    def robot_state(self) -> RobotState:
        """A fresh read of the robot state (``LinkError`` if it cannot be read)."""
        return self.link.state()

    def snapshot(self, history_from: int = 0) -> dict[str, Any]:
        """What the agent reads of the stream (picklable).

        Fault, end, statistics, state, and the path history from index ``history_from`` on.
        """
        st = self.stats
        n = min(len(self.history_t), len(self.history_s), len(self.history_phase))  # the thread may be appending
        return {
            "fault": self.fault,
            "done_t_s": self.done_t_s,
            "ended": self.ended.is_set(),
            "stats": ServoStats(st.cycles, st.missed_cycles, st.max_gap_s, st.servo_call_max_s, st.stop_result),
            "state": self.state,
            "history": (
                self.history_t[history_from:n],
                self.history_s[history_from:n],
                self.history_phase[history_from:n],
            ),
        }

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop streaming (``servoStop``) and wait for the thread."""
        self._stop_requested.set()
        if self._thread.is_alive():
            self._thread.join(timeout=timeout_s)

    # ------------------------------------------------------------------ thread
    def _run(self) -> None:
        streaming = False
        try:
            last_send: float | None = None
            last_now = self.t0  # the path runs on the episode's clock (module docstring)
            last_timestamp, last_rtde_change = self.state.timestamp_s, time.monotonic()
            for _ in range(MAX_CYCLES):
                if self._stop_requested.is_set():
                    break
                t_cycle = self.link.init_period()
                now = time.monotonic()
                t = now - self.t0
                dt = now - last_now
                last_now = now
                state = self.link.state()
                if state.timestamp_s != last_timestamp:
                    last_timestamp, last_rtde_change = state.timestamp_s, now
                self.state = state
                target = self._next_target(dt)
                fault = self._check(state, target, now, now - last_rtde_change, last_send, t)
                if fault is not None:
                    self._fail(fault)
                    streaming = False
                    return
                ok = self.link.servo_l(np.concatenate([target, self.geo.tool_rotvec]))
                sent = time.monotonic()
                self.stats.servo_call_max_s = max(self.stats.servo_call_max_s, sent - now)
                if not ok:
                    self._fail(self._refusal_cause(t))
                    streaming = False
                    return
                streaming = True
                self.target_base_m = target
                if last_send is not None:
                    self._count_gap(sent - last_send)
                    if sent - last_send > self.limits.max_cycle_gap_s:
                        gap_ms = (sent - last_send) * 1e3
                        self._fail(safety.Fault("watchdog_cycle", f"{gap_ms:.0f} ms between two servo commands", t))
                        streaming = False
                        return
                last_send = sent
                self.stats.cycles += 1
                self.history_t.append(t)
                self.history_s.append(self.path.s_m)
                self.history_phase.append(int(self.path.phase))
                if self.path.phase == Phase.DONE:
                    self.stats.stop_result = f"servoStop {self.link.servo_stop()}"
                    streaming = False
                    self.done_t_s = t
                    return
                self.link.wait_period(t_cycle)
        except LinkError as e:
            self._fail(safety.Fault("link_lost", str(e), time.monotonic() - self.t0))
            streaming = False
        except Exception as e:  # never die silently: stop the robot and report
            self._fail(safety.Fault("internal_error", f"{type(e).__name__}: {e}", time.monotonic() - self.t0))
            streaming = False
        finally:
            if streaming:
                self.stats.stop_result = self._try_stop()
            self.ended.set()

    def _refusal_cause(self, t_s: float) -> safety.Fault:
        """Why the controller refused ``servoL``: a safety stop if the next RTDE states show one, else ``servo_refused``.

        A protective stop refuses the servo program at once, but the RTDE state that reports it can arrive
        a cycle or two after the state this cycle read; the root cause is the stop, not the refusal.
        """
        deadline = time.monotonic() + REFUSAL_STATE_WAIT_S
        while True:
            try:
                state = self.link.state()
            except LinkError:
                break
            self.state = state
            fault = safety.check_safety_bits(state.safety_status_bits, t_s)
            if fault is not None:
                return safety.Fault(fault.reason, f"{fault.message} (servoL was refused)", t_s)
            if time.monotonic() >= deadline:
                break
            time.sleep(REFUSAL_POLL_S)
        return safety.Fault("servo_refused", "the controller refused servoL", t_s)

    def _count_gap(self, gap_s: float) -> None:
        period = self.servo.period_s
        self.stats.max_gap_s = max(self.stats.max_gap_s, gap_s)
        if gap_s > 1.5 * period:
            self.stats.missed_cycles += round(gap_s / period) - 1
        if len(self.stats.gaps_s) < 200_000:
            self.stats.gaps_s.append(gap_s)

    def _next_target(self, dt_s: float) -> np.ndarray:
        """Advance the path by ``dt_s`` (s, the episode clock's step) and rate-limit the new target.

        The rate limit counts at most 3 servo periods, so after a late cycle the target catches up with the path
        at ``max_tcp_speed_m_s`` over the next cycles instead of jumping.
        """
        corr, scale, _ = self.slot.read()
        s = self.path.advance(dt_s, scale)
        desired = self.geo.to_base(self.geo.R_base_task.T @ corr + np.array([0.0, 0.0, s]))
        step_s = min(max(dt_s, 1e-4), 3.0 * self.servo.period_s)
        return safety.rate_limit(self.target_base_m, desired, self.limits.max_tcp_speed_m_s * step_s)

    def _check(
        self, state: RobotState, target: np.ndarray, now: float, rtde_age_s: float, last_send: float | None, t: float
    ) -> safety.Fault | None:
        """The first failing safety check of this cycle, root causes first, or None."""
        lim, geo, dry = self.limits, self.geo, self.link.dry_run
        if not self.link.connected():
            return safety.Fault("link_lost", f"RTDE connection to {self.link.host} lost", t)
        fault = safety.check_safety_bits(state.safety_status_bits, t)
        if fault is None and last_send is not None and now - last_send > lim.max_cycle_gap_s:
            fault = safety.Fault("watchdog_cycle", f"{(now - last_send) * 1e3:.0f} ms since the last servo command", t)
        if fault is None and not dry and state.runtime_state != safety.PROGRAM_PLAYING:
            msg = f"the control program is not running (runtime_state {state.runtime_state})"
            fault = safety.Fault("program_stopped", msg, t)
        fault = fault or safety.check_age("rtde", rtde_age_s, lim.rtde_stale_s, t)
        fault = fault or safety.check_workspace(geo.to_task(target), geo.depth_m, lim, "servo target", t)
        fault = fault or safety.check_workspace(geo.to_task(state.tcp_pose[:3]), geo.depth_m, lim, "measured TCP", t)
        if fault is None and not dry:
            fault = safety.check_tracking(state.tcp_pose[:3], self.target_base_m, lim, t)
        rec = self.ft.latest()
        fault = fault or safety.check_age("ft", None if rec is None else now - rec.t_recv_s, lim.ft_stale_s, t)
        if fault is None and rec is not None:
            fault = safety.check_force(rec.wrench - self.ft_bias, self.force_limit_n, t)
        idle = now - self.slot.read()[2]
        if fault is None and idle > lim.agent_timeout_s:
            fault = safety.Fault("agent_timeout", f"no step() for {idle:.2f} s", t)
        return fault

    def _fail(self, fault: safety.Fault) -> None:
        """Record the fault and stop the robot as far as the link allows."""
        self.fault = fault
        self.stats.stop_result = self._try_stop(blind=fault.reason in BLIND_FAULTS)

    def _try_stop(self, blind: bool = False) -> str:
        """Command ``servoStop`` where the link allows it; say what happened.

        ``blind``: the robot state is not coming in, so ``ur_rtde`` would wait for a "done" it cannot see; the
        stream has stopped, and the robot's RTDE watchdog (armed at reset) ends the program.
        """
        if blind or not self.link.connected():
            return (
                "servoStop not sent: no robot state (link down or stale); streaming stopped, the robot's RTDE "
                f"watchdog ({self.limits.robot_watchdog_hz:g} Hz) stops the program"
            )
        try:
            return f"servoStop {self.link.servo_stop()}"
        except LinkError as e:
            return f"servoStop failed: {e}"
