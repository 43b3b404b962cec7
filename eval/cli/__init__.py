"""The ``drillgym`` command: one front for every user-facing job.

Each sub-command lives in its own module of this package, named after it (``drillgym bench-speed`` is
:mod:`drillgym.eval.cli.bench_speed`), exposing ``add_arguments(parser)`` and ``run(args) -> int``;
modules are imported only when their sub-command runs, so ``drillgym --help`` stays fast and a job
never imports what it does not use (Ray, torch, ...).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from drillgym.envs.errors import UserError

COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("drillgym.eval.cli.demo", "Run the paper scenario end to end and print where the results are."),
    "identify-stiffness": (
        "drillgym.eval.cli.identify_stiffness",
        "Identify the UR5 joint stiffnesses from simulated load tests (Li 2023 eq. 8, Table 1).",
    ),
    "bench-speed": ("drillgym.eval.cli.bench_speed", "Real-time factor and peak memory of the simulated cell."),
    "reproduce": (
        "drillgym.eval.cli.reproduce",
        "Reproduce Li 2023 (and Zhang 2005's claims): report.md, reproduction.json, figures.",
    ),
    "calibrate": (
        "drillgym.eval.cli.calibrate",
        "Calibrate the entry mechanics on the uncompensated paper run and predict li2023 on each candidate.",
    ),
    "explain-paper": (
        "drillgym.eval.cli.explain_paper",
        "Which unmodelled effect explains Li's compensated runs: fit on the uncompensated and KP 1 runs, predict KP 4.",
    ),
    "validate-forces": (
        "drillgym.eval.cli.validate_forces",
        "The force model against published bone-drilling thrust and torque: one calibration per series, the rest predicted.",
    ),
    "tune-entry": (
        "drillgym.eval.cli.tune_entry",
        "Tune a slow entry (feed schedule) on top of a controller on the paper and sweep suites; pick the best.",
    ),
    "tune-table": (
        "drillgym.eval.cli.tune_table",
        "Tune a gain-scheduling table (the schedule residual's fields at 11 anchor plans) on tuning episodes only.",
    ),
    "train": (
        "drillgym.eval.cli.train",
        "Train a residual policy (SB3) on top of a compensator; resumable; --seeds: several seeds and their report.",
    ),
    "bench": (
        "drillgym.eval.cli.bench",
        "Benchmark controllers on a scenario suite over seeds: metrics with confidence intervals, paired differences, plots, logs.",
    ),
    "run": (
        "drillgym.eval.cli.run",
        "Drill with a controller on the real UR5 cell (or the emulator); same episode logs as the sim.",
    ),
    "emulate": (
        "drillgym.eval.cli.emulate",
        "Serve a UR CB3 controller + ATI Net F/T emulator, backed by the simulator, on a loopback address.",
    ),
    "ft-check": (
        "drillgym.eval.cli.ft_check",
        "Check the F/T sensor's force scale with a known mass (calibration read from the sensor); exit 1 if off.",
    ),
    "bench-rtde": (
        "drillgym.eval.cli.bench_rtde",
        "Timing of the 125 Hz servoL stream through ur_rtde: missed cycles, command-to-state latency.",
    ),
    "diagnose": (
        "drillgym.eval.cli.diagnose",
        "Sim-to-real gap diagnosis of real episode logs: where, which unmodelled effect, how far it shrinks.",
    ),
    "separate": (
        "drillgym.eval.cli.separate",
        "For a diagnosis with a model not ruled out: the feed at which simulated holes would tell it from the named one.",
    ),
    "make-reality": (
        "drillgym.eval.cli.make_reality",
        "Write real-schema episode logs from the simulator with unmodelled effects switched on.",
    ),
    "bench-diagnosis": (
        "drillgym.eval.cli.bench_diagnosis",
        "Withheld-effect benchmark of the diagnosis: identification, shrink, false alarms, out-of-library effect.",
    ),
    "import-rtde": (
        "drillgym.eval.cli.import_rtde",
        "Import ur_rtde file recordings joined with F/T and tracker CSVs into episode logs.",
    ),
}


USER_ERRORS: tuple[type[BaseException], ...] = (UserError, OSError, ModuleNotFoundError)
"""What a command raises on bad input: a bad value, name, spec or file content (:class:`~drillgym.envs.errors.UserError`,
the project's one user-error type), a missing, existing or unreadable file, a refused or dropped connection, a port
in use (``OSError``), an optional package that is not installed, e.g. Ray (``ModuleNotFoundError``,
:func:`drillgym.eval.scale.cluster.require_ray`). The top-level handler prints these on one line with exit status 2;
anything else (a plain ``ValueError`` or ``KeyError`` is the project's bug, not the user's) keeps its traceback. Set
``DRILLGYM_TRACEBACK=1`` to see the traceback of a user error too."""


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Show each option's default, unless its help already says it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text.lower() or action.default is None or action.default is False:
            return text
        return super()._get_help_string(action)


class CommandParser(argparse.ArgumentParser):
    """A sub-command's parser: a usage error is one line, ``drillgym CMD: error: ...``, exit 2."""

    def error(self, message: str) -> NoReturn:
        """Print the error and where the options are listed, exit 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("drillgym")
    except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
        return "unknown"


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split()) or type(error).__name__
    if isinstance(error, KeyError) and error.args:
        text = f"unknown name {error.args[0]!r}"
    return text


def build_parser() -> argparse.ArgumentParser:
    """Argument parser with one sub-parser per command (arguments added lazily)."""
    parser = argparse.ArgumentParser(prog="drillgym", description="Robot-assisted bone drilling with a UR5.")
    parser.add_argument("--version", action="version", version=f"drillgym {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text.replace("%", "%%"), description=help_text)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``drillgym`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not argv or argv[0] in ("-h", "--help", "--version") or argv[0] not in COMMANDS:
        if argv and argv[0] not in ("-h", "--help", "--version"):
            parser.error(f"unknown command {argv[0]!r}; choose from {', '.join(COMMANDS)}")
        if argv and argv[0] == "--version":
            parser.parse_args(argv[:1])  # prints the version, exits 0
        parser.print_help()
        return 0
    name = argv[0]
    module = importlib.import_module(COMMANDS[name][0])
    sub = CommandParser(prog=f"drillgym {name}", description=COMMANDS[name][1], formatter_class=HelpFormatter)
    module.add_arguments(sub)
    args = sub.parse_args(argv[1:])
    try:
        return int(module.run(args) or 0)
    except KeyboardInterrupt:
        print(f"drillgym {name}: interrupted", file=sys.stderr)
        return 130
    except USER_ERRORS as e:
        if os.environ.get("DRILLGYM_TRACEBACK"):
            raise
        print(f"drillgym {name}: error: {_one_line(e)}", file=sys.stderr)
        return 2
