"""``drillgym run``: run a controller on the real cell (or the emulator) and log it like a simulated run.

Asks for confirmation before anything moves (unless ``--yes``; ``--dry-run`` moves nothing and sends nothing),
writes each episode's log incrementally (``<out>/logs/*.parquet``, the sim's schema with ``source: "real"``),
and prints the metrics a real cell can measure (forces, drilling time, tracker deviation; the true tip
deviation and the entry-hole offset need the specimen measured). A dry run also prints how far the commanded
targets went from the entry point, the plan's reach and its worst case under the correction limit, and writes them
to ``<out>/dry_run.json`` (:mod:`drillgym.eval.real.dry_run`).
Exit codes: 0 done, 1 could not connect or start, 2 bad arguments or not confirmed, 3 an episode ended on a fault.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym

from drillgym.controllers.rollout import run_episode
from drillgym.envs.json_safe import json_safe
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.emulator.cli import parse_scenario
from drillgym.envs.real.metrics import OBSERVABLE_METRICS
from drillgym.envs.real.netft import NetFTCalibration
from drillgym.eval.real.preflight import ENV_ID, ft_calibration, seed_emulated_specimen


def _limits(max_gap_ms: float) -> SafetyLimits:
    """Default safety limits with the three stream-timing limits set to ``max_gap_ms``."""
    gap_s = max_gap_ms * 1e-3
    return SafetyLimits(max_cycle_gap_s=gap_s, rtde_stale_s=gap_s, ft_stale_s=gap_s)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``run``."""
    parser.add_argument("--robot", required=True, help="UR controller address")
    parser.add_argument(
        "--ft", default=None, help="Net F/T HOST[:PORT] (default: the robot's address, as the emulator)"
    )
    parser.add_argument("--tracker", default="none", help="'none' or 'udp:HOST[:PORT]' (the emulator's marker stream)")
    parser.add_argument("--controller", default="li2023", help="controller spec: li2023[:k=v,...], residual:PATH, ...")
    parser.add_argument("--scenario", default=None, help="the plan: env arguments as JSON or key=value,...")
    parser.add_argument("--episodes", type=int, default=1, help="holes to drill, one after the other")
    parser.add_argument("--seed", type=int, default=0, help="reset seed of the first episode (logged)")
    parser.add_argument(
        "--counts-per-force",
        type=float,
        default=None,
        help="the F/T sensor's counts per N. By default read from the sensor (TCP 49151, READCALINFO); given, "
        "it must match what the sensor reports, or the run is refused: a wrong value rescales every force, the "
        f"force limit included. Without an answer from the sensor: {NetFTCalibration.counts_per_force:g}",
    )
    parser.add_argument(
        "--counts-per-torque",
        type=float,
        default=None,
        help=f"counts per N·m, read and checked likewise (without an answer: {NetFTCalibration.counts_per_torque:g})",
    )
    parser.add_argument(
        "--max-gap-ms",
        type=float,
        default=SafetyLimits.max_cycle_gap_s * 1e3,
        help="longest pause tolerated in the servo stream, the RTDE state and the F/T stream before a stop (ms; "
        "the robot's own RTDE watchdog stops at twice this)",
    )
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="connect and stream nothing: log what would be sent (commands.jsonl) and say how far the "
        "targets go from the entry point (dry_run.json)",
    )
    parser.add_argument("--yes", action="store_true", help="do not ask before moving the robot")
    parser.add_argument(
        "--servo-thread",
        action="store_true",
        help="run the 125 Hz servo loop as a thread of this process instead of a process of its own at real-time "
        "priority (the default; a thread starves under load: docs/deployment.md)",
    )
    parser.add_argument(
        "--record-rtde",
        action="store_true",
        help="also write each episode as a recording session for `drillgym import-rtde` (<out>/rtde/<log name>/: "
        "ur_rtde's own file recording of the robot state, on a receive interface of its own, and the F/T, "
        "tracker, commands and header files from the log)",
    )
    parser.add_argument("--out", type=Path, required=True, help="output folder (logs, metrics.json, commands.jsonl)")


