"""95 % intervals of a fitted model's parameters: a bootstrap over the calibration episodes.

A fit evaluates its model at many points (grid, compass search, refits), each with every calibration
episode's gap terms (:attr:`~drillgym.eval.diagnosis.fit.FitResult.samples`). A bootstrap resample of the
episodes weights those terms; its fit is the evaluated point with the lowest resampled gap
``Σ w J / Σ w N``, refined along each parameter by a parabola through it and its evaluated neighbours.
Percentiles of the resampled fits, per parameter, are the interval: the **expanded percentile interval**
(Hesterberg 2015), whose tails are those of a t interval on the resampled episodes, ``Φ(−√(n/(n−1)) t_{n−1})``
(:func:`expanded_tail`). The plain 2.5 and 97.5 percentiles are too narrow for the few episodes a diagnosis
calibrates on (a bootstrap of n values spreads like ``√((n−1)/n)`` standard errors, and the mean of a
handful of values is t-, not normally, distributed): with 6 episodes they are the 0.24 and 99.76 percentiles.

No replay is run for it: the interval is over the points the search visited, which cluster around the
fit (the compass search tries ± 1/16 … 1/1024 of each parameter's range there), so an interval reaching
the edge of the visited region (``at_search_edge``) means "at least this wide". A parameter the search
held fixed (the first effect of a forward-selected pair) gets no interval. Episodes, not blocks, are
resampled: blocks of one episode share its specimen, its noise draw and the candidate's misfit of the
reality's form, so they are not independent.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.context import Spec

BOOTSTRAP = 4000
"""Bootstrap resamples of the calibration episodes (the expanded tails are far out: ~10 resamples beyond each end)."""
LEVEL = 0.95
"""Coverage of the intervals."""


def expanded_tail(n: int, level: float = LEVEL) -> float:
    """Tail probability of the expanded percentile interval of ``n`` resampled units (Hesterberg 2015).

    ``Φ(−√(n/(n−1)) · t_{n−1, (1+level)/2})``: 0.0024 for 6 units, 0.0085 for 10, → (1 − level)/2 as n grows.
    """
    if n < 2:
        return (1.0 - level) / 2.0
    from scipy import stats  # ~0.6 s to import: not in every diagnosis worker, which never needs it

    t = float(stats.t.ppf(0.5 + level / 2.0, n - 1))
    return float(stats.norm.cdf(-math.sqrt(n / (n - 1.0)) * t))


def parameter_intervals(
    samples: Sequence[tuple[Spec, np.ndarray | None, np.ndarray | None]], seed: int = 0
) -> dict[str, dict[str, dict[str, Any] | None]]:
    """Per effect and parameter: ``low``, ``high`` (SI), ``contains_off``, ``at_search_edge``, or None if held.

    ``samples``: a fit's evaluated points with each calibration episode's ``J`` and ``N`` there.
    """
    points = _usable(samples)
    if not points:
        return {}
    keys, values, j, n = _arrays(points)
    m = j.shape[1]
    idx = np.random.default_rng(seed).integers(0, m, size=(BOOTSTRAP, m))
    counts = np.zeros((BOOTSTRAP, m))  # how often each episode is drawn in each resample
    np.add.at(counts, (np.arange(BOOTSTRAP)[:, None], idx), 1.0)
    objective = (counts @ j.T) / (counts @ n.T)  # (B, P)
    best = np.argmin(objective, axis=1)
    chosen = _refined(values, objective, best)
    tail = expanded_tail(j.shape[1])
    out: dict[str, dict[str, dict[str, Any] | None]] = {}
    for k, (name, param) in enumerate(keys):
        spread = values[:, k]
        entry: dict[str, Any] | None = None
        if spread.max() > spread.min():
            low, high = (float(np.quantile(chosen[:, k], q)) for q in (tail, 1.0 - tail))
            off = _off_value(name, param)
            entry = {
                "low": low,
                "high": high,
                "contains_off": bool(low <= off <= high),
                "at_search_edge": bool(low <= spread.min() or high >= spread.max()),
            }
        out.setdefault(name, {})[param] = entry
    return out


def refined_minimum(
    samples: Sequence[tuple[Spec, np.ndarray | None, np.ndarray | None]],
) -> dict[str, dict[str, float]]:
    """The minimum of the pooled gap over a fit's evaluated points, refined along each parameter by a parabola.

    The point estimate the intervals' resamples are made of, on all episodes at once: finer than the search's
    last step (1/1024 of each range), where it stopped. Per effect and parameter (SI); empty without points.
    """
    points = _usable(samples)
    if not points:
        return {}
    keys, values, j, n = _arrays(points)
    objective = (j.sum(axis=1) / n.sum(axis=1))[None, :]
    chosen = _refined(values, objective, np.argmin(objective, axis=1))[0]
    out: dict[str, dict[str, float]] = {}
    for (name, param), v in zip(keys, chosen, strict=True):
        out.setdefault(name, {})[param] = float(v)
    return out


def _usable(
    samples: Sequence[tuple[Spec, np.ndarray | None, np.ndarray | None]],
) -> list[tuple[Spec, np.ndarray, np.ndarray]]:
    """The evaluated points with every episode's terms, each point once.

    Two searches may share points (a fit and its refit): a point listed twice has no neighbour on one side of its
    copy, so no parabola through it.
    """
    unique: dict[Spec, tuple[Spec, np.ndarray, np.ndarray]] = {}
    for spec, j, n in samples:
        if j is not None and n is not None and np.isfinite(j).all():
            unique[spec] = (spec, j, n)
    return list(unique.values())


def _arrays(
    points: list[tuple[Spec, np.ndarray, np.ndarray]],
) -> tuple[list[tuple[str, str]], np.ndarray, np.ndarray, np.ndarray]:
    """``(effect, parameter)`` keys, the points' values (P, K), and each episode's ``J`` and ``N`` there (P, E)."""
    keys = [(name, param) for name, values in points[0][0] for param, _ in values]
    values = np.array([[v for _, vals in spec for _, v in vals] for spec, _, _ in points])
    return keys, values, np.array([p[1] for p in points]), np.array([p[2] for p in points])


def _refined(values: np.ndarray, objective: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Each resample's fit, refined per parameter between the evaluated points next to its best one.

    Along each parameter, the best point's nearest evaluated neighbours on either side (the other
    parameters equal) and the resampled gap there define a parabola; its vertex, kept between the two
    neighbours, is the estimate. Without it the estimate snaps to the evaluated points, and an interval
    narrower than their spacing would come out as a single value.
    """
    chosen = values[best].copy()
    rows = np.arange(best.size)
    for k in range(values.shape[1]):
        left, right = _neighbours(values, k)
        lo, hi = left[best], right[best]
        ok = (lo >= 0) & (hi >= 0)
        if not ok.any():
            continue
        r, b, a, c = rows[ok], best[ok], lo[ok], hi[ok]
        x0, x1, x2 = values[a, k], values[b, k], values[c, k]
        f0, f1, f2 = objective[r, a], objective[r, b], objective[r, c]
        num = (x1 - x0) ** 2 * (f1 - f2) - (x1 - x2) ** 2 * (f1 - f0)
        den = (x1 - x0) * (f1 - f2) - (x1 - x2) * (f1 - f0)
        with np.errstate(divide="ignore", invalid="ignore"):
            vertex = np.where(den != 0.0, x1 - 0.5 * num / den, x1)
        chosen[ok, k] = np.clip(vertex, x0, x2)
    return chosen


def _neighbours(values: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """For each point, the evaluated point just below and just above it along parameter ``k`` (-1: none)."""
    left = np.full(len(values), -1)
    right = np.full(len(values), -1)
    others = np.delete(values, k, axis=1)
    lines: dict[bytes, list[int]] = {}
    for i, row in enumerate(others):
        lines.setdefault(row.tobytes(), []).append(i)
    for members in lines.values():
        order = sorted(members, key=lambda i: values[i, k])
        for a, b in itertools.pairwise(order):
            if values[b, k] > values[a, k]:
                right[a], left[b] = b, a
    return left, right


def off_point_inside(intervals: dict[str, dict[str, dict[str, Any] | None]], names: Sequence[str]) -> list[str]:
    """The effects of ``names`` whose every interval contains the value that switches them off.

    Such an effect is not told apart from its absence by the calibration episodes: it is not named.
    An effect with no interval at all (every parameter held) is not judged here.
    """
    out = []
    for name in names:
        entries = [v for v in intervals.get(name, {}).values() if v is not None]
        if entries and all(v["contains_off"] for v in entries):
            out.append(name)
    return out


def _off_value(effect: str, param: str) -> float:
    return float(next(p.default for p in EFFECTS[effect].params if p.name == param))
