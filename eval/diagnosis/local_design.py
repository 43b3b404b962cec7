"""Intervals of a named model's parameters from a local design around its fit and a quadratic surrogate.

The search's own points (:mod:`drillgym.eval.diagnosis.intervals`) cluster on the lines of the compass search
through the fit; where two parameters trade off along a shallow, slanted valley (a resonance's amplitude and
damping, a registration's displacements), the resampled minima would lie along the valley, where no point was
evaluated, and the interval comes out narrower than the data allow. So the named model, once refined, is also
evaluated on a small design around its fit (:func:`design_points`: each parameter ± one step, and every pair of
parameters on the four diagonals; ``2K² + 1`` points for K parameters), in the same job, with every calibration
episode's gap terms. A full quadratic in the parameters fitted through the design's pooled gaps gives the gap's
curvature there (its Hessian H, which must be positive definite); each bootstrap resample of the episodes (the same
resamples as the search's intervals) weights the terms, and the slope ``g`` of the same fit through its resampled
gaps moves the fit by one Newton step, ``−H⁻¹ g`` (a one-step bootstrap: the resample's minimum of the pooled
curvature). Percentiles of those are the interval, expanded as the search's are
(:func:`~drillgym.eval.diagnosis.intervals.expanded_tail`). Along a shallow valley H is nearly singular and the
steps are long: a step beyond the design is kept, clipped to the parameter's range, and the interval marked
``at_search_edge`` (it rests on the quadratic beyond the points evaluated).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.context import Spec
from drillgym.eval.diagnosis.intervals import BOOTSTRAP, expanded_tail

DESIGN_STEP = 1 / 64
"""Step of the design in each parameter (share of its range): 16 times the compass search's finest."""
MAX_DESIGN_PARAMS = 3
"""A model with more parameters gets no design (``2K² + 1`` replays of the calibration episodes: 19 for three)."""


def _offsets(x: float) -> tuple[float, float]:
    """The design's two steps (in units of :data:`DESIGN_STEP`) along a parameter at unit-box value ``x``."""
    if x - DESIGN_STEP < 0.0:
        return 1.0, 2.0
    if x + DESIGN_STEP > 1.0:
        return -1.0, -2.0
    return -1.0, 1.0


def design_points(u: np.ndarray) -> list[np.ndarray]:
    """The centre ``u`` (unit box), two steps along each parameter, and four diagonal points per pair of them.

    A parameter at the edge of its range (a one-sided effect fitted at its off point) is stepped inward twice.
    """
    u = np.asarray(u, dtype=float)
    offs = [_offsets(float(x)) for x in u]
    points = [u.copy()]
    for i, steps in enumerate(offs):
        for s in steps:
            p = u.copy()
            p[i] += s * DESIGN_STEP
            points.append(p)
    for i, j in itertools.combinations(range(u.size), 2):
        for si, sj in itertools.product(offs[i], offs[j]):
            p = u.copy()
            p[i] += si * DESIGN_STEP
            p[j] += sj * DESIGN_STEP
            points.append(p)
    return points


def _features(x: np.ndarray) -> np.ndarray:
    """Quadratic features ``1, x_i, x_i x_j (i ≤ j)`` of offsets ``x`` (P, K)."""
    k = x.shape[1]
    cols = [np.ones(len(x)), *(x[:, i] for i in range(k))]
    cols += [x[:, i] * x[:, j] for i, j in itertools.combinations_with_replacement(range(k), 2)]
    return np.column_stack(cols)


def _hessian(coef: np.ndarray, k: int) -> np.ndarray:
    """The Hessian (K, K) of a quadratic's coefficients (:func:`_features`' order)."""
    hess = np.zeros((k, k))
    for c, (a, b) in enumerate(itertools.combinations_with_replacement(range(k), 2)):
        hess[a, b] = hess[b, a] = coef[1 + k + c] * (2.0 if a == b else 1.0)
    return hess


def _unit(names: Sequence[str], spec: Spec) -> np.ndarray:
    """Unit-box vector of a spec (every parameter of ``names``, in the library's order)."""
    values = dict(spec)
    out = []
    for name in names:
        params = dict(values[name])
        out += [(params[p.name] - p.low) / (p.high - p.low) for p in EFFECTS[name].params]
    return np.array(out, dtype=float)


