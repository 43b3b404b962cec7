"""The ``drillgym`` command: one front for every user-facing job.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args) -> int``;
modules are imported only when their sub-command runs, so ``drillgym --help`` stays fast and a job
never imports what it does not use (Ray, torch, ...).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("drillgym.eval.demo", "Run the paper scenario end to end and print where the results are."),
    "identify-stiffness": (
        "drillgym.envs.robot.stiffness_cli",
        "Identify the UR5 joint stiffnesses from simulated load tests (Li 2023 eq. 8, Table 1).",
    ),
    "bench-speed": ("drillgym.eval.bench_speed", "Real-time factor and peak memory of the simulated cell."),
    "reproduce": (
        "drillgym.eval.reproduce",
        "Reproduce Li 2023 (and Zhang 2005's claims): report.md, reproduction.json, figures.",
    ),
    "calibrate": (
        "drillgym.eval.calibration_cli",
        "Calibrate the entry mechanics on the uncompensated paper run and predict li2023 on each candidate.",
    ),
    "tune-entry": (
        "drillgym.eval.tune_entry",
        "Tune a slow entry (feed schedule) on top of a controller on the paper and sweep suites; pick the best.",
    ),
    "train": (
        "drillgym.eval.train_seeds",
        "Train a residual policy (SB3) on top of a compensator; resumable; --seeds: several seeds and their report.",
    ),
    "bench": (
        "drillgym.eval.bench",
        "Benchmark controllers on a scenario suite over seeds: metrics with confidence intervals, paired differences, plots, logs.",
    ),
    "run": (
        "drillgym.eval.run_real",
        "Drill with a controller on the real UR5 cell (or the emulator); same episode logs as the sim.",
    ),
    "emulate": (
        "drillgym.envs.real.emulator.cli",
        "Serve a UR CB3 controller + ATI Net F/T emulator, backed by the simulator, on a loopback address.",
    ),
    "bench-rtde": (
        "drillgym.eval.bench_rtde",
        "Timing of the 125 Hz servoL stream through ur_rtde: missed cycles, command-to-state latency.",
    ),
    "diagnose": (
        "drillgym.eval.diagnosis.cli_diagnose",
        "Sim-to-real gap diagnosis of real episode logs: where, which unmodelled effect, how far it shrinks.",
    ),
    "make-reality": (
        "drillgym.eval.diagnosis.reality.cli",
        "Write real-schema episode logs from the simulator with unmodelled effects switched on.",
    ),
    "bench-diagnosis": (
        "drillgym.eval.diagnosis.bench_cli",
        "Withheld-effect benchmark of the diagnosis: identification, shrink, false alarms, out-of-library effect.",
    ),
    "import-rtde": (
        "drillgym.eval.diagnosis.rtde_cli",
        "Import ur_rtde file recordings joined with F/T and tracker CSVs into episode logs.",
    ),
}


def build_parser() -> argparse.ArgumentParser:
    """Argument parser with one sub-parser per command (arguments added lazily)."""
    parser = argparse.ArgumentParser(prog="drillgym", description="Robot-assisted bone drilling with a UR5.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text.replace("%", "%%"), description=help_text)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``drillgym`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in COMMANDS:
        if argv and argv[0] not in ("-h", "--help"):
            parser.error(f"unknown command {argv[0]!r}; choose from {', '.join(COMMANDS)}")
        parser.print_help()
        return 0
    name = argv[0]
    module = importlib.import_module(COMMANDS[name][0])
    sub = argparse.ArgumentParser(prog=f"drillgym {name}", description=COMMANDS[name][1])
    module.add_arguments(sub)
    args = sub.parse_args(argv[1:])
    return int(module.run(args) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
