"""When a pair of effects is named over the best single, and the guards on what an effect predicts where only it acts.

A pair is one of the best singles with another effect fitted on top (forward selection, then refitted jointly).
It is named over the best single (:func:`pair_beats`) when it is surely better (:func:`pair_improves`: better in
:data:`PAIR_P_MIN` of the bootstrap resamples, removing at least :data:`PAIR_RESIDUAL_SHRINK_MIN` of the excess gap
the single leaves) and its second effect is a second effect rather than a patch on the first one's form
(:func:`second_is_real`): it removes the gap where only its physics reaches (:func:`second_on_own_cells`), or it
explains alone at least :data:`PAIR_ALONE_MIN` of what it adds (:func:`second_stands_alone`) without worsening the
gap where only it reaches (:func:`second_contradicted`). A pair whose second effect is shown on its own cells needs
only be surely better: what the first leaves elsewhere may be its own form's misfit. A single effect has the same
guard before contact (:func:`single_contradicted`). Pairs whose second effect is not shown to be one are reported
(:func:`possible_second_effects`). The scores these rules read: :mod:`drillgym.eval.diagnosis.rank`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, GROUP_OF, STAGES
from drillgym.eval.diagnosis.gap import Terms
from drillgym.eval.diagnosis.rank import BOOTSTRAP, ModelScore, p_better, singles_by_name

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
    a second effect rather than a patch on the first one's form (:func:`second_is_real`). A second effect shown on
    its own cells (:func:`second_on_own_cells`: the first surely leaves a gap where only the second acts, and the
    pair surely removes half of it) needs only be surely better overall (in :data:`PAIR_P_MIN` of the resamples),
    not to remove half of everything the first leaves: the rest may be the first effect's form, in cells the second
    cannot reach (a stick-out error whose tool also loads the sensor differently before contact, with an arm offset
    on top that only the tracker shows before contact).
    """
    g = None if null is None else _own_cell_gaps(pair, first, null)
    if g is not None and g.removed():  # shown on its own cells (pair_improves implies the same p_better bar)
        return p_better(pair, best) >= PAIR_P_MIN
    return (
        pair_improves(pair, best, null_gap)
        and second_stands_alone(pair, first, second)
        and not (g is not None and g.worsened())
    )


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
