"""``drillgym run``: run a controller on the real cell (or the emulator) and log it like a simulated run.

What it drills: one hole (``--episodes N``: N holes at the same entry point, one after the other, for the emulator,
which puts a fresh specimen in after each), or the holes of a plan file (``--plan FILE``, one entry point per hole,
:mod:`drillgym.eval.real.plan_file`), each with an env of its own: connected, reset at its entry point, drilled and
closed before the next hole. It asks before anything moves: once for a single-hole run (unless ``--yes``), before
each hole of a plan (unless ``--yes-all``); ``--dry-run`` moves nothing and sends nothing.

What it writes: each hole's log incrementally (``<out>/logs/*.parquet``, the sim's schema with ``source: "real"``),
the commands sent (``<out>/commands.jsonl``; for a plan ``<out>/commands/<hole>.jsonl``), the metrics of every hole
(``<out>/metrics.json``) and a plan's holes as checked (``<out>/plan.json``). A run's record is append-only: an
``--out`` that holds one (:data:`RECORD_FILES`, :data:`RECORD_FOLDERS`) is refused before anything is read or
moved, as ``bench`` and ``train`` refuse theirs, and there is no ``--overwrite``.

What it prints at the end of every hole: the metrics a real cell can measure (forces, drilling time, tracker
deviation; the true tip deviation and the entry-hole offset need the specimen measured), and how the servo loop kept
time against the machine's load, naming the load as the likely cause of a stale-stream or watchdog stop that followed
missed cycles (:mod:`drillgym.eval.real.load_report`). A dry run also prints how far the commanded targets went from
the entry point, the plan's reach and its worst case under the correction limit, and writes them to
``<out>/dry_run.json`` (``<out>/dry_run/<hole>.json`` for a plan; :mod:`drillgym.eval.real.dry_run`).
Exit codes: 0 done, 1 could not connect or start (after a plan's first hole), 2 bad arguments, not confirmed, or the
cell could not be opened for the first hole, 3 an episode ended on a fault.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drillgym.envs.cell_params import CellParams
from drillgym.envs.errors import UserError
from drillgym.envs.json_safe import json_safe
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.emulator.cli import parse_scenario
from drillgym.envs.real.netft import NetFTCalibration
from drillgym.eval.cli.bench import previous_run
from drillgym.eval.real.hole import CellOptions, drill_hole, open_cell, summarise_dry_run, write_metrics
from drillgym.eval.real.plan_file import DrillingPlan, PlannedHole, far_transits, load_plan
from drillgym.eval.real.preflight import ft_calibration

RECORD_FILES = ("metrics.json", "commands.jsonl", "dry_run.json", "plan.json")
"""What a run writes at the top of its ``--out``: any of them there means a previous run's record."""
RECORD_FOLDERS = (("logs", "*"), ("commands", "*"), ("dry_run", "*"), ("rtde", "*"))
"""A run's sub-folders, anything in them a previous run's record: episode logs (whole or in parts, as a crash
leaves them), a plan's command logs and dry-run reaches, ``--record-rtde`` sessions."""


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
    parser.add_argument(
        "--plan",
        type=Path,
        default=None,
        help="a plan file (YAML, or JSON): one entry point per hole (mm, UR base frame), drilled in order, each with "
        "its own log; asks before each hole. Holds the scenario: not with --scenario, --episodes or --yes "
        "(docs/deployment.md, 'Several holes')",
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=1,
        help="holes to drill one after the other at the same entry point (the emulator puts a fresh specimen in "
        "after each; on a real cell drill several holes with --plan)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="reset seed of the first episode (logged); a plan's holes count on from it"
    )
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
    parser.add_argument("--yes", action="store_true", help="do not ask before moving the robot (single-hole runs)")
    parser.add_argument(
        "--yes-all",
        action="store_true",
        help="with --plan: drill every hole without asking before each (consecutive entry points must then be "
        "within the 50 mm a reset moves)",
    )
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
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        help="output folder (logs, metrics.json, commands); one that holds a previous run's record is refused",
    )


