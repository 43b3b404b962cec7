"""Timing of the 125 Hz ``servoL`` stream through the real ``ur_rtde`` client.

The command is :mod:`drillgym.eval.cli.bench_rtde`.

Streams ``servoL`` for ``--seconds`` with ``initPeriod`` / ``waitPeriod`` where the real env's loop runs
(``--loop process``, the default: a servo process of its own at real-time priority where allowed, as the real env
runs it by default, :mod:`drillgym.envs.real.servo_process`; ``--loop thread``: a thread of this process) and reports:

* missed cycles (client side): periods in which no command went out (a late cycle counts the periods it
  skipped; the target is <= 0.1 %), and the cycle-gap distribution;
* command-to-state latency: from the ``servoL`` call to the first RTDE state, read in this process, whose
  ``target_TCP_pose`` shows that command, median and p99. Each command carries its cycle number in the target's
  z, in 1 nm steps (at most 1 µm away from the start pose); the emulator echoes the servo target exactly. A real
  controller reports its interpolated target instead, so there the latency is ``n/a``;
* with the emulator: controller cycles that saw no new command while servoing (robot side);
* the platform floor (unless ``--no-floor``): a bare sleep loop at the same rate, in the same place and at the
  same priority, timed right after the stream for as long under the same load. Its missed periods are what the
  machine itself loses (a 2-vCPU virtual machine loses wake-ups even for a ``SCHED_FIFO`` loop when its other
  vCPU is busy), so the stream's own share is the difference.

``--load-procs N`` starts N busy processes (``python -c "while True: pass"``, ordinary priority) for the run and
ends them afterwards: the load the acceptance test runs under (two on a 2-core machine). The load average
before and after the run is reported, since a shared machine has load of its own.

Without ``--robot`` it starts an emulator on a free loopback address and ends it afterwards.
"""

from __future__ import annotations

import bisect
import contextlib
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from drillgym.envs.real.config import ServoParams
from drillgym.envs.real.netft import NetFTCalibration
from drillgym.envs.real.servo_bench import missed_periods, sleep_floor, stream_coded_targets
from drillgym.envs.real.servo_process import ServoProcess, ServoProcessSpec

POLL_S = 0.0002
"""How often the state is polled for the echo (s)."""
LATENCY_MAX_S = 1.0
"""An echo later than this is not counted as one (s)."""
BUSY_LOOP = "while True: pass"
"""What each ``--load-procs`` process runs."""


def _percentiles_ms(values_s: list[float]) -> dict[str, float | None]:
    if not values_s:
        return {"median_ms": None, "p99_ms": None, "max_ms": None}
    v = np.asarray(values_s) * 1e3
    return {"median_ms": float(np.median(v)), "p99_ms": float(np.percentile(v, 99)), "max_ms": float(v.max())}


class _EchoWatcher(threading.Thread):
    """Polls the receive interface and records ``(time, target z)`` at each new RTDE state."""

    def __init__(self, receive: Any, stop: threading.Event) -> None:
        super().__init__(name="echo-watcher", daemon=True)
        self.receive, self.stop_event = receive, stop
        self.seen: list[tuple[float, float]] = []
        self.state_timestamps: list[float] = []

    def run(self) -> None:
        last_ts = -1.0
        while not self.stop_event.is_set():
            now = time.perf_counter()
            ts = self.receive.getTimestamp()
            if ts != last_ts:
                last_ts = ts
                self.state_timestamps.append(ts)
                self.seen.append((now, self.receive.getTargetTCPPose()[2]))
            time.sleep(POLL_S)


def echo_latencies_s(send_t: list[float], send_z: list[float], seen: list[tuple[float, float]]) -> list[float]:
    """Command-to-state latencies (s), one per command whose echo came within :data:`LATENCY_MAX_S`.

    A command sent at ``send_t`` with target z ``send_z`` is echoed by the first state after it that shows
    exactly that z.
    """
    by_z: dict[float, list[float]] = {}
    for t, z in seen:
        by_z.setdefault(z, []).append(t)
    out = []
    for t, z in zip(send_t, send_z, strict=True):
        times = by_z.get(z, [])
        i = bisect.bisect_left(times, t)
        if i < len(times) and times[i] - t <= LATENCY_MAX_S:
            out.append(times[i] - t)
    return out


