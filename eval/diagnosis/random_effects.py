"""Random-effect fits: a sensor-side candidate whose parameters differ per episode around a shared mean.

For effects that declare :attr:`~drillgym.envs.effects.base.Effect.per_episode` (an F/T drift whose rate is
the episode's own). The model: episode e has parameters ``θ_e ~ N(μ, diag τ²)``, in the unit box of the
effect's ranges. Sensor-side effects are applied to the cached nominal replays, so a per-episode fit needs no
replay.

1. **Each episode alone.** ``θ̂_e`` minimises the episode's gap ``J_e`` (the grid, then the compass search of
   :mod:`drillgym.eval.diagnosis.fit`), with the curvature ``h_e`` of ``J_e`` along each parameter there. ``J``
   is χ²-like (−2 log-likelihood), so ``2 / h_e`` is the estimate's variance.
2. **Mean and spread, from the calibration episodes only.** ``μ = mean θ̂_e``; ``τ² = var θ̂_e − mean 2/h_e``
   (the scatter of the estimates beyond their own uncertainty; 0 when negative: no spread shown).
3. **Each episode's parameters** (the empirical-Bayes estimate): ``θ_e`` minimises
   ``J_e(θ) + Σ ((θ − μ) / τ)²``. The prior's cost is part of the episode's misfit, as the specimen's
   hardness prior is (:mod:`drillgym.eval.diagnosis.gap`); a parameter with ``τ = 0`` is held at ``μ``.
4. **The penalty counts them honestly.** A held-out episode's parameters are fitted to that episode, so the
   held-out score counts, besides ``μ`` and ``τ`` of each parameter, each held-out episode's effective number of
   parameters ``Σ h / (h + 2/τ²)`` (1 for a parameter its data pin down, 0 for one the prior holds: the degrees
   of freedom of a ridge estimate), as a conditional information criterion does.

Intervals (95 %): a bootstrap over the calibration episodes of ``μ`` and ``τ`` (the per-episode estimates are
resampled, nothing is refitted), expanded for the few episodes as every interval of the diagnosis is
(:func:`~drillgym.eval.diagnosis.intervals.expanded_tail`). A spread's off value is 0: an effect whose mean and spread intervals all
contain their off values is not told apart from its absence, and is not named.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np

from drillgym.eval.diagnosis.context import Evaluator
from drillgym.eval.diagnosis.fit import FitResult, ParamBox, local_search
from drillgym.eval.diagnosis.gap import Terms, pooled
from drillgym.eval.diagnosis.intervals import expanded_tail

EVALS_PER_PARAM = 20
"""Compass-search budget per parameter for one episode's fit (evaluations)."""
CURVATURE_STEP = 1 / 64
"""Step (fraction of each parameter's range) of the finite differences for the curvature of ``J_e``."""
BOOTSTRAP = 4000
"""Bootstrap resamples of the calibration episodes for the intervals."""
SPREAD_SUFFIX = "_spread"
"""Interval key of a parameter's episode-to-episode standard deviation (``fx_rate_n_s_spread``)."""


def fit_per_episode(ev: Evaluator, name: str, seed: int = 0) -> FitResult:
    """Fit ``name`` as a random effect on every episode; held-out terms, mean, spread and intervals.

    Args:
        ev: the evaluator (data + replays; the effect is sensor-side, so none is run).
        name: a candidate with :attr:`~drillgym.envs.effects.base.Effect.per_episode`.
        seed: seed of the intervals' bootstrap.
    """
    t0 = time.perf_counter()
    box = ParamBox([name])
    k = box.size
    result = FitResult(names=(name,), params=box.from_unit(box.to_unit([{}])), n_params=2 * k)
    memo: dict[tuple[int, Any], Terms] = {}

    def terms(i: int, u: np.ndarray) -> Terms:
        key = (i, box.spec(u))
        if key not in memo:
            memo[key] = ev.terms(key[1], [i])[0]
        return memo[key]

    try:
        d = ev.data
        n = len(d.episodes)
        own = [_own_fit(partial(terms, i), box) for i in range(n)]
        theta = np.array([u for u, _ in own])  # (episodes, k) unit box
        curv = np.array([h for _, h in own])
        cal = np.asarray(d.cal)
        mu, tau2 = _mean_spread(theta[cal], curv[cal])
        fitted: list[Terms] = []
        values: list[np.ndarray] = []
        dof: list[float] = []
        for i in range(n):
            u, t, df = _shrunk_fit(partial(terms, i), theta[i], curv[i], mu, tau2)
            fitted.append(t)
            values.append(u)
            dof.append(df)
        result.params = box.from_unit(mu)
        result.cal_objective = pooled([fitted[i] for i in d.cal])
        result.ho_terms = [fitted[i] for i in d.ho]
        result.ho_raw_terms = [ev.terms(box.spec(values[i]), [i], profile=False)[0] for i in d.ho]
        result.penalty_params = 2 * k + float(sum(dof[i] for i in d.ho))
        spans = np.array([p.high - p.low for _, p in box.entries])
        keys = [p.name for _, p in box.entries]
        result.per_episode = {
            "spread": dict(zip(keys, (np.sqrt(tau2) * spans).tolist(), strict=True)),
            "effective_params": result.penalty_params,
            "episodes": {ep.name: box.from_unit(u)[0] for ep, u in zip(d.episodes, values, strict=True)},
        }
        result.intervals = {name: _intervals(theta[cal], curv[cal], box, seed)}
    except Exception as e:  # a fit must not stop the diagnosis
        result.error = f"{type(e).__name__}: {e}"
    result.evaluations = len(memo)
    result.wall_s = time.perf_counter() - t0
    return result