def _confirm(args: argparse.Namespace, scenario_text: str) -> bool:
    if args.dry_run or args.yes:
        return True
    print(f"About to MOVE the robot at {args.robot}: {args.controller} drilling {scenario_text}.")
    print("Check: workspace clear, specimen clamped, E-stop at hand, spindle on, F/T and tracker reading.")
    if not sys.stdin.isatty():
        print("stdin is not a terminal: cannot ask; pass --yes to confirm", file=sys.stderr)
        return False
    return input("Type 'yes' to start: ").strip().lower() == "yes"


def _given_calibration(args: argparse.Namespace) -> NetFTCalibration | None:
    """The calibration given on the command line (None: read it from the sensor)."""
    if args.counts_per_force is None and args.counts_per_torque is None:
        return None
    default = NetFTCalibration()
    return NetFTCalibration(
        default.counts_per_force if args.counts_per_force is None else args.counts_per_force,
        default.counts_per_torque if args.counts_per_torque is None else args.counts_per_torque,
    )


def _print_metrics(metrics: dict[str, float]) -> None:
    for name in OBSERVABLE_METRICS:
        value = metrics.get(name, math.nan)
        print(f"  {name:28s} {value:9.3f}" if math.isfinite(value) else f"  {name:28s}       n/a")
    print("  deviation_*_mm, hole_offset_mm: measure the hole on the specimen (no true tip on a real cell)")


def run(args: argparse.Namespace) -> int:
    """Connect, confirm, drill ``--episodes`` holes, print and save the metrics."""
    from drillgym.controllers import make_controller
    from drillgym.eval.logs import EpisodeLogger, build_header

    try:
        scenario = parse_scenario(args.scenario).to_dict()
        controller = make_controller(args.controller)
        given = _given_calibration(args)
        limits = _limits(args.max_gap_ms)
    except (ValueError, TypeError) as e:
        print(f"drillgym run: error: {e}", file=sys.stderr)
        return 2
    if not _confirm(args, args.scenario or "the default plan"):
        print("not confirmed; nothing moved")
        return 2
    scenario.pop("tracker", None)
    calibration, calibration_source = ft_calibration(args.ft or args.robot, given)
    print(
        f"F/T calibration ({calibration_source}): {calibration.counts_per_force:g} counts/N, "
        f"{calibration.counts_per_torque:g} counts/N-m"
    )
    created = not args.out.exists()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.dry_run:
        print(
            "DRY RUN: nothing is sent to the robot. The episode follows the commanded path with the robot at rest; "
            f"{args.out / 'commands.jsonl'} logs every command that would have been sent. Forces and metrics "
            "below describe a robot that did not move, and the servo loop's timing (missed_cycles in metrics.json) "
            "times a loop that sends nothing."
        )
    try:
        env = gym.make(
            ENV_ID,
            robot_host=args.robot,
            ft_sensor=args.ft,
            tracker=args.tracker,
            ft_calibration=calibration,
            dry_run=args.dry_run,
            command_log_path=str(args.out / "commands.jsonl"),
            safety_limits=limits,
            servo_process=not args.servo_thread,
            **scenario,
        )
    except (RuntimeError, OSError, ValueError) as e:
        if created:  # leave no empty output folder behind
            shutil.rmtree(args.out, ignore_errors=True)
        print(f"drillgym run: error: cannot open the cell: {e}", file=sys.stderr)
        return 2
    results, code = [], 0
    try:
        for k in range(args.episodes):
            seed = args.seed + k
            name = f"real__{args.controller.replace(':', '_').replace('/', '_')}__ep{k}.parquet"
            extra = {"controller_spec": args.controller, "robot": args.robot, "dry_run": args.dry_run}
            extra["ft_calibration"] = {
                "counts_per_force": calibration.counts_per_force,
                "counts_per_torque": calibration.counts_per_torque,
                "source": calibration_source,
            }
            specimen = seed_emulated_specimen(args.robot, seed)
            if specimen is not None:
                extra["emulator_specimen"] = specimen
            header = build_header(env, controller.describe(), seed, source="real", extra=extra)
            logger = EpisodeLogger(env, args.out / "logs" / name, header, overwrite=True)
            try:
                with _rtde_session(args, env, args.out / "logs" / name, extra):
                    try:
                        info = run_episode(logger, controller, seed, keep_trace=False).info
                    finally:
                        logger.close_log()
            except RuntimeError as e:  # refused to start (safety bits, too far from the start pose, ...)
                print(f"episode {k}: could not start: {e}", file=sys.stderr)
                code = 1
                break
            metrics = dict(info.get("metrics") or {})
            results.append(
                {
                    "episode": k,
                    "seed": seed,
                    "log": f"logs/{name}",
                    "failure": info.get("failure"),
                    "error": info.get("error"),
                    "metrics": metrics,
                    "missed_cycles": info.get("missed_cycles"),
                }
            )
            dry = " DRY RUN, nothing sent;" if args.dry_run else ""
            print(f"episode {k} ({args.controller},{dry} log {args.out / 'logs' / name}):")
            if info.get("failure"):
                print(f"  ENDED ON A FAULT: {info['failure']}: {info['error']}; stop: {info.get('stop_result')}")
                code = 3
            _print_metrics(metrics)
            if code:
                break
    except KeyboardInterrupt:
        print("interrupted: stopping the robot", file=sys.stderr)
        code = 3
    finally:
        env.close()
        (args.out / "metrics.json").write_text(json.dumps(json_safe(results), indent=2))
    _summarise_dry_run(env, args)
    print(f"results in {args.out.resolve()}")
    return code