def _check_options(args: argparse.Namespace) -> None:
    """Refuse options that do not go together (``ValueError``)."""
    if args.plan is None:
        if args.yes_all:
            raise UserError("--yes-all is for --plan (every hole without asking); a single-hole run takes --yes")
        return
    if args.scenario is not None:
        raise UserError("--plan FILE holds the scenario (its 'scenario' key, and each hole's); drop --scenario")
    if args.episodes != 1:
        raise UserError("--plan drills each of its holes once; drop --episodes")
    if args.yes:
        raise UserError(
            "--yes confirms a single-hole run; with --plan the run asks before each hole, or --yes-all drills every "
            "hole without asking"
        )


def _refuse_previous_record(out: Path) -> None:
    """A run's record is append-only: refuse an ``--out`` that holds one (``ValueError`` naming what is there)."""
    found = previous_run(out, RECORD_FILES, RECORD_FOLDERS)
    if found:
        raise UserError(
            f"{out} holds a previous run's record ({', '.join(found)}): a run's record is never overwritten or "
            "added to; pass another --out"
        )


def _refuse_far_transits(plan: DrillingPlan, limits: SafetyLimits) -> None:
    """With ``--yes-all``: every next entry point within the distance a reset moves (else it would stop mid-plan)."""
    far = far_transits(plan.holes, limits.reset_max_distance_m)
    if far:
        a, b, distance_m = far[0]
        raise UserError(
            f"{plan.path}: {b.label} is {distance_m * 1e3:.0f} mm from {a.label}, farther than the "
            f"{limits.reset_max_distance_m * 1e3:.0f} mm a reset moves the robot: drop --yes-all and jog the robot "
            "over when the run asks before that hole"
        )


def _confirm(args: argparse.Namespace, scenario_text: str) -> bool:
    if args.dry_run or args.yes:
        return True
    print(f"About to MOVE the robot at {args.robot}: {args.controller} drilling {scenario_text}.")
    print("Check: workspace clear, specimen clamped, E-stop at hand, spindle on, F/T and tracker reading.")
    if not sys.stdin.isatty():
        print("stdin is not a terminal: cannot ask; pass --yes to confirm", file=sys.stderr)
        return False
    return input("Type 'yes' to start: ").strip().lower() == "yes"


def _confirm_hole(args: argparse.Namespace, hole: PlannedHole, count: int, previous: PlannedHole | None) -> bool:
    """Ask before one hole of a plan (what moves where, what to check); whether the answer was ``yes``."""
    limits = _limits(args.max_gap_ms)
    print(f"About to MOVE the robot at {args.robot}: {hole.label} of {count}, {args.controller}: {hole.describe()}.")
    where = "3 mm above this entry point, on the drill axis"
    if previous is None:
        print(f"It moves in a straight line from where it stands to {where}.")
    else:
        distance_m = math.dist(previous.entry_base_m, hole.entry_base_m)
        print(
            f"It moves in a straight line from 3 mm above {previous.label}'s entry point to {where}, "
            f"{distance_m * 1e3:.1f} mm away: check that this line clears the bone, or jog the robot over first."
        )
    print(
        f"A reset moves at most {limits.reset_max_distance_m * 1e3:.0f} mm (else it refuses: jog closer). Check: "
        "workspace clear, specimen clamped, E-stop at hand, spindle on, F/T and tracker reading."
    )
    try:
        answer = input(f"Type 'yes' to drill {hole.label} (anything else stops the plan here): ")
    except EOFError:  # stdin closed: no answer is no
        return False
    return answer.strip().lower() == "yes"


def _given_calibration(args: argparse.Namespace) -> NetFTCalibration | None:
    """The calibration given on the command line (None: read it from the sensor)."""
    if args.counts_per_force is None and args.counts_per_torque is None:
        return None
    default = NetFTCalibration()
    return NetFTCalibration(
        default.counts_per_force if args.counts_per_force is None else args.counts_per_force,
        default.counts_per_torque if args.counts_per_torque is None else args.counts_per_torque,
    )


