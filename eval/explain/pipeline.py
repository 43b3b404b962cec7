"""Which candidate explains Li's compensated runs; fit on none + KP 1, predict KP 4.

The command is :mod:`drillgym.eval.cli.explain_paper`.

Writes ``OUT/explanation.json`` and ``OUT/explanation.md`` (:mod:`drillgym.eval.explain.report`). Candidates
are fitted in ``--workers`` spawned processes, each with its own simulator.
"""

from __future__ import annotations

from typing import Any

import numpy as np

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