@contextlib.contextmanager
def _rtde_session(args: argparse.Namespace, env: gym.Env[Any, Any], log: Path, run: dict[str, Any]) -> Iterator[None]:
    """With ``--record-rtde``: record the episode run inside as a session for ``drillgym import-rtde``.

    ``ur_rtde``'s file recording of the robot state (a receive interface of its own) goes to
    ``<out>/rtde/<log name>/rtde.csv``; once the episode's log is closed, the recording is cut to the episode
    ± 0.5 s (whole lines, as the shipped session's generator does: the robot's approach before t0 is no part of
    the episode, and a busy start-up there can leave gaps the importer rightly refuses), and the F/T, tracker,
    commands and header files are written from the log, with the episode's t0 put on the RTDE clock.
    """
    if not args.record_rtde:
        yield
        return
    from drillgym.eval.logs import read_episode_log
    from drillgym.eval.real.record_session import RECORDING_MARGIN_S, RtdeFileRecorder, trim_recording, write_side_files

    session = args.out / "rtde" / log.stem
    session.mkdir(parents=True, exist_ok=True)
    recorder = RtdeFileRecorder(args.robot, session / "rtde.csv")
    try:
        yield
    finally:
        recorder.stop()
    header, frame = read_episode_log(log, allow_partial=True)
    t0 = env.unwrapped.streams.t0  # type: ignore[attr-defined]
    rtde_t0 = recorder.rtde_timestamp_at(t0)
    end_s = float(frame["t_s"].max()) if len(frame) else 0.0
    trim_recording(session / "rtde.csv", rtde_t0 - RECORDING_MARGIN_S, rtde_t0 + end_s + RECORDING_MARGIN_S)
    run = {**run, "rtde_clock_offset_s": round(recorder.offset_s, 6)}
    write_side_files(session, header, frame, rtde_t0, run)
    print(f"recording session for drillgym import-rtde: {session}")


def _summarise_dry_run(env: gym.Env[Any, Any], args: argparse.Namespace) -> None:
    """A dry run: print how far the commanded targets went from the entry point, write ``<out>/dry_run.json``."""
    from drillgym.eval.real.dry_run import describe_reach, target_reach

    if not args.dry_run:
        return
    cell, out = env.unwrapped, args.out
    commands = out / "commands.jsonl"
    try:
        reach = target_reach(commands, cell.T_base_task, cell.scenario.depth_m, cell.limits)  # type: ignore[attr-defined]
    except (OSError, ValueError) as e:
        print(f"DRY RUN: no reach summary: {e}", file=sys.stderr)
        return
    print(describe_reach(reach, commands))
    (out / "dry_run.json").write_text(json.dumps(reach, indent=2))
