"""``drillgym diagnose --real DIR --out OUT``: diagnose the sim-to-real gap of a folder of episode logs.

A diagnosis is a record: an ``--out`` that holds one (:data:`RECORD_FILES`) is refused before any log is read, as
``drillgym run`` refuses a previous run's record; there is no ``--overwrite``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES, EFFECTS, parse_candidates
from drillgym.envs.errors import UserError
from drillgym.eval.cli.bench import previous_run

RECORD_FILES = ("diagnosis.json", "report.md", "gap_map.png", "ranking.png", "overlays.png", "spectra.png")
"""What a diagnosis writes into its ``--out`` (:func:`drillgym.eval.diagnosis.report.write_outputs`)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument(
        "--real", required=True, type=Path, help="folder of real episode logs (*.parquet, ur_rtde sessions)"
    )
    parser.add_argument(
        "--out",
        required=True,
        type=Path,
        help="output folder: diagnosis.json, report.md, figures; one that holds a previous diagnosis is refused",
    )
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    parser.add_argument(
        "--candidates",
        default=",".join(DIAGNOSIS_CANDIDATES),
        help=f"comma-separated candidate effects, any of {', '.join(EFFECTS)} (default: {', '.join(DIAGNOSIS_CANDIDATES)})",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the calibration/held-out split and the bootstrap")
    parser.add_argument("--strict", action="store_true", help="fail on the first bad log instead of skipping it")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")


def run(args: argparse.Namespace) -> int:
    """Load, diagnose, write."""
    from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, run_diagnosis
    from drillgym.eval.diagnosis.episodes import load_episodes
    from drillgym.eval.diagnosis.report import write_outputs

    found = previous_run(args.out, RECORD_FILES, ())
    if found:
        raise UserError(
            f"{args.out} holds a previous diagnosis ({', '.join(found)}): a diagnosis is never overwritten; "
            "pass another --out"
        )
    candidates = parse_candidates(args.candidates)
    episodes, skipped = load_episodes(args.real, strict=args.strict)
    for s in skipped:
        print(f"skipped {s}", file=sys.stderr)
    if len(episodes) < 4:
        raise UserError(f"{args.real}: {len(episodes)} usable episode(s); the diagnosis needs at least 4")
    opts = DiagnoseOptions(workers=args.workers, candidates=candidates, seed=args.seed, progress=not args.no_progress)
    diag = run_diagnosis(episodes, opts)
    paths = write_outputs(diag, args.out, skipped, figures=not args.no_figures)
    print(diag.result["summary"])
    print(f"wrote {paths['json']} and {paths['report']}")
    return 0
