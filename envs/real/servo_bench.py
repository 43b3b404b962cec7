"""The stream ``drillgym bench-rtde`` times: ``servoL`` at 125 Hz to a pose whose z carries the cycle number.

Runs wherever the servo loop runs (a thread of the caller, or the servo process,
:mod:`drillgym.envs.real.servo_process`) with ``initPeriod`` / ``waitPeriod`` as the real env's loop does, and
records when each command went out (``time.perf_counter()``, s: CLOCK_MONOTONIC, the same in every process), so
the caller can match them to the states that echo them.
"""

from __future__ import annotations

import itertools
import time
from typing import Any

CODE_STEP_M = 1e-9
"""Target z step per cycle number (m)."""
CODE_MODULUS = 1000
"""Cycle numbers repeat every this many cycles (8 s at 125 Hz)."""


def coded_z(z0_m: float, cycle: int) -> float:
    """The target z of ``cycle`` (m): ``z0_m`` plus the cycle number modulo 1000, in 1 nm steps."""
    return z0_m + (cycle % CODE_MODULUS) * CODE_STEP_M


def missed_periods(send_t: list[float], period_s: float) -> int:
    """Periods in which nothing went out: each gap longer than 1.5 periods counts the periods it skipped."""
    return sum(round((b - a) / period_s) - 1 for a, b in itertools.pairwise(send_t) if b - a > 1.5 * period_s)


def sleep_floor(seconds: float, period_s: float) -> dict[str, Any]:
    """The platform's floor for a periodic loop: wake every ``period_s`` for ``seconds`` with nothing else to do.

    Run where the servo loop runs (same process, same priority), right after it and under the same load, its
    missed periods are what the machine itself loses (scheduler, hypervisor), however light the loop. Returns
    ``send_t`` (each wake-up, s) and ``cycles``.
    """
    n_cycles = max(int(seconds / period_s), 1)
    wake_t: list[float] = []
    for _ in range(n_cycles):
        wake_t.append(time.perf_counter())
        t_next = wake_t[-1] + period_s  # each cycle from its own start, as the servo loop's init/waitPeriod
        rest = t_next - time.perf_counter()
        if rest > 0:
            time.sleep(rest)
    return {"send_t": wake_t, "cycles": n_cycles}


def stream_coded_targets(control: Any, pose0: list[float], seconds: float, period_s: float) -> dict[str, Any]:
    """``servoL`` to ``pose0`` (m, rad; base frame) with a coded z for ``seconds``, then ``servoStop``.

    ``control``: a ``ur_rtde`` ``RTDEControlInterface``. Returns ``send_t`` (when each command was sent, s),
    ``send_z`` (its target z, m), ``call_s`` (how long each ``servoL`` call took, s) and ``cycles``; raises ``RuntimeError`` if the controller refuses a command.
    """
    n_cycles = max(int(seconds / period_s), 1)
    send_t: list[float] = []
    send_z: list[float] = []
    call_s: list[float] = []
    try:
        for k in range(n_cycles):
            t_cycle = control.initPeriod()
            pose = list(pose0)
            pose[2] = coded_z(pose0[2], k)
            send_t.append(time.perf_counter())
            send_z.append(pose[2])
            ok = control.servoL(pose, 0.25, 1.2, period_s, 0.1, 300.0)
            call_s.append(time.perf_counter() - send_t[-1])
            if not ok:
                raise RuntimeError(f"servoL refused at cycle {k}")
            control.waitPeriod(t_cycle)
    finally:
        control.servoStop(10.0)
    return {"send_t": send_t, "send_z": send_z, "call_s": call_s, "cycles": n_cycles}
