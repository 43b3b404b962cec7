"""``drillgym bench-rtde``: timing of the 125 Hz ``servoL`` stream through the real ``ur_rtde`` client.

Streams ``servoL`` for ``--seconds`` with ``initPeriod`` / ``waitPeriod`` (as the real env does) and reports:

* missed cycles (client side): periods in which no command went out (a late cycle counts the periods it
  skipped; the target is <= 1 %), and the cycle-gap distribution;
* command-to-state latency: from the ``servoL`` call to the first RTDE state whose ``target_TCP_pose`` shows
  that command, median and p99. Each command carries its cycle number in the target's z, in 1 nm steps
  (at most 1 µm away from the start pose); the emulator echoes the servo target exactly. A real controller
  reports its interpolated target instead, so there the latency is ``n/a``;
* with the emulator: controller cycles that saw no new command while servoing (robot side).

Without ``--robot`` it starts an emulator on a free loopback address and ends it afterwards.
"""

from __future__ import annotations

import argparse
import json
import math
import threading
import time
from typing import Any

import numpy as np

CODE_STEP_M = 1e-9
"""Target z step per cycle number (m)."""
CODE_MODULUS = 1000
"""Cycle numbers repeat every this many cycles (8 s at 125 Hz)."""
POLL_S = 0.0002
"""How often the state is polled for the echo (s)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench-rtde``."""
    parser.add_argument("--robot", default=None, help="controller address (default: start an emulator)")
    parser.add_argument("--seconds", type=float, default=60.0, help="streaming time (s)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--yes", action="store_true", help="confirm streaming to a real robot (--robot)")


def _percentiles_ms(values_s: list[float]) -> dict[str, float | None]:
    if not values_s:
        return {"median_ms": None, "p99_ms": None, "max_ms": None}
    v = np.asarray(values_s) * 1e3
    return {"median_ms": float(np.median(v)), "p99_ms": float(np.percentile(v, 99)), "max_ms": float(v.max())}


class _EchoWatcher(threading.Thread):
    """Polls the receive interface and times when each command's code first shows in ``target_TCP_pose``."""

    def __init__(self, receive: Any, z0: float, sent: dict[int, tuple[float, float]], stop: threading.Event) -> None:
        super().__init__(name="echo-watcher", daemon=True)
        self.receive, self.z0, self.sent, self.stop_event = receive, z0, sent, stop
        self.latencies_s: list[float] = []
        self.state_timestamps: list[float] = []

    def run(self) -> None:
        last_code, last_ts = -1, -1.0
        while not self.stop_event.is_set():
            now = time.perf_counter()
            ts = self.receive.getTimestamp()
            if ts != last_ts:
                last_ts = ts
                self.state_timestamps.append(ts)
                z = self.receive.getTargetTCPPose()[2]
                code = round((z - self.z0) / CODE_STEP_M)
                if code != last_code and code in self.sent and self.sent[code][1] == z:  # exactly what was sent
                    last_code = code
                    self.latencies_s.append(now - self.sent.pop(code)[0])
            time.sleep(POLL_S)


def bench(host: str, seconds: float) -> dict[str, Any]:
    """Stream for ``seconds`` against ``host``; returns the timing figures."""
    import rtde_control
    import rtde_receive

    receive = rtde_receive.RTDEReceiveInterface(host, 125.0, ["timestamp", "actual_TCP_pose", "target_TCP_pose"])
    control = rtde_control.RTDEControlInterface(host, 125.0)
    period = 1.0 / 125.0
    n_cycles = max(int(seconds / period), 1)
    pose0 = list(receive.getActualTCPPose())
    sent: dict[int, tuple[float, float]] = {}
    stop = threading.Event()
    watcher = _EchoWatcher(receive, pose0[2], sent, stop)
    gaps, last = [], None
    try:
        watcher.start()
        for k in range(n_cycles):
            t_cycle = control.initPeriod()
            code = k % CODE_MODULUS
            pose = list(pose0)
            pose[2] = pose0[2] + code * CODE_STEP_M
            now = time.perf_counter()
            if last is not None:
                gaps.append(now - last)
            last = now
            sent[code] = (now, pose[2])
            if not control.servoL(pose, 0.25, 1.2, period, 0.1, 300.0):
                raise RuntimeError(f"servoL refused at cycle {k}")
            control.waitPeriod(t_cycle)
    finally:
        stop.set()
        watcher.join(timeout=1.0)
        control.servoStop(10.0)
        control.stopScript()
        control.disconnect()
        receive.disconnect()
    missed = sum(round(g / period) - 1 for g in gaps if g > 1.5 * period)
    ts = np.diff(watcher.state_timestamps)
    return {
        "seconds": seconds,
        "cycles": n_cycles,
        "missed_cycles": int(missed),
        "missed_cycle_rate": missed / (n_cycles + missed),
        "cycle_gap": _percentiles_ms(gaps),
        "latency_samples": len(watcher.latencies_s),
        "command_to_state_latency": _percentiles_ms(watcher.latencies_s),
        "state_packages_missed": int(np.sum(np.maximum(np.round(ts / period) - 1, 0))) if ts.size else 0,
    }


def run(args: argparse.Namespace) -> int:
    """Run the benchmark (on an emulator unless ``--robot``)."""
    from drillgym.envs.real.emulator.process import EmulatorProcess

    if args.robot and not args.yes:
        print("bench-rtde streams servoL to a real robot (within 1 µm of its pose): pass --yes to confirm")
        return 2
    if not args.seconds > 0:
        raise ValueError(f"--seconds={args.seconds:g} must be > 0")
    emulator = None if args.robot else EmulatorProcess(max_lifetime_s=args.seconds + 120).start()
    host = args.robot or emulator.host  # type: ignore[union-attr]
    try:
        result = bench(host, args.seconds)
        if emulator is not None:
            st = emulator.status()
            result["emulator_servo_updates"] = st["servo_updates"]
            result["emulator_ticks_without_update"] = st["servo_ticks_without_update"]
            result["emulator_late_ticks"] = st["late_ticks"]
    finally:
        if emulator is not None:
            emulator.stop()
    result["target"] = "emulator" if emulator is not None else host
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    lat, gap = result["command_to_state_latency"], result["cycle_gap"]
    print(f"bench-rtde against {result['target']}: {result['cycles']} cycles at 125 Hz over {args.seconds:g} s")
    print(
        f"  missed cycles        {result['missed_cycles']} ({100 * result['missed_cycle_rate']:.3f} %; target <= 1 %)"
    )
    print(f"  cycle gap            median {_ms(gap['median_ms'])}, p99 {_ms(gap['p99_ms'])}, max {_ms(gap['max_ms'])}")
    print(
        f"  command-to-state     median {_ms(lat['median_ms'])}, p99 {_ms(lat['p99_ms'])}, "
        f"max {_ms(lat['max_ms'])} ({result['latency_samples']} samples)"
    )
    if "emulator_servo_updates" in result:
        print(
            f"  controller side      {result['emulator_servo_updates']} servo updates, "
            f"{result['emulator_ticks_without_update']} cycles without a new command"
        )
    return 0


def _ms(value: float | None) -> str:
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.2f} ms"
