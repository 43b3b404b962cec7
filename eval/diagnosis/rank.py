"""Held-out scores, bootstrap intervals, the parameter penalty and the naming bar.

Gap of a set of episodes: ``G = Σ J / Σ N``, the mean normalised term (:mod:`drillgym.eval.diagnosis.gap`);
the simulator's own level ``G₀`` comes from null replays (noise and a drawn specimen on). For a model
(one effect or a pair, fitted on the calibration episodes) on the held-out episodes:

* ``shrink = (G_before − G_after) / (G_before − G₀)``: the share of the excess gap the model removes;
* ``score = Σ J_after + k ln Σ N``: a BIC-like penalised misfit (k fitted parameters; lower is better);
* bootstrap over held-out episodes (:data:`BOOTSTRAP`): a 95 % interval of the shrink and the
  probability that each model has the best score.

A gap counts when it is significant (:func:`~drillgym.eval.diagnosis.where.gap_significance`); a model is nameable when it removes at least
:data:`NAME_SHRINK_MIN` of the excess (interval above :data:`NAME_CI_LOW_MIN`) and beats "no effect" on the
penalised score (:func:`nameable`). When a pair is named over a single, and the guards on what an effect predicts
where only its physics acts: :mod:`drillgym.eval.diagnosis.pairs`; the verdict on all of it:
:mod:`drillgym.eval.diagnosis.verdict`. Where the gap lies: :mod:`drillgym.eval.diagnosis.where`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import physics_set
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import Terms

BOOTSTRAP = 1000
"""Bootstrap resamples of the held-out episodes."""
NAME_SHRINK_MIN = 0.5
"""A model is named only if it removes at least this share of the held-out excess gap."""
NAME_CI_LOW_MIN = 0.2
"""... and the lower end of its 95 % interval is above this."""
RESCUE_CI_LOW_MIN = 0.5
"""A model named only after the best single effect was refined on a gap that had nothing named: the lower end of
its shrink interval must be at least this (a second look is not taken on a model that is barely better than none)."""


@dataclass
class ModelScore:
    """A fitted model's held-out numbers."""

    fit: FitResult
    before: float
    after: float
    shrink: float
    ci_low: float
    ci_high: float
    score: float
    leftover_ratio: float = math.nan
    """Held-out gap after the model over the simulator's own level (1: nothing left but the sim's own scatter)."""
    p_best: float = 0.0
    named: bool = False
    intervals: dict[str, dict[str, dict[str, Any] | None]] = field(default_factory=dict)
    """95 % intervals of the parameters (:func:`drillgym.eval.diagnosis.intervals.parameter_intervals`)."""
    shape: dict[str, Any] | None = None
    """The shape test (:func:`drillgym.eval.diagnosis.shape.shape_test`), for a nameable model; else None."""
    shrink_draws: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    score_draws: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    @property
    def name(self) -> str:
        """``"a"`` or ``"a+b"``."""
        return "+".join(self.fit.names)

    def to_json(self) -> dict[str, Any]:
        """JSON entry of the ``effects`` list."""
        return {
            "name": self.name,
            "effects": list(self.fit.names),
            "params": {n: p for n, p in zip(self.fit.names, self.fit.params, strict=True)},
            "param_intervals": self.intervals,
            "n_params": self.fit.n_params,
            "penalty_params": self.fit.penalty_params,
            "per_episode": self.fit.per_episode,
            "heldout_gap_before": self.before,
            "heldout_gap_after": self.after,
            "shrink": self.shrink,
            "leftover_ratio": self.leftover_ratio,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "score": self.score,
            "p_best": self.p_best,
            "named": self.named,
            "shape": self.shape,
            "fit": {
                "calibration_gap": self.fit.cal_objective,
                "evaluations": self.fit.evaluations,
                "replays": self.fit.replays,
                "wall_s": self.fit.wall_s,
                "error": self.fit.error,
            },
        }