@contextlib.contextmanager
def busy_processes(n: int) -> Iterator[list[int]]:
    """``n`` busy Python processes for the duration (ended by their pids afterwards); yields the pids."""
    procs = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(n)]
    try:
        yield [p.pid for p in procs]
    finally:
        for p in procs:
            p.kill()
            p.wait(timeout=5.0)


def _stream_in_thread(
    host: str, pose0: list[float], seconds: float, period: float, floor: bool = False
) -> tuple[dict[str, Any], str]:
    import rtde_control

    control = rtde_control.RTDEControlInterface(host, 125.0)
    try:
        result = stream_coded_targets(control, pose0, seconds, period)
    finally:
        control.stopScript()
        control.disconnect()
    if floor:
        result["floor"] = sleep_floor(seconds, period)  # where the stream ran: this thread
    return result, "thread of the benchmark's process"


def _stream_in_process(
    host: str, pose0: list[float], seconds: float, period: float, floor: bool = False
) -> tuple[dict[str, Any], str]:

    proc = ServoProcess(ServoProcessSpec(host, ServoParams(), False, None, None, NetFTCalibration()))
    try:
        result = proc.call("bench", "stream", pose0, seconds, period, timeout_s=seconds + 30.0)
        proc.call("link", "stop_script")
        if floor:
            result["floor"] = proc.call("bench", "floor", seconds, period, timeout_s=seconds + 30.0)
        return result, f"servo process ({proc.scheduling})"
    finally:
        proc.close()


def bench(host: str, seconds: float, loop: str = "process", floor: bool = False) -> dict[str, Any]:
    """Stream for ``seconds`` against ``host`` from ``loop`` (``process`` or ``thread``); the timing figures.

    ``floor``: then, in the same place and under the same load, time a bare sleep loop at the same rate for as
    long (:func:`drillgym.envs.real.servo_bench.sleep_floor`): what the machine itself loses.
    """
    import rtde_receive

    receive = rtde_receive.RTDEReceiveInterface(host, 125.0, ["timestamp", "actual_TCP_pose", "target_TCP_pose"])
    period = 1.0 / 125.0
    pose0 = list(receive.getActualTCPPose())
    stop = threading.Event()
    watcher = _EchoWatcher(receive, stop)
    stream = _stream_in_process if loop == "process" else _stream_in_thread
    try:
        watcher.start()
        sent, where = stream(host, pose0, seconds, period, floor)
    finally:
        stop.set()
        watcher.join(timeout=1.0)
        receive.disconnect()
    send_t, n_cycles = sent["send_t"], sent["cycles"]
    gaps = np.diff(send_t).tolist()
    missed = missed_periods(send_t, period)
    late_at = [round(send_t[i + 1] - send_t[0], 3) for i, g in enumerate(gaps) if g > 1.5 * period]
    latencies = echo_latencies_s(send_t, sent["send_z"], watcher.seen)
    ts = np.diff(watcher.state_timestamps)
    result: dict[str, Any] = {
        "seconds": seconds,
        "loop": where,
        "cycles": n_cycles,
        "missed_cycles": int(missed),
        "missed_cycle_rate": missed / (n_cycles + missed),
        "cycle_gap": _percentiles_ms(gaps),
        "servo_call": _percentiles_ms(sent["call_s"]),
        "late_cycles_at_s": late_at[:20],
        "latency_samples": len(latencies),
        "command_to_state_latency": _percentiles_ms(latencies),
        "state_packages_missed": int(np.sum(np.maximum(np.round(ts / period) - 1, 0))) if ts.size else 0,
    }
    if "floor" in sent:
        wake = sent["floor"]["send_t"]
        floor_missed = missed_periods(wake, period)
        result["floor_missed_cycles"] = floor_missed
        result["floor_missed_cycle_rate"] = floor_missed / (sent["floor"]["cycles"] + floor_missed)
        result["floor_cycle_gap"] = _percentiles_ms(np.diff(wake).tolist())
    return result
