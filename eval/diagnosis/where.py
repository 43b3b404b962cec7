"""Whether the gap counts, and where it lies: by channel and stage, against the simulator's own level.

The gap of a set of episodes and the simulator's own level ``G₀`` (null replays: noise and a drawn specimen on) are
:mod:`drillgym.eval.diagnosis.gap`'s. :func:`gap_significance` says whether the excess is beyond ``G₀`` (bootstrap over
episodes); :func:`gap_map` gives every (channel, stage) cell's normalised gap, raw RMS and excess; :func:`locate`
names the cells holding the most excess, which the report states as the gap's location and the shape test
(:mod:`drillgym.eval.diagnosis.shape`) sums over regions (:func:`excess_cells`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.gap import Terms, pooled
from drillgym.eval.diagnosis.rank import BOOTSTRAP

GAP_RATIO_MIN = 1.1
"""The median episode's gap must exceed the simulator's own level by this factor to count."""


def gap_significance(real: list[Terms], null: list[Terms], seed: int = 0) -> dict[str, Any]:
    """Is the gap beyond the simulator's own scatter? (all episodes, bootstrap over episodes)."""
    g_null = pooled(null)
    ratios = np.array([(t.j / t.n) / g_null for t in real])
    dj = np.array([r.j - n.j for r, n in zip(real, null, strict=True)])
    nn = np.array([r.n for r in real])
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(real), size=(BOOTSTRAP, len(real)))
    excess = dj[idx].sum(axis=1) / nn[idx].sum(axis=1)
    low = float(np.quantile(excess, 0.025))
    median_ratio = float(np.median(ratios))
    return {
        "gap": pooled(real),
        "null": g_null,
        "median_episode_ratio": median_ratio,
        "excess_ci_low": low,
        "significant": bool(low > 0.0 and median_ratio >= GAP_RATIO_MIN),
    }


def gap_map(terms: list[Terms], null: list[Terms]) -> dict[str, Any]:
    """Gap by channel and stage: normalised (≈ 1 where the sim explains the data), raw RMS, excess."""
    tot = sum(terms, Terms.zeros())
    nul = sum(null, Terms.zeros())
    with np.errstate(invalid="ignore", divide="ignore"):
        norm = tot.cell_sum / tot.cell_n
        rms = np.sqrt(tot.rms_sum / tot.cell_n)
        null_norm = np.where(nul.cell_n > 0, nul.cell_sum / nul.cell_n, 0.0)
    excess = tot.cell_sum - tot.cell_n * null_norm
    return {
        "channels": list(ALL_CHANNELS),
        "stages": list(STAGES),
        "normalised": _nested(norm.T),
        "null": _nested(np.where(nul.cell_n > 0, null_norm, np.nan).T),
        "rms": _nested(rms.T),
        "excess": _nested(excess.T),
    }


def gap_and_own_level(terms: list[Terms], null: list[Terms]) -> tuple[np.ndarray, np.ndarray]:
    """Summed terms of ``terms`` per (stage, channel) cell, and what the simulator's own level (``null``) gives them."""
    tot = sum(terms, Terms.zeros())
    nul = sum(null, Terms.zeros())
    with np.errstate(invalid="ignore", divide="ignore"):
        null_norm = np.where(nul.cell_n > 0, nul.cell_sum / nul.cell_n, 0.0)
    return tot.cell_sum, tot.cell_n * null_norm


def excess_cells(terms: list[Terms], null: list[Terms]) -> np.ndarray:
    """Excess gap of ``terms`` over the simulator's own level per (stage, channel) cell, clipped at 0, (6, 18)."""
    gap, own = gap_and_own_level(terms, null)
    return np.clip(gap - own, 0.0, None)


def locate(terms: list[Terms], null: list[Terms], top: int = 3) -> list[dict[str, Any]]:
    """The cells holding the most excess gap (channel, stage, share of the total excess)."""
    excess = excess_cells(terms, null)
    total = float(excess.sum()) or 1.0
    order = np.argsort(excess, axis=None)[::-1][:top]
    out = []
    for k in order:
        s, c = np.unravel_index(k, excess.shape)
        out.append({"channel": ALL_CHANNELS[c], "stage": STAGES[s], "share": float(excess[s, c] / total)})
    return out


def _nested(a: np.ndarray) -> list[list[float | None]]:
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in a]
