"""How the servo loop kept time during one hole, and whether a stream stop was likely the machine's load.

``drillgym run`` prints this at the end of every hole (issue 43): the 125 Hz cycles the loop missed (as the loop
counts them, :attr:`drillgym.envs.real.servo.ServoStats.missed_cycles`), its period (median, 99th percentile and
maximum of the time between two servo commands), how it was scheduled (``SCHED_FIFO`` or not, niceness; in the
servo process or as a thread of the agent's process) and the 1-min load average of the machine against its cores.
When a hole stops on a stale stream or the watchdog (:data:`LOAD_FAULTS`), :func:`likely_cause` says whether the
machine's load is the likely cause, by the rule in its docstring.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

LOAD_FAULTS = ("rtde_stale", "ft_stale", "watchdog_cycle")
"""The stops a busy machine can cause: a stream seen stale, or the servo commands too far apart."""
BUSY_LOAD_PER_CORE = 1.0
"""A 1-min load average at or above this many runnable tasks per core means every core had work queued over the
last minute: a loop that is not real-time waits its turn, and on a virtual machine even a real-time one loses
wake-ups to the host (``docs/deployment.md`` §7: beside two busy processes on 2 cores, load 2.6-3.8)."""
UPSTREAM = {
    "rtde_stale": "the robot's state stopped coming: check the network link to the robot and its controller",
    "ft_stale": "the F/T records stopped coming: check the Net F/T's cable, power and RDT output rate",
    "watchdog_cycle": "the commands came late without a whole period lost: check --max-gap-ms against the period",
}
"""Where to look when the loop kept its period: the stream stopped upstream of this machine."""


@dataclass(frozen=True)
class ServoTiming:
    """One hole's servo-loop timing and the machine's load at its end.

    Periods are the times between two consecutive servo commands (s); ``scheduling`` says how the loop ran
    (e.g. ``SCHED_FIFO priority 20 (servo process)``), ``realtime`` whether that is a real-time policy;
    ``load_1min`` is ``os.getloadavg()[0]`` (runnable tasks, whole machine) and ``cores`` the machine's CPUs.
    """

    cycles: int
    missed_cycles: int
    period_median_s: float
    period_p99_s: float
    period_max_s: float
    scheduling: str
    realtime: bool
    load_1min: float
    cores: int
    servo_call_max_s: float = math.nan
    """The longest ``servoL`` call (s): ``ur_rtde`` waits in it for the control program's "ready"; the first
    call of a hole waits for the program to take the watchdog set at reset."""

    @property
    def busy(self) -> bool:
        """Whether the machine was saturated over the last minute (:data:`BUSY_LOAD_PER_CORE`)."""
        return self.load_1min >= BUSY_LOAD_PER_CORE * self.cores

    def to_json(self) -> dict[str, Any]:
        """JSON-ready (NaN stays NaN: the caller sanitises)."""
        return asdict(self)


def period_stats_s(send_times_s: Any) -> tuple[float, float, float]:
    """Median, 99th percentile and maximum of the time between consecutive commands (s); NaN with < 2 commands."""
    t = np.asarray(send_times_s, dtype=float)
    if t.size < 2:
        return math.nan, math.nan, math.nan
    gaps = np.diff(t)
    return float(np.median(gaps)), float(np.percentile(gaps, 99)), float(np.max(gaps))


def this_process_scheduling() -> tuple[str, bool]:
    """This process's scheduling policy and niceness, e.g. ``("SCHED_OTHER nice 0", False)``."""
    names = {getattr(os, n): n for n in ("SCHED_OTHER", "SCHED_BATCH", "SCHED_IDLE", "SCHED_FIFO", "SCHED_RR")}
    try:
        policy = os.sched_getscheduler(0)
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return f"policy unknown, nice {os.nice(0)}", False
    name = names.get(policy, f"policy {policy}")
    realtime = name in ("SCHED_FIFO", "SCHED_RR")
    if realtime:
        return f"{name} priority {os.sched_getparam(0).sched_priority}", True
    return f"{name} nice {os.nice(0)}", False


