"""``drillgym explain-paper``: which candidate explains Li's compensated runs; fit on none + KP 1, predict KP 4.

Writes ``OUT/explanation.json`` and ``OUT/explanation.md`` (:mod:`drillgym.eval.explain.report`). Candidates
are fitted in ``--workers`` spawned processes, each with its own simulator.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.eval.explain.candidates import CANDIDATES, QUICK, candidate
from drillgym.eval.explain.observations import (
    CALIBRATION_RUNS,
    HELD_OUT_RUN,
    RUNS,
    calibration_targets,
    held_out_targets,
)
from drillgym.eval.pool import run_ordered

FULL = {"fit_seeds": 3, "predict_seeds": 5, "grid_points": 9, "refine_evals": 6}
QUICK_SETTINGS = {"fit_seeds": 1, "predict_seeds": 2, "grid_points": 4, "refine_evals": 2}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", type=Path, required=True, help="output folder (explanation.json, explanation.md)")
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
    parser.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")


def _job(args: tuple[Any, ...]) -> dict[str, Any]:
    from drillgym.eval.explain.predict import fit_and_predict

    return fit_and_predict(*args)


def seed_scatter(nominal: dict[str, Any]) -> dict[tuple[str, str], float]:
    """The simulator's own seed-to-seed SD of each run's metrics (0 with one seed)."""
    out = {}
    for run in RUNS:
        for k, v in nominal[run].items():
            out[(run, k)] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
    return out


def explain(names: list[str], settings: dict[str, int], workers: int) -> dict[str, Any]:
    """Fit every named candidate on the calibration subset, predict the held-out run, rank and choose."""
    from drillgym.eval.explain.fit import nominal_outcome
    from drillgym.eval.explain.report import build_explanation
    from drillgym.eval.explain.simulate import close, means, simulate

    fit_seeds = list(range(settings["fit_seeds"]))
    predict_seeds = list(range(settings["predict_seeds"]))
    if len(fit_seeds) > len(predict_seeds):
        raise ValueError("the fit cannot use more seeds than the prediction")
    targets = calibration_targets()
    nominal_pred = simulate(None, 0.0, RUNS, predict_seeds)
    seed_sd = seed_scatter(nominal_pred)
    # the fit's seeds are the first of the prediction's, so the nominal cell's calibration runs are already done
    fitted = {run: {k: v[: len(fit_seeds)] for k, v in nominal_pred[run].items()} for run in CALIBRATION_RUNS}
    nominal_fit = nominal_outcome(targets, seed_sd, means(fitted))
    close()
    jobs = [
        (n, targets, seed_sd, fit_seeds, predict_seeds, settings["grid_points"], settings["refine_evals"])
        for n in names
    ]
    results = run_ordered(_job, jobs, workers)
    close()  # the env of an in-process run
    nominal = {
        "fit": nominal_fit,
        "prediction": {k: {"sim": float(np.mean(v)), "per_seed": v} for k, v in nominal_pred[HELD_OUT_RUN].items()},
    }
    return build_explanation(results, nominal, held_out_targets(), seed_sd, settings)


def run(args: argparse.Namespace) -> int:
    """Entry point (bad arguments raise ``ValueError``/``LookupError`` for the CLI's one-line error)."""
    from drillgym.eval.explain.report import markdown

    if args.workers < 1:
        raise ValueError(f"--workers={args.workers} must be >= 1")
    if args.candidates is not None:
        names = [n.strip() for n in args.candidates.split(",") if n.strip()]
        if not names:
            raise ValueError("--candidates is empty")
    else:
        names = list(QUICK) if args.quick else [c.name for c in CANDIDATES]
    for n in names:
        candidate(n)
    if len(set(names)) != len(names):
        raise ValueError(f"--candidates lists a name twice: {names}")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"--out {args.out} exists and is not a folder")
    settings = QUICK_SETTINGS if args.quick else FULL
    result = explain(names, settings, args.workers)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "explanation.json").write_text(json.dumps(result, indent=2) + "\n")
    md = markdown(result)
    (args.out / "explanation.md").write_text(md)
    print(md)
    print(f"Results: {args.out / 'explanation.json'} and {args.out / 'explanation.md'}")
    return 0