def design_intervals(
    names: Sequence[str],
    design: Sequence[Spec],
    samples: Sequence[tuple[Spec, np.ndarray | None, np.ndarray | None]],
    seed: int = 0,
) -> dict[str, dict[str, dict[str, Any] | None]] | None:
    """Per effect and parameter: ``low``, ``high`` (SI), ``contains_off``, ``at_search_edge``; None where unusable.

    ``design``: the design's specs (centre first); ``samples``: evaluated points with each calibration
    episode's ``J`` and ``N`` (the design's among them). None when a design point failed to replay or the pooled
    gap has no minimum there (its quadratic is not convex).
    """
    terms = {spec: (j, n) for spec, j, n in samples if j is not None and n is not None and np.isfinite(j).all()}
    if not design or any(spec not in terms for spec in design):
        return None
    u = np.array([_unit(names, spec) for spec in design])
    x = u - u[0]
    j = np.array([terms[spec][0] for spec in design])
    n = np.array([terms[spec][1] for spec in design])
    m, k = j.shape[1], x.shape[1]
    idx = np.random.default_rng(seed).integers(0, m, size=(BOOTSTRAP, m))
    counts = np.zeros((BOOTSTRAP, m))
    np.add.at(counts, (np.arange(BOOTSTRAP)[:, None], idx), 1.0)
    gap = (counts @ j.T) / (counts @ n.T)  # (B, P)
    fit = np.linalg.pinv(_features(x))  # least squares of a quadratic through the design
    hess = _hessian(fit @ (j.sum(axis=1) / n.sum(axis=1)), k)
    if np.linalg.eigvalsh(hess)[0] <= 0.0:
        return None
    grad = (gap @ fit.T)[:, 1 : 1 + k]  # each resample's slope at the centre
    chosen = np.clip(u[0] - np.linalg.solve(hess, grad.T).T, 0.0, 1.0)
    tail = expanded_tail(m)
    span_low, span_high = u.min(axis=0), u.max(axis=0)
    out: dict[str, dict[str, dict[str, Any] | None]] = {}
    col = 0
    for name in names:
        for p in EFFECTS[name].params:
            lo_u, hi_u = (float(np.quantile(chosen[:, col], q)) for q in (tail, 1.0 - tail))
            low, high = p.low + lo_u * (p.high - p.low), p.low + hi_u * (p.high - p.low)
            out.setdefault(name, {})[p.name] = {
                "low": low,
                "high": high,
                "contains_off": bool(low <= p.default <= high),
                "at_search_edge": bool(lo_u < span_low[col] or hi_u > span_high[col]),
            }
            col += 1
    return out


def widest(
    search: dict[str, dict[str, dict[str, Any] | None]], local: dict[str, dict[str, dict[str, Any] | None]] | None
) -> dict[str, dict[str, dict[str, Any] | None]]:
    """Each parameter's interval from the search's points and from the local design, joined: the wider of the two.

    Each can be too narrow in its own way (the search's where its points do not span a slanted valley; the
    design's where the gap has several basins, or is not quadratic over the interval), so the named model
    reports both (``search``, ``design``: ``[low, high]``) and their hull.
    """
    if local is None:
        return search
    out: dict[str, dict[str, dict[str, Any] | None]] = {}
    for name, params in search.items():
        for param, entry in params.items():
            other = local.get(name, {}).get(param)
            if entry is None or other is None:
                out.setdefault(name, {})[param] = entry
                continue
            low, high = min(entry["low"], other["low"]), max(entry["high"], other["high"])
            off = next(p.default for p in EFFECTS[name].params if p.name == param)
            out.setdefault(name, {})[param] = {
                "low": low,
                "high": high,
                "contains_off": bool(low <= off <= high),
                "at_search_edge": bool(entry["at_search_edge"] or other["at_search_edge"]),
                "search": [entry["low"], entry["high"]],
                "design": [other["low"], other["high"]],
            }
    return out