def run(args: argparse.Namespace) -> int:
    """Check every argument and the output folder, confirm, drill, print and save the metrics."""
    from drillgym.controllers import make_controller

    try:
        _check_options(args)
        limits = _limits(args.max_gap_ms)
        plan = load_plan(args.plan, args.seed) if args.plan is not None else None
        scenario = parse_scenario(args.scenario).to_dict() if plan is None else {}
        controller = make_controller(args.controller)
        given = _given_calibration(args)
        _refuse_previous_record(args.out)
        if plan is not None and args.yes_all and not args.dry_run:
            _refuse_far_transits(plan, limits)
    except (ValueError, TypeError, OSError) as e:
        print(f"drillgym run: error: {e}", file=sys.stderr)
        return 2
    opts = CellOptions(
        robot=args.robot,
        ft=args.ft,
        tracker=args.tracker,
        controller_spec=args.controller,
        dry_run=args.dry_run,
        servo_thread=args.servo_thread,
        record_rtde=args.record_rtde,
        limits=limits,
        out=args.out,
    )
    if plan is not None:
        return _run_plan(args, opts, controller, plan, given)
    if not _confirm(args, args.scenario or "the default plan"):
        print("not confirmed; nothing moved")
        return 2
    scenario.pop("tracker", None)
    return _run_episodes(args, opts, controller, scenario, given)


@dataclass
class _Record:
    """What a run has written so far: its calibration, whether it made ``--out``, its holes' metrics entries."""

    calibration: NetFTCalibration | None = None
    calibration_entry: dict[str, Any] = field(default_factory=dict)
    created: bool = False
    results: list[dict[str, Any]] = field(default_factory=list)


def _open_record(opts: CellOptions, given: NetFTCalibration | None, commands: Path) -> _Record:
    """Read the F/T calibration and create ``--out`` (``commands``: where the commands go, for the dry-run note)."""
    calibration, source = ft_calibration(opts.ft or opts.robot, given)
    print(
        f"F/T calibration ({source}): {calibration.counts_per_force:g} counts/N, "
        f"{calibration.counts_per_torque:g} counts/N-m"
    )
    created = not opts.out.exists()
    opts.out.mkdir(parents=True, exist_ok=True)
    if opts.dry_run:
        print(
            "DRY RUN: nothing is sent to the robot. The episode follows the commanded path with the robot at rest; "
            f"{commands} logs every command that would have been sent. Forces and metrics "
            "below describe a robot that did not move, and the servo loop's timing (missed_cycles in metrics.json) "
            "times a loop that sends nothing."
        )
    entry = {
        "counts_per_force": calibration.counts_per_force,
        "counts_per_torque": calibration.counts_per_torque,
        "source": source,
    }
    return _Record(calibration, entry, created)


def _drop_unopened(out: Path, created: bool, commands: Path) -> None:
    """The cell could not be opened for the first hole: leave no record behind (nothing was sent).

    The command log is made before the connection; it is this run's (``--out`` held no record) and empty.
    """
    if created:  # leave no empty output folder behind
        shutil.rmtree(out, ignore_errors=True)
        return
    commands.unlink(missing_ok=True)
    if commands.parent != out:
        with contextlib.suppress(OSError):
            commands.parent.rmdir()


def _run_episodes(
    args: argparse.Namespace,
    opts: CellOptions,
    controller: Any,
    scenario: dict[str, Any],
    given: NetFTCalibration | None,
) -> int:
    """``--episodes`` holes at the default entry point, with one env; logged to ``<out>``."""
    commands = opts.out / "commands.jsonl"
    record = _open_record(opts, given, commands)
    assert record.calibration is not None
    try:
        env = open_cell(opts, record.calibration, commands, scenario)
    except (RuntimeError, OSError, ValueError) as e:
        _drop_unopened(opts.out, record.created, commands)
        print(f"drillgym run: error: cannot open the cell: {e}", file=sys.stderr)
        return 2
    code = 0
    try:
        for k in range(args.episodes):
            extra = {"ft_calibration": record.calibration_entry}
            name = opts.log_name(f"ep{k}")
            result, code = drill_hole(env, opts, controller, args.seed + k, name, f"episode {k}", extra)
            if result is not None:
                record.results.append({"episode": k, **result})
            if code:
                break
    except KeyboardInterrupt:
        print("interrupted: stopping the robot", file=sys.stderr)
        code = 3
    finally:
        env.close()
        write_metrics(opts.out, record.results)
    if opts.dry_run:
        summarise_dry_run(env, commands, opts.out / "dry_run.json")
    print(f"results in {opts.out.resolve()}")
    return code