def machine_load() -> tuple[float, int]:
    """The 1-min load average and the number of CPUs of this machine (NaN where there is no load average)."""
    try:
        load = os.getloadavg()[0]
    except OSError:  # pragma: no cover - not Unix
        load = math.nan
    return float(load), os.cpu_count() or 1


def servo_timing(env: Any) -> ServoTiming | None:
    """The timing of the hole just run by the real env ``env`` (its servo loop's statistics), or None before any.

    The servo process's scheduling is what it got when it started (:attr:`drillgym.envs.real.servo_process.ServoProcess.scheduling`); a servo thread's
    is this process's.
    """
    cell = env.unwrapped
    servo = getattr(cell, "servo", None)
    if servo is None:
        return None
    process = getattr(cell.devices, "process", None)
    if process is not None:
        scheduling, realtime = f"{process.scheduling} (servo process)", bool(process.realtime)
    else:
        what, realtime = this_process_scheduling()
        scheduling = f"{what} (thread of this process, --servo-thread)"
    load, cores = machine_load()
    median, p99, worst = period_stats_s(servo.history_t)
    return ServoTiming(
        cycles=int(servo.stats.cycles),
        missed_cycles=int(servo.stats.missed_cycles),
        period_median_s=median,
        period_p99_s=p99,
        period_max_s=worst,
        scheduling=scheduling,
        realtime=realtime,
        load_1min=load,
        cores=cores,
        servo_call_max_s=float(servo.stats.servo_call_max_s),
    )


def _ms(value_s: float) -> str:
    return f"{value_s * 1e3:.1f} ms" if math.isfinite(value_s) else "n/a"


def describe_timing(timing: ServoTiming) -> str:
    """One console line: cycles, missed cycles, period median / p99 / max, longest servoL call, scheduling, load."""
    return (
        f"servo loop: {timing.cycles} cycles, {timing.missed_cycles} missed; period median "
        f"{_ms(timing.period_median_s)}, p99 {_ms(timing.period_p99_s)}, max {_ms(timing.period_max_s)}; "
        f"longest servoL call {_ms(timing.servo_call_max_s)}; "
        f"{timing.scheduling}; load average {timing.load_1min:.1f} on {timing.cores} cores"
    )


def likely_cause(failure: str | None, timing: ServoTiming) -> str | None:
    """What most likely stopped a hole on a stale stream or the watchdog; None for any other end.

    The rule: a stop in :data:`LOAD_FAULTS` that follows at least one missed cycle, with a 1-min load average at
    or above :data:`BUSY_LOAD_PER_CORE` per core, names the machine's load. Missed cycles on a machine that was
    not saturated on average point at a burst of load or the host (steal time); no missed cycle at all means the
    loop kept its period, so the stream stopped upstream (:data:`UPSTREAM`).
    """
    if failure not in LOAD_FAULTS:
        return None
    missed, load = timing.missed_cycles, f"load average {timing.load_1min:.1f} on {timing.cores} cores"
    cycles = f"{missed} missed cycle{'s' if missed != 1 else ''}"
    if missed == 0:
        return f"{failure} with no missed servo cycle ({load}): the loop kept its period, so not this machine's load; {UPSTREAM[failure]}"
    priority = (
        ""
        if timing.realtime
        else f"; the loop was not real-time ({timing.scheduling}): give the Python binary cap_sys_nice"
    )
    if timing.busy:
        return (
            f"{failure} after {cycles}, {load}: the machine was likely too busy for the 125 Hz servo loop{priority}. "
            "Stop other jobs on this PC, check it with `drillgym bench-rtde`, and drill again"
        )
    return (
        f"{failure} after {cycles}, but {load} (not saturated over the last minute): a short burst of load or the "
        f"host's own preemption (a virtual machine's steal time) is likely{priority}; check with `drillgym bench-rtde`"
    )
