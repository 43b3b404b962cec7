"""Fit one candidate's parameter on the calibration subset; its interval, penalised score and plausibility.

Misfit: ``χ² = Σ ((sim − Li) / σ)²`` over the calibration numbers (:func:`drillgym.eval.explain.observations.calibration_targets`,
σ from :func:`~drillgym.eval.explain.observations.sigma`), the simulated value being the mean over the fit's
seeds (the same seeds at every parameter value, so χ² is a deterministic function of it). The fit is a grid
over the searched range, then a bounded scalar search between the best grid point's neighbours. The
interval is where ``χ² ≤ χ²_min + 1`` (a profile interval, linear between evaluated points; it ends at the
searched bound when it does not close there). Score: ``χ² + k ln n`` (BIC-like, k fitted parameters, n
calibration numbers), as the log-based diagnosis penalises its parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from drillgym.envs.errors import UserError
from drillgym.eval.explain.candidates import Candidate
from drillgym.eval.explain.observations import HELD_OUT_RUN, check_calibration_only, sigma

Evaluate = Callable[[float], dict[str, dict[str, float]]]
"""Parameter value -> ``{run: {metric: mean}}`` of the calibration runs."""
PIN_SHARE = 0.02
"""A fit within this share of the searched span from a bound that is not the effect's off value is 'pinned'."""


@dataclass
class FitOutcome:
    """A candidate's fit on the calibration subset."""

    value: float
    interval: tuple[float, float]
    chi2: float
    n_params: int
    n_numbers: int
    fitted_on: list[str]
    """``run.metric`` of every number the fit saw."""
    calibration: dict[str, dict[str, float]]
    """``run.metric -> {sim, li, sigma, z}`` at the fitted value."""
    evaluated: list[tuple[float, float]] = field(default_factory=list)
    """``(value, χ²)`` of every evaluation, sorted by value."""
    plausible: bool = True
    note: str = ""

    @property
    def score(self) -> float:
        """χ² + k ln n (lower is better)."""
        return self.chi2 + self.n_params * math.log(self.n_numbers)


def chi2_terms(
    sim: Mapping[str, Mapping[str, float]],
    targets: Mapping[tuple[str, str], float],
    seed_sd: Mapping[tuple[str, str], float],
    held_out: str = HELD_OUT_RUN,
) -> dict[str, dict[str, float]]:
    """Per calibration number: ``{sim, li, sigma, z}`` (z = (sim − li) / σ); ``held_out``: the fold's held-out run."""
    check_calibration_only(targets, held_out)
    out = {}
    for (run, metric), li in targets.items():
        s = sigma(metric, li, seed_sd.get((run, metric), 0.0))
        v = float(sim[run][metric])
        out[f"{run}.{metric}"] = {"sim": v, "li": li, "sigma": s, "z": (v - li) / s}
    return out


def _chi2(terms: Mapping[str, Mapping[str, float]]) -> float:
    return float(sum(t["z"] ** 2 for t in terms.values()))


def profile_interval(points: list[tuple[float, float]], lo: float, hi: float) -> tuple[float, float]:
    """Where χ² ≤ min + 1 along sorted ``(value, χ²)`` points (linear between them; a searched bound if open)."""
    xs = np.array([p[0] for p in points])
    ys = np.array([p[1] for p in points])
    i = int(np.argmin(ys))
    level = ys[i] + 1.0
    left, right = lo, hi
    for j in range(i, 0, -1):
        if ys[j - 1] > level:
            left = float(xs[j - 1] + (level - ys[j - 1]) * (xs[j] - xs[j - 1]) / (ys[j] - ys[j - 1]))
            break
    for j in range(i, len(xs) - 1):
        if ys[j + 1] > level:
            right = float(xs[j] + (level - ys[j]) * (xs[j + 1] - xs[j]) / (ys[j + 1] - ys[j]))
            break
    return left, right


def fit_candidate(
    cand: Candidate,
    targets: Mapping[tuple[str, str], float],
    seed_sd: Mapping[tuple[str, str], float],
    evaluate: Evaluate,
    grid_points: int = 9,
    refine_evals: int = 6,
    held_out: str = HELD_OUT_RUN,
) -> FitOutcome:
    """Fit ``cand``'s parameter to ``targets``: the calibration runs of the fold holding out ``held_out`` only.

    Targets of any other run raise ``ValueError``.
    """
    check_calibration_only(targets, held_out)
    if grid_points < 3:
        raise UserError(f"grid_points={grid_points} must be >= 3")
    seen: dict[float, tuple[float, dict[str, dict[str, float]]]] = {}

    def misfit(x: float) -> float:
        x = float(x)
        if x not in seen:
            terms = chi2_terms(evaluate(x), targets, seed_sd, held_out)
            c = _chi2(terms)
            seen[x] = (c if math.isfinite(c) else math.inf, terms)  # a metric the run cannot give: no fit there
        return seen[x][0]

    grid = np.linspace(cand.low, cand.high, grid_points)
    values = [misfit(x) for x in grid]
    i = int(np.argmin(values))
    if refine_evals > 0:
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
        minimize_scalar(
            misfit, bounds=(a, b), method="bounded", options={"maxiter": refine_evals, "xatol": 1e-3 * (b - a)}
        )
    points = sorted((x, c) for x, (c, _) in seen.items())
    best = min(points, key=lambda p: p[1])[0]
    chi2, terms = seen[best]
    outcome = FitOutcome(
        value=best,
        interval=profile_interval(points, cand.low, cand.high),
        chi2=chi2,
        n_params=1,
        n_numbers=len(targets),
        fitted_on=sorted(terms),
        calibration=terms,
        evaluated=points,
    )
    judge_plausibility(cand, outcome)
    return outcome


def judge_plausibility(cand: Candidate, outcome: FitOutcome) -> None:
    """Mark a fit outside the plausible range, or pinned at a searched bound other than the off value."""
    lo, hi = cand.plausible
    span = cand.high - cand.low
    v = outcome.value
    if not lo <= v <= hi:
        outcome.plausible = False
        outcome.note = f"{cand.param}={v:.4g} is outside its physical range [{lo:g}, {hi:g}]"
        return
    for bound in (cand.low, cand.high):
        if bound != 0.0 and abs(v - bound) <= PIN_SHARE * span:
            outcome.plausible = False
            outcome.note = (
                f"{cand.param}={v:.4g} is pinned at the bound {bound:g}: the data want more than the range allows"
            )
            return


def nominal_outcome(
    targets: Mapping[tuple[str, str], float],
    seed_sd: Mapping[tuple[str, str], float],
    sim: dict[str, Any],
    held_out: str = HELD_OUT_RUN,
) -> FitOutcome:
    """The shipped cell (no candidate, no parameter) scored on the same numbers."""
    terms = chi2_terms(sim, targets, seed_sd, held_out)
    return FitOutcome(0.0, (0.0, 0.0), _chi2(terms), 0, len(targets), sorted(terms), terms)
