"""``drillgym explain-paper``: which unmodelled effect explains Li's compensated runs (:mod:`drillgym.eval.explain.pipeline`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from drillgym.envs.errors import UserError
from drillgym.eval.cli.bench import refuse_previous_record
from drillgym.eval.explain.candidates import CANDIDATES, QUICK, candidate
from drillgym.eval.explain.observations import FOLDS, RUNS
from drillgym.eval.explain.pipeline import FULL, QUICK_SETTINGS, explain_folds


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", type=Path, required=True, help="output folder (explanation.json, explanation.md)")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace a previous record in --out (without it, one is refused)"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"3 candidates, 1 fit seed, 2 prediction seeds, 4 grid points ({', '.join(QUICK)})",
    )
    parser.add_argument(
        "--candidates",
        default=None,
        help="comma-separated candidate names (default: all, or the quick set with --quick)",
    )
    parser.add_argument(
        "--folds",
        default="all",
        help="held-out runs, comma-separated, from none,kp1,kp4; each fold fits on the other two runs "
        "(default all: kp4 first, the primary fold, then none and kp1)",
    )
    parser.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")


def parse_folds(text: str) -> tuple[str, ...]:
    """``--folds``: ``all`` or held-out runs from :data:`RUNS`, comma-separated (``ValueError`` otherwise)."""
    if text.strip() == "all":
        return FOLDS
    folds = tuple(f.strip() for f in text.split(",") if f.strip())
    if not folds:
        raise UserError("--folds is empty")
    bad = [f for f in folds if f not in RUNS]
    if bad:
        raise UserError(f"--folds: unknown run(s) {bad}; choose from {list(RUNS)} or 'all'")
    if len(set(folds)) != len(folds):
        raise UserError(f"--folds lists a run twice: {list(folds)}")
    return folds


def run(args: argparse.Namespace) -> int:
    """Entry point (bad arguments raise ``ValueError``/``LookupError`` for the CLI's one-line error)."""
    from drillgym.eval.explain.report import markdown

    if args.workers < 1:
        raise UserError(f"--workers={args.workers} must be >= 1")
    if args.candidates is not None:
        names = [n.strip() for n in args.candidates.split(",") if n.strip()]
        if not names:
            raise UserError("--candidates is empty")
    else:
        names = list(QUICK) if args.quick else [c.name for c in CANDIDATES]
    for n in names:
        candidate(n)
    if len(set(names)) != len(names):
        raise UserError(f"--candidates lists a name twice: {names}")
    folds = parse_folds(args.folds)
    refuse_previous_record(args.out, ("explanation.json", "explanation.md"), args.overwrite, "explain-paper record")
    settings = QUICK_SETTINGS if args.quick else FULL
    result = explain_folds(names, settings, args.workers, folds)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "explanation.json").write_text(json.dumps(result, indent=2) + "\n")
    md = markdown(result)
    (args.out / "explanation.md").write_text(md)
    print(md)
    print(f"Results: {args.out / 'explanation.json'} and {args.out / 'explanation.md'}")
    return 0