def score_models(fits: list[FitResult], before: list[Terms], null: list[Terms], seed: int = 0) -> list[ModelScore]:
    """Held-out scores with bootstrap intervals, sorted by penalised score (best first)."""
    rng = np.random.default_rng(seed)
    m = len(before)
    idx = rng.integers(0, m, size=(BOOTSTRAP, m))
    jb = np.array([t.j for t in before])
    nb = np.array([t.n for t in before])
    jn = np.array([t.j for t in null])
    nn = np.array([t.n for t in null])
    g_before, g_null = jb.sum() / nb.sum(), jn.sum() / nn.sum()
    b_before = jb[idx].sum(1) / nb[idx].sum(1)
    b_null = jn[idx].sum(1) / nn[idx].sum(1)
    out = []
    for f in fits:
        if f.error or len(f.ho_terms) != m:
            continue
        ja = np.array([t.j for t in f.ho_terms])
        na = np.array([t.n for t in f.ho_terms])
        g_after = ja.sum() / na.sum()
        shrink = _shrink(g_before, g_after, g_null)
        b_shrink = _shrink(b_before, ja[idx].sum(1) / na[idx].sum(1), b_null)
        counted = f.n_params if f.penalty_params is None else f.penalty_params  # a random effect's effective count
        penalty = counted * math.log(max(na.sum(), 2.0))
        score = float(ja.sum() + penalty)
        lo, hi = np.nanquantile(b_shrink, [0.025, 0.975]) if np.isfinite(b_shrink).any() else (math.nan, math.nan)
        out.append(
            ModelScore(
                fit=f,
                before=float(g_before),
                after=float(g_after),
                shrink=float(shrink),
                ci_low=float(lo),
                ci_high=float(hi),
                score=score,
                leftover_ratio=float(g_after / g_null) if g_null > 0 else math.nan,
                shrink_draws=b_shrink,
                score_draws=ja[idx].sum(1) + penalty,
            )
        )
    if out:
        draws = np.stack([s.score_draws for s in out])
        best = np.bincount(np.argmin(draws, axis=0), minlength=len(out)) / draws.shape[1]
        for s, p in zip(out, best, strict=True):
            s.p_best = float(p)
    return sorted(out, key=lambda s: s.score)


def _shrink(before: Any, after: Any, null: Any) -> Any:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.asarray(before) > np.asarray(null), (before - after) / (before - null), np.nan)


def baseline_score(before: list[Terms]) -> float:
    """Penalised score of "no effect" (no parameters)."""
    return float(sum(t.j for t in before))


def nameable(s: ModelScore, s0: float) -> bool:
    """Does a model remove enough of the gap, surely enough, and beat no effect at all?"""
    return s.shrink >= NAME_SHRINK_MIN and s.ci_low >= NAME_CI_LOW_MIN and s.score < s0


def p_better(a: ModelScore, b: ModelScore) -> float:
    """Share of the bootstrap resamples in which ``a`` scores better (lower) than ``b``."""
    return float(np.mean(a.score_draws < b.score_draws))


def singles_by_name(scores: list[ModelScore]) -> dict[str, ModelScore]:
    """The single-effect models of ``scores``, by effect name."""
    return {s.fit.names[0]: s for s in scores if len(s.fit.names) == 1}


ALTERNATIVE_P_MIN = 0.05
"""A model with other effects that scores better than the named one in at least this share of the
bootstrap resamples is reported as an alternative the data cannot rule out."""


def alternatives(scores: list[ModelScore], named: ModelScore, s0: float) -> list[dict[str, Any]]:
    """Nameable models with other effects that the held-out data do not rule out against ``named``.

    A model that holds every named effect plus others is not an alternative (it adds to the named
    explanation); one that swaps an effect for another is (e.g. a tool-length error for a kinematic
    offset, which move the tool alike at nearby poses). A pair is left out when one of its effects is
    an alternative on its own.

    Returns:
        ``{"name", "effects", "p_better"}`` per alternative, most likely first; ``p_better`` is the share
        of resamples in which it scores better than the named model.
    """
    out: list[dict[str, Any]] = []
    sets: list[set[str]] = []
    for s in scores:
        if s is named or set(named.fit.names) <= set(s.fit.names) or not nameable(s, s0):
            continue
        p = p_better(s, named)
        if p >= ALTERNATIVE_P_MIN:
            out.append({"name": s.name, "effects": list(s.fit.names), "p_better": p})
            sets.append(set(s.fit.names))
    minimal = [a for a, e in zip(out, sets, strict=True) if not any(o < e for o in sets)]
    return sorted(minimal, key=lambda a: -a["p_better"])


def other_physics(named: list[str], alts: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The entries of :func:`alternatives` (``alts``) whose physics differ from the named effects' (``named``).

    A per-episode and a shared F/T drift are one physics: only an alternative of other physics leaves the question
    which one the cell follows (``drillgym separate``).
    """
    return [a for a in alts if physics_set(a["effects"]) != physics_set(named)]
