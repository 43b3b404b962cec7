"""Fit one candidate and predict the held-out run: the unit of work of ``drillgym explain-paper``.

:func:`fit_and_predict` receives the calibration targets only; the held-out numbers are compared with its
predictions afterwards (:func:`score_prediction`), outside the fit.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from drillgym.eval.bench.summary import mean_ci
from drillgym.eval.explain.candidates import Candidate, candidate
from drillgym.eval.explain.fit import fit_candidate
from drillgym.eval.explain.observations import HELD_OUT_RUN, METRICS, calibration_runs
from drillgym.eval.explain.simulate import means, simulate


def predict_run(
    cand: Candidate | None, values: list[float], seeds: list[int], held_out: str = HELD_OUT_RUN
) -> dict[str, dict[str, Any]]:
    """The held-out run at the fitted value (``values[0]``) and the interval's ends: mean and interval per metric.

    The interval spans the 95 % CI over seeds at the fitted value and the means at the other values.
    """
    runs = [simulate(cand, v, (held_out,), seeds)[held_out] for v in values]
    out: dict[str, dict[str, Any]] = {}
    for k in METRICS:
        mean, lo, hi, n = mean_ci(runs[0][k])
        if n < 2:
            lo = hi = mean
        ends = [float(np.mean(r[k])) for r in runs[1:]]
        out[k] = {"sim": mean, "interval": [min([lo, *ends]), max([hi, *ends])], "per_seed": runs[0][k]}
    return out


def fit_and_predict(
    name: str,
    targets: Mapping[tuple[str, str], float],
    seed_sd: Mapping[tuple[str, str], float],
    fit_seeds: list[int],
    predict_seeds: list[int],
    grid_points: int,
    refine_evals: int,
    held_out: str = HELD_OUT_RUN,
) -> dict[str, Any]:
    """Fit candidate ``name`` on ``targets`` (the fold's calibration runs only) and predict the held-out run."""
    cand = candidate(name)
    runs = calibration_runs(held_out)

    def evaluate(x: float) -> dict[str, dict[str, float]]:
        return means(simulate(cand, x, runs, fit_seeds))

    fit = fit_candidate(cand, targets, seed_sd, evaluate, grid_points, refine_evals, held_out)
    ends = [v for v in fit.interval if abs(v - fit.value) > 1e-12 * max(1.0, abs(fit.value))]
    return {"name": name, "fit": fit, "prediction": predict_run(cand, [fit.value, *ends], predict_seeds, held_out)}


def score_prediction(prediction: Mapping[str, Mapping[str, Any]], li: Mapping[str, float]) -> dict[str, dict[str, Any]]:
    """Each predicted held-out metric that Li reports against his: ``{sim, interval, li, rel_err, li_inside}``.

    Li reports four numbers of his uncompensated and KP 4 runs and one (the deviation) of KP 1; a metric he does
    not report is not scored.
    """
    out = {}
    for k, p in prediction.items():
        if k not in li:
            continue
        lo, hi = p["interval"]
        out[k] = {
            "sim": p["sim"],
            "interval": [lo, hi],
            "li": li[k],
            "rel_err": (p["sim"] - li[k]) / li[k],
            "li_inside": bool(lo <= li[k] <= hi),
        }
    return out