def _own_fit(terms: Callable[[np.ndarray], Terms], box: ParamBox) -> tuple[np.ndarray, np.ndarray]:
    """One episode's own fit (unit box) and the curvature of its gap there along each parameter."""

    def objective(u: np.ndarray) -> float:
        return terms(u).j

    points = box.grid()
    u = local_search(objective, min(points, key=objective), EVALS_PER_PARAM * box.size)
    return u, _curvature(objective, u)


def _curvature(objective: Callable[[np.ndarray], float], u: np.ndarray) -> np.ndarray:
    """Second difference of ``objective`` along each parameter at ``u`` (one-sided at a bound)."""
    f0 = objective(u)
    out = np.zeros(u.size)
    h = CURVATURE_STEP
    for p in range(u.size):
        step = np.zeros(u.size)
        step[p] = h
        if u[p] - h < 0.0:
            a, b = objective(u + step), objective(u + 2 * step)
            out[p] = (b - 2 * a + f0) / h**2
        elif u[p] + h > 1.0:
            a, b = objective(u - step), objective(u - 2 * step)
            out[p] = (b - 2 * a + f0) / h**2
        else:
            out[p] = (objective(u + step) + objective(u - step) - 2 * f0) / h**2
    return out


def _mean_spread(theta: np.ndarray, curv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``μ`` and ``τ²`` (unit box) from per-episode estimates and their curvatures (method of moments)."""
    mu = theta.mean(axis=0)
    if len(theta) < 2:
        return mu, np.zeros_like(mu)
    with np.errstate(divide="ignore"):
        own_var = np.where(curv > 0, 2.0 / curv, np.inf)
    tau2 = theta.var(axis=0, ddof=1) - np.mean(np.minimum(own_var, 1.0), axis=0)
    return mu, np.clip(tau2, 0.0, None)


def _shrunk_fit(
    terms: Callable[[np.ndarray], Terms], own: np.ndarray, curv: np.ndarray, mu: np.ndarray, tau2: np.ndarray
) -> tuple[np.ndarray, Terms, float]:
    """An episode's empirical-Bayes parameters, its terms with the prior's cost, and its effective parameters."""
    free = np.flatnonzero(tau2 > 0)
    if free.size == 0:
        return mu.copy(), terms(mu), 0.0

    def prior(u: np.ndarray) -> float:
        return float(np.sum((u[free] - mu[free]) ** 2 / tau2[free]))

    def objective(u: np.ndarray) -> float:
        return terms(u).j + prior(u)

    start = mu.copy()
    start[free] = own[free]
    u = local_search(objective, min((start, mu.copy()), key=objective), EVALS_PER_PARAM * free.size, free)
    h = np.clip(curv[free], 0.0, None)
    dof = float(np.sum(h / (h + 2.0 / tau2[free])))
    t = terms(u)
    return u, replace(t, prior_sum=t.prior_sum + prior(u), prior_n=t.prior_n + free.size), dof


def _intervals(theta: np.ndarray, curv: np.ndarray, box: ParamBox, seed: int) -> dict[str, dict[str, Any] | None]:
    """95 % intervals of each parameter's mean and spread (physical units), by a bootstrap over the episodes."""
    m = len(theta)
    idx = np.random.default_rng(seed).integers(0, m, size=(BOOTSTRAP, m))
    draws = [_mean_spread(theta[r], curv[r]) for r in idx]
    mus = np.array([a for a, _ in draws])
    taus = np.sqrt(np.array([b for _, b in draws]))
    tail = expanded_tail(m)
    out: dict[str, dict[str, Any] | None] = {}
    for p, (_, param) in enumerate(box.entries):
        span = param.high - param.low
        lo, hi = (param.low + span * float(np.quantile(mus[:, p], q)) for q in (tail, 1.0 - tail))
        out[param.name] = _entry(lo, hi, param.default)
        slo, shi = (span * float(np.quantile(taus[:, p], q)) for q in (tail, 1.0 - tail))
        out[param.name + SPREAD_SUFFIX] = _entry(slo, shi, 0.0)
    return out


def _entry(low: float, high: float, off: float) -> dict[str, Any]:
    """An interval entry as :func:`~drillgym.eval.diagnosis.intervals.parameter_intervals` writes them.

    No search edge: nothing is searched for it.
    """
    return {"low": low, "high": high, "contains_off": bool(low <= off <= high), "at_search_edge": False}


__all__ = ["fit_per_episode"]
