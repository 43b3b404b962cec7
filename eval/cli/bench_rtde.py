"""``drillgym bench-rtde``: timing of the 125 Hz servoL stream through ur_rtde (:mod:`drillgym.eval.perf.rtde`)."""

from __future__ import annotations

import argparse
import json
import math
import os

from drillgym.envs.errors import UserError
from drillgym.eval.perf.rtde import bench, busy_processes


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench-rtde``."""
    parser.add_argument("--robot", default=None, help="controller address (default: start an emulator)")
    parser.add_argument("--seconds", type=float, default=60.0, help="streaming time (s)")
    parser.add_argument(
        "--loop",
        choices=("process", "thread"),
        default="process",
        help="where the stream runs: a servo process of its own (as the real env by default), or a thread of this "
        "process (as drillgym run --servo-thread)",
    )
    parser.add_argument(
        "--load-procs", type=int, default=0, help="busy processes to run alongside (load generator; default none)"
    )
    parser.add_argument(
        "--no-floor",
        action="store_true",
        help="skip the platform floor (a bare sleep loop at the same rate and priority, timed after the stream for "
        "as long; it doubles the run time)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--yes", action="store_true", help="confirm streaming to a real robot (--robot)")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark (on an emulator unless ``--robot``)."""
    from drillgym.envs.real.emulator.process import EmulatorProcess

    if args.robot and not args.yes:
        print("bench-rtde streams servoL to a real robot (within 1 µm of its pose): pass --yes to confirm")
        return 2
    if not args.seconds > 0:
        raise UserError(f"--seconds={args.seconds:g} must be > 0")
    if args.load_procs < 0:
        raise UserError(f"--load-procs={args.load_procs} must be >= 0")
    emulator = None if args.robot else EmulatorProcess(max_lifetime_s=args.seconds + 120).start()
    host = args.robot or emulator.host  # type: ignore[union-attr]
    load_before = os.getloadavg()
    try:
        with busy_processes(args.load_procs):
            result = bench(host, args.seconds, args.loop, floor=not args.no_floor)
            load_after = os.getloadavg()
        if emulator is not None:
            st = emulator.status()
            result["emulator_servo_updates"] = st["servo_updates"]
            result["emulator_ticks_without_update"] = st["servo_ticks_without_update"]
            result["emulator_late_ticks"] = st["late_ticks"]
    finally:
        if emulator is not None:
            emulator.stop()
    result["target"] = "emulator" if emulator is not None else host
    result["load_procs"] = args.load_procs
    result["cpu_count"] = os.cpu_count()
    result["loadavg_before"] = [round(v, 2) for v in load_before]
    result["loadavg_after"] = [round(v, 2) for v in load_after]
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    lat, gap = result["command_to_state_latency"], result["cycle_gap"]
    print(f"bench-rtde against {result['target']}: {result['cycles']} cycles at 125 Hz over {args.seconds:g} s")
    print(f"  loop                 {result['loop']}")
    print(
        f"  load                 {args.load_procs} busy processes; load average (1 min) "
        f"{load_before[0]:.2f} before, {load_after[0]:.2f} at the end, {result['cpu_count']} CPUs"
    )
    print(
        f"  missed cycles        {result['missed_cycles']} ({100 * result['missed_cycle_rate']:.3f} %; target <= 0.1 %)"
    )
    print(f"  cycle gap            median {_ms(gap['median_ms'])}, p99 {_ms(gap['p99_ms'])}, max {_ms(gap['max_ms'])}")
    call = result["servo_call"]
    print(
        f"  servoL call          median {_ms(call['median_ms'])}, p99 {_ms(call['p99_ms'])}, max {_ms(call['max_ms'])}"
    )
    if result["late_cycles_at_s"]:
        print(f"  late cycles at       {', '.join(f'{t:g}' for t in result['late_cycles_at_s'])} s (first 20)")
    print(
        f"  command-to-state     median {_ms(lat['median_ms'])}, p99 {_ms(lat['p99_ms'])}, "
        f"max {_ms(lat['max_ms'])} ({result['latency_samples']} samples)"
    )
    if "floor_missed_cycles" in result:
        fgap = result["floor_cycle_gap"]
        print(
            f"  platform floor       {result['floor_missed_cycles']} missed "
            f"({100 * result['floor_missed_cycle_rate']:.3f} %) by a bare sleep loop at the same rate and priority, "
            f"right after, under the same load; its gap p99 {_ms(fgap['p99_ms'])}, max {_ms(fgap['max_ms'])}"
        )
    if "emulator_servo_updates" in result:
        print(
            f"  controller side      {result['emulator_servo_updates']} servo updates, "
            f"{result['emulator_ticks_without_update']} cycles without a new command"
        )
    return 0


def _ms(value: float | None) -> str:
    return "n/a" if value is None or not math.isfinite(value) else f"{value:.2f} ms"
