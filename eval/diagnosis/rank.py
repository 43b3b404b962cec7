"""Held-out scores, bootstrap intervals, the parameter penalty, and the verdict.

Gap of a set of episodes: ``G = Σ J / Σ N``, the mean normalised term (:mod:`drillgym.eval.diagnosis.gap`);
the simulator's own level ``G₀`` comes from null replays (noise and a drawn specimen on). For a model
(one effect or a pair, fitted on the calibration episodes) on the held-out episodes:

* ``shrink = (G_before − G_after) / (G_before − G₀)``: the share of the excess gap the model removes;
* ``score = Σ J_after + k ln Σ N``: a BIC-like penalised misfit (k fitted parameters; lower is better);
* bootstrap over held-out episodes (:data:`BOOTSTRAP`): a 95 % interval of the shrink and the
  probability that each model has the best score.

Verdict: ``no_gap`` unless the gap is significant (:func:`gap_significance`); ``explained`` when the
best-scoring model removes at least :data:`NAME_SHRINK_MIN` of the excess (interval above
:data:`NAME_CI_LOW_MIN`) and beats "no effect" on the penalised score; a pair (one of the best singles
with another effect fitted on top) is named instead when it passes the same test and
:func:`pair_beats` the best single; otherwise
``unexplained``, located at the channel and stage with the largest excess gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, GROUP_OF, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import Terms, pooled

BOOTSTRAP = 1000
"""Bootstrap resamples of the held-out episodes."""
GAP_RATIO_MIN = 1.1
"""The median episode's gap must exceed the simulator's own level by this factor to count."""
NAME_SHRINK_MIN = 0.5
"""A model is named only if it removes at least this share of the held-out excess gap."""
NAME_CI_LOW_MIN = 0.2
"""... and the lower end of its 95 % interval is above this."""
PAIR_P_MIN = 0.95
"""A pair beats its best single in at least this share of the bootstrap resamples."""
PAIR_RESIDUAL_SHRINK_MIN = 0.5
"""... removes at least this share of the excess gap the single leaves ..."""
PAIR_ALONE_MIN = 0.3
"""... and its second effect alone removes at least this share of what it adds on top of the first (or
the pair removes the gap where only the second effect's physics reaches: :func:`second_on_own_cells`)."""
PAIR_TRY_RESIDUAL = 2.0
"""Pairs (the best single plus each other candidate) are tried when the best single leaves a held-out gap
of at least this many times ``G₀``."""


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


def pair_improves(pair: ModelScore, best: ModelScore, null_gap: float) -> bool:
    """Is ``pair`` surely better than the best single ``best``?

    It must score better in :data:`PAIR_P_MIN` of the resamples and remove at least
    :data:`PAIR_RESIDUAL_SHRINK_MIN` of the excess gap ``best`` leaves.
    """
    left = best.after - null_gap
    return (
        p_better(pair, best) >= PAIR_P_MIN and left > 0 and (best.after - pair.after) / left >= PAIR_RESIDUAL_SHRINK_MIN
    )


def second_stands_alone(pair: ModelScore, first: ModelScore, second: ModelScore | None) -> bool:
    """Does the pair's second effect explain on its own what it adds on top of ``first``?

    Alone it must remove at least :data:`PAIR_ALONE_MIN` of what it adds. Two real effects add up; an
    effect that only helps alongside another may be correcting the other's misfit.
    """
    added = first.after - pair.after
    if second is None or added <= 0:
        return False
    return second.before - second.after >= PAIR_ALONE_MIN * added


def own_cells(first: str, second: str) -> np.ndarray | None:
    """(stage, channel) cells where ``second``'s physics reaches and ``first``'s cannot; None if unknown.

    From the effects' declared channel groups (``channels``, and ``channels_before_contact`` for the
    approach), which tests check against the simulator: e.g. a joint friction reaches the joint angles,
    which no bone effect moves, and a kinematic offset shows on the tracker before contact, where a tool
    length error or any bone effect changes nothing.
    """
    a, b = EFFECTS.get(first), EFFECTS.get(second)
    if a is None or b is None:
        return None
    mask = np.zeros((len(STAGES), len(ALL_CHANNELS)), dtype=bool)
    approach = STAGES.index("approach")
    for c, channel in enumerate(ALL_CHANNELS):
        group = GROUP_OF[channel]
        mask[:, c] = group in b.channels and group not in a.channels
        mask[approach, c] |= group in b.channels_before_contact and group not in a.channels_before_contact
    return mask


def singles_by_name(scores: list[ModelScore]) -> dict[str, ModelScore]:
    """The single-effect models of ``scores``, by effect name."""
    return {s.fit.names[0]: s for s in scores if len(s.fit.names) == 1}


def pair_roles(pair: ModelScore, singles: dict[str, ModelScore]) -> tuple[ModelScore | None, ModelScore | None]:
    """The pair's first and second effects as singles: the better-scoring single first.

    A pair is named instead of a single effect, so what has to be shown is the effect it adds to the stronger
    of its two: forward selection may have built it the other way round (a weak first effect with the real one
    fitted on top, which then "adds" everything it explains alone). Missing singles are None (first stays the
    pair's own first then).
    """
    a, b = (singles.get(n) for n in pair.fit.names)
    if a is not None and b is not None and b.score < a.score:
        return b, a
    return a, b


def _other(pair: ModelScore, first: ModelScore) -> str:
    """The pair's effect that is not ``first``'s."""
    return next((n for n in pair.fit.names if n != first.fit.names[0]), pair.fit.names[-1])


@dataclass
class _OwnCellGaps:
    """Held-out gaps on a pair's own cells: pooled values and their bootstrap draws (first, pair, null)."""

    first: float
    pair: float
    null: float
    first_draws: np.ndarray
    pair_draws: np.ndarray
    null_draws: np.ndarray

    def removed(self) -> bool:
        """The first effect surely leaves a gap there and the pair surely removes enough of it."""
        return bool(
            self.first > self.null
            and np.mean(self.first_draws > self.null_draws) >= PAIR_P_MIN
            and np.mean(self.pair_draws < self.first_draws) >= PAIR_P_MIN
            and (self.first - self.pair) / (self.first - self.null) >= PAIR_RESIDUAL_SHRINK_MIN
        )

    def worsened(self) -> bool:
        """The pair surely makes the gap there larger than the first effect alone."""
        return bool(np.mean(self.pair_draws > self.first_draws) >= PAIR_P_MIN)


def _own_cell_gaps(
    pair: ModelScore, first: ModelScore, null: list[Terms], mask: np.ndarray | None = None, seed: int = 0
) -> _OwnCellGaps | None:
    """Gaps on ``mask`` (default: the :func:`own_cells` of the pair's second effect); None without cells."""
    if mask is None and len(pair.fit.names) == 2:
        mask = own_cells(first.fit.names[0], _other(pair, first))
    return _cell_gaps(first.fit.ho_terms, pair.fit.ho_terms, null, mask, seed)


def _cell_gaps(
    first: list[Terms], pair: list[Terms], null: list[Terms], mask: np.ndarray | None, seed: int = 0
) -> _OwnCellGaps | None:
    """Held-out gaps on ``mask`` of two models' terms and the null's, with bootstrap draws; None without cells."""
    m = len(null)
    if mask is None or not mask.any() or m == 0 or len(pair) != m or len(first) != m:
        return None

    def part(terms: list[Terms]) -> tuple[np.ndarray, np.ndarray]:
        return np.array([t.cell_sum[mask].sum() for t in terms]), np.array([t.cell_n[mask].sum() for t in terms])

    parts = [part(first), part(pair), part(null)]
    if min(n.sum() for _, n in parts) <= 0:
        return None
    idx = np.random.default_rng(seed).integers(0, m, size=(BOOTSTRAP, m))
    with np.errstate(invalid="ignore", divide="ignore"):
        draws = [j[idx].sum(1) / n[idx].sum(1) for j, n in parts]
    f, p, z = (float(j.sum() / n.sum()) for j, n in parts)
    return _OwnCellGaps(f, p, z, *draws)


def second_on_own_cells(pair: ModelScore, first: ModelScore, null: list[Terms], seed: int = 0) -> bool:
    """Does the pair remove most of the gap ``first`` leaves where only its second effect reaches?

    On the :func:`own_cells` of the pair's second effect, ``first``'s held-out gap must surely exceed
    the simulator's own level there, and the pair must surely lower it (both in :data:`PAIR_P_MIN` of the
    bootstrap resamples) by at least :data:`PAIR_RESIDUAL_SHRINK_MIN` of that excess. A second effect
    hidden behind a much larger first one still shows where the first cannot act; a patch on the first
    one's form has no such cells.
    """
    g = _own_cell_gaps(pair, first, null, seed=seed)
    return g is not None and g.removed()


def second_contradicted(pair: ModelScore, first: ModelScore, null: list[Terms], seed: int = 0) -> bool:
    """Does the pair's second effect surely worsen the gap where only it reaches?

    E.g. an F/T drift fitted on top of a density model to bend the force along the hole (a drift in time
    looks like a gradient in depth at a steady feed) predicts a drifting force before contact, which the
    data do not show: the pair's gap there exceeds the first effect's in :data:`PAIR_P_MIN` of the
    resamples.
    """
    g = _own_cell_gaps(pair, first, null, seed=seed)
    return g is not None and g.worsened()


def before_contact_cells(effect: str) -> np.ndarray | None:
    """(stage, channel) cells of the approach where ``effect``'s physics acts before contact; None if unknown.

    Before the drill touches the bone only the effects that declare ``channels_before_contact`` change anything
    (an F/T drift the force, a kinematic offset the tracker); the data there are the plainest check of them.
    """
    e = EFFECTS.get(effect)
    if e is None or not e.channels_before_contact:
        return None
    mask = np.zeros((len(STAGES), len(ALL_CHANNELS)), dtype=bool)
    approach = STAGES.index("approach")
    for c, channel in enumerate(ALL_CHANNELS):
        mask[approach, c] = GROUP_OF[channel] in e.channels_before_contact
    return mask


def single_contradicted(single: ModelScore, before: list[Terms], null: list[Terms], seed: int = 0) -> bool:
    """Does a single effect surely worsen the held-out gap before contact, where only its own physics acts?

    The guard a pair's second effect has (:func:`second_contradicted`), for a single named effect against no
    effect at all: e.g. an F/T drift fitted to a gain error on the lateral axes bends the force during the cut,
    but it also predicts a force before contact that the data do not show. On the effect's
    :func:`before_contact_cells`, its gap must not exceed the simulator-as-is gap in :data:`PAIR_P_MIN` of the
    bootstrap resamples.
    """
    if len(single.fit.names) != 1:
        return False
    g = _cell_gaps(before, single.fit.ho_terms, null, before_contact_cells(single.fit.names[0]), seed)
    return g is not None and g.worsened()


def second_is_real(
    pair: ModelScore, first: ModelScore, second: ModelScore | None, null: list[Terms] | None = None
) -> bool:
    """Is the pair's second effect a second effect rather than a patch on the first one's form?

    Either the pair removes the gap where only the second effect's physics reaches
    (:func:`second_on_own_cells`), or the second effect explains on its own what it adds
    (:func:`second_stands_alone`) without being contradicted where only it reaches
    (:func:`second_contradicted`). Without the null terms only the "alone" test is made.
    """
    g = None if null is None else _own_cell_gaps(pair, first, null)
    if g is not None and g.removed():
        return True
    return second_stands_alone(pair, first, second) and not (g is not None and g.worsened())


def second_effect_evidence(
    pair: ModelScore, first: ModelScore, second: ModelScore | None, null: list[Terms]
) -> dict[str, Any]:
    """How a pair's second effect is shown to be one (the ``second_effect_evidence`` of ``diagnosis.json``).

    Returns:
        ``second``; ``alone`` (:func:`second_stands_alone`); ``own_cells`` (:func:`second_on_own_cells`);
        ``contradicted`` (:func:`second_contradicted`); ``own_groups``: the channel groups of those cells,
        with the held-out gap there of the first effect alone, of the pair and of the simulator
        (``own_gap_first``, ``own_gap_pair``, ``own_gap_null``; None without such cells).
    """
    mask = own_cells(first.fit.names[0], _other(pair, first))
    g = None if mask is None else _own_cell_gaps(pair, first, null, mask)
    groups = sorted({GROUP_OF[ALL_CHANNELS[c]] for c in np.flatnonzero(mask.any(axis=0))}) if mask is not None else []
    return {
        "second": _other(pair, first),
        "alone": second_stands_alone(pair, first, second),
        "own_cells": g is not None and g.removed(),
        "contradicted": g is not None and g.worsened(),
        "own_groups": groups,
        "own_gap_first": None if g is None else g.first,
        "own_gap_pair": None if g is None else g.pair,
        "own_gap_null": None if g is None else g.null,
    }


def pair_beats(
    pair: ModelScore,
    best: ModelScore,
    first: ModelScore,
    second: ModelScore | None,
    null_gap: float,
    null: list[Terms] | None = None,
) -> bool:
    """Is the pair (``first``'s fit plus ``second``'s effect fitted on top) surely better than ``best``?

    ``best`` is the best single: the pair must :func:`pair_improves` on it, and its second effect must be
    a second effect rather than a patch on the first one's form (:func:`second_is_real`).
    """
    return pair_improves(pair, best, null_gap) and second_is_real(pair, first, second, null)


def possible_second_effects(
    scores: list[ModelScore], named: ModelScore, null_gap: float, null: list[Terms] | None = None
) -> list[dict[str, Any]]:
    """Pairs with the named single effect that improve on it but whose second effect is not shown to be one.

    Such a second effect may be real but hidden behind a much larger first one, or a patch on the first
    one's form: the data cannot tell, so it is reported, not named. The second effect is the pair's other one,
    whichever order forward selection built the pair in (:func:`pair_roles`); each is listed once, with its
    best-scoring pair.

    Returns:
        ``{"name", "second", "heldout_gap_after", "p_better"}`` per pair, best score first.
    """
    if len(named.fit.names) != 1:
        return []
    singles = singles_by_name(scores)
    out: list[dict[str, Any]] = []
    for s in scores:
        if len(s.fit.names) != 2 or named.fit.names[0] not in s.fit.names:
            continue
        other = _other(s, named)
        if any(x["second"] == other for x in out):
            continue
        if pair_improves(s, named, null_gap) and not second_is_real(s, named, singles.get(other), null):
            out.append({"name": s.name, "second": other, "heldout_gap_after": s.after, "p_better": p_better(s, named)})
    return out


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


def locate(terms: list[Terms], null: list[Terms], top: int = 3) -> list[dict[str, Any]]:
    """The cells holding the most excess gap (channel, stage, share of the total excess)."""
    tot = sum(terms, Terms.zeros())
    nul = sum(null, Terms.zeros())
    with np.errstate(invalid="ignore", divide="ignore"):
        null_norm = np.where(nul.cell_n > 0, nul.cell_sum / nul.cell_n, 0.0)
    excess = np.clip(tot.cell_sum - tot.cell_n * null_norm, 0.0, None)
    total = float(excess.sum()) or 1.0
    order = np.argsort(excess, axis=None)[::-1][:top]
    out = []
    for k in order:
        s, c = np.unravel_index(k, excess.shape)
        out.append({"channel": ALL_CHANNELS[c], "stage": STAGES[s], "share": float(excess[s, c] / total)})
    return out


def _nested(a: np.ndarray) -> list[list[float | None]]:
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in a]
