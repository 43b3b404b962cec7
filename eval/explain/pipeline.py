"""Which candidate explains Li's compensated runs; fit on none + KP 1, predict KP 4 (and the other folds).

The command is :mod:`drillgym.eval.cli.explain_paper`.

Writes ``OUT/explanation.json`` and ``OUT/explanation.md`` (:mod:`drillgym.eval.explain.report`). Candidates
are fitted in ``--workers`` spawned processes, each with its own simulator.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.eval.explain.fit import nominal_outcome
from drillgym.eval.explain.observations import (
    FOLDS,
    HELD_OUT_RUN,
    RUNS,
    calibration_runs,
    calibration_targets,
    held_out_targets,
)
from drillgym.eval.explain.predict import fit_and_predict
from drillgym.eval.explain.report import build_explanation
from drillgym.eval.explain.simulate import close, means, simulate
from drillgym.eval.pool import run_ordered

FULL = {"fit_seeds": 3, "predict_seeds": 5, "grid_points": 9, "refine_evals": 6}
QUICK_SETTINGS = {"fit_seeds": 1, "predict_seeds": 2, "grid_points": 4, "refine_evals": 2}


def _job(args: tuple[Any, ...]) -> dict[str, Any]:

    return fit_and_predict(*args)


def seed_scatter(nominal: dict[str, Any]) -> dict[tuple[str, str], float]:
    """The simulator's own seed-to-seed SD of each run's metrics (0 with one seed)."""
    out = {}
    for run in RUNS:
        for k, v in nominal[run].items():
            out[(run, k)] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
    return out


def explain(
    names: list[str],
    settings: dict[str, int],
    workers: int,
    held_out: str = HELD_OUT_RUN,
    nominal_pred: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Fit every named candidate on the fold's calibration runs, predict its held-out run, rank and choose.

    ``held_out``: the run the fold holds out (:data:`~drillgym.eval.explain.observations.FOLDS`); ``nominal_pred``:
    the nominal cell's runs over the prediction seeds when already simulated (every fold shares them).
    """
    fit_seeds = list(range(settings["fit_seeds"]))
    predict_seeds = list(range(settings["predict_seeds"]))
    if len(fit_seeds) > len(predict_seeds):
        raise UserError("the fit cannot use more seeds than the prediction")
    targets = calibration_targets(held_out)
    if nominal_pred is None:
        nominal_pred = simulate(None, 0.0, RUNS, predict_seeds)
    seed_sd = seed_scatter(nominal_pred)
    # the fit's seeds are the first of the prediction's, so the nominal cell's calibration runs are already done
    fitted = {run: {k: v[: len(fit_seeds)] for k, v in nominal_pred[run].items()} for run in calibration_runs(held_out)}
    nominal_fit = nominal_outcome(targets, seed_sd, means(fitted), held_out)
    close()
    jobs = [
        (n, targets, seed_sd, fit_seeds, predict_seeds, settings["grid_points"], settings["refine_evals"], held_out)
        for n in names
    ]
    results = run_ordered(_job, jobs, workers)
    close()  # the env of an in-process run
    nominal = {
        "fit": nominal_fit,
        "prediction": {k: {"sim": float(np.mean(v)), "per_seed": v} for k, v in nominal_pred[held_out].items()},
    }
    return build_explanation(results, nominal, held_out_targets(held_out), seed_sd, settings, held_out)


def explain_folds(
    names: list[str], settings: dict[str, int], workers: int, folds: tuple[str, ...] = FOLDS
) -> dict[str, Any]:
    """Every fold of ``folds`` (held-out runs; the first is the document's own, the others go under ``"folds"``).

    The nominal cell's runs are simulated once for all folds. Each fold's fits see only its calibration runs.
    """
    if not folds:
        raise UserError("at least one fold is needed")
    if len(set(folds)) != len(folds):
        raise UserError(f"a fold is listed twice: {list(folds)}")
    for held_out in folds:
        calibration_runs(held_out)
    nominal_pred = simulate(None, 0.0, RUNS, list(range(settings["predict_seeds"])))
    close()
    docs = [explain(names, settings, workers, held_out, nominal_pred) for held_out in folds]
    primary = docs[0]
    primary["folds"] = {doc["held_out_run"]: doc for doc in docs[1:]}
    return primary