def _print_plan(args: argparse.Namespace, plan: DrillingPlan) -> None:
    if args.dry_run:
        asks = "a dry run: nothing moves"
    else:
        asks = "--yes-all: no question before each hole" if args.yes_all else "a question before each hole"
    print(f"plan {plan.path}: {len(plan.holes)} hole(s) with {args.controller}, in this order; {asks}:")
    for hole in plan.holes:
        print(f"  {hole.label}: {hole.describe()}")


def _run_plan(
    args: argparse.Namespace, opts: CellOptions, controller: Any, plan: DrillingPlan, given: NetFTCalibration | None
) -> int:
    """The holes of ``plan`` in order, one env each; ``<out>/plan.json`` records the plan as checked."""
    _print_plan(args, plan)
    asks = not (args.dry_run or args.yes_all)
    if asks and not sys.stdin.isatty():
        print(
            "stdin is not a terminal: cannot ask before each hole; pass --yes-all to drill every hole without asking",
            file=sys.stderr,
        )
        print("not confirmed; nothing moved")
        return 2
    record: _Record | None = None
    previous: PlannedHole | None = None
    code = 0
    try:
        for hole in plan.holes:
            if asks and not _confirm_hole(args, hole, len(plan.holes), previous):
                moved = "nothing moved" if previous is None else f"{previous.label} was the last one"
                print(f"{hole.label} not confirmed: it and the holes after it were not drilled; {moved}")
                code = 2
                break
            commands = opts.out / "commands" / f"{hole.name}.jsonl"
            record = record or _open_record(opts, given, commands)
            code = _plan_hole(opts, controller, plan, hole, record, commands, first=previous is None)
            if code == 2:  # the cell could not be opened for the first hole: no record
                return code
            previous = hole
            if code:
                left = [h.label for h in plan.holes[hole.index :]]
                print(f"the plan stops at {hole.label}" + (f"; not drilled: {', '.join(left)}" if left else ""))
                break
    except KeyboardInterrupt:
        print("interrupted: stopping the robot; the holes after this one were not drilled", file=sys.stderr)
        code = 3
    finally:
        if record is not None and previous is not None:
            write_metrics(opts.out, record.results)
    if previous is not None:
        print(f"results in {opts.out.resolve()}")
    return code


def _plan_hole(
    opts: CellOptions,
    controller: Any,
    plan: DrillingPlan,
    hole: PlannedHole,
    record: _Record,
    commands: Path,
    first: bool,
) -> int:
    """One hole of a plan with an env of its own; its exit code (2: the first hole's cell could not be opened)."""
    assert record.calibration is not None
    commands.parent.mkdir(exist_ok=True)
    scenario = {k: v for k, v in hole.scenario.to_dict().items() if k != "tracker"}
    try:
        env = open_cell(opts, record.calibration, commands, scenario, CellParams(entry_point_base_m=hole.entry_base_m))
    except (RuntimeError, OSError, ValueError) as e:
        if first:
            _drop_unopened(opts.out, record.created, commands)
            print(f"drillgym run: error: cannot open the cell: {e}", file=sys.stderr)
            return 2
        print(f"{hole.label}: cannot open the cell: {e}", file=sys.stderr)
        return 1
    if first:
        (opts.out / "plan.json").write_text(json.dumps(json_safe(plan.to_json()), indent=2))
    where = {"index": hole.index, "of": len(plan.holes), "name": hole.name, "entry_point_base_mm": hole.entry_base_mm}
    extra = {"ft_calibration": record.calibration_entry, "plan_file": str(plan.path), "hole": where}
    label = f"{hole.label} of {len(plan.holes)}"
    try:
        result, code = drill_hole(env, opts, controller, hole.seed, opts.log_name(hole.name), label, extra)
    finally:
        env.close()
    if result is not None:
        record.results.append(
            {"hole": hole.index, "name": hole.name, "entry_point_base_mm": hole.entry_base_mm, **result}
        )
        write_metrics(opts.out, record.results)
    if opts.dry_run:
        summarise_dry_run(env, commands, opts.out / "dry_run" / f"{hole.name}.json")
    return code
