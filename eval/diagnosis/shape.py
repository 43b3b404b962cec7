"""The shape test: a model is named only if its predicted change has the gap's shape, not only its size.

The held-out excess gap (each (stage, channel) cell's terms over the simulator's own level, clipped at 0, as
:func:`~drillgym.eval.diagnosis.where.locate` reads it) is summed over **regions**: a stage group (before contact,
entry, stable, retract) crossed with a channel group (lateral force, thrust, each also as HF: the power about the
0.1 s block means, so the spectrum's high band; torque, tracker, joint angles). Every region holding at least
:data:`SHAPE_SHARE_MIN` of the excess must lose at least :data:`SHAPE_REMOVE_MIN` of its own excess under the model. A model whose shrink comes
from one part of the gap while another large part stays untouched (an effect that acts only while the tool cuts,
fitted to a gap that is there before contact too; a lateral effect fitted to a gap on the thrust; a once-per-turn
force fitted to a broadband one) is refused, with the region, its share and what the model removed there as the
reason. Point estimates on the held-out episodes: the rule is a check of shape, the bootstrap bars of
:mod:`~drillgym.eval.diagnosis.rank` already judge how sure the shrink is.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.eval.diagnosis.channels import (
    ALL_CHANNELS,
    FORCE_CHANNELS,
    HF_CHANNELS,
    Q_CHANNELS,
    STAGES,
    TORQUE_CHANNELS,
    TRACKER_CHANNELS,
)
from drillgym.eval.diagnosis.gap import Terms
from drillgym.eval.diagnosis.rank import ModelScore
from drillgym.eval.diagnosis.where import excess_cells

SHAPE_SHARE_MIN = 0.25
"""A region holding at least this share of the held-out excess gap must be explained in part."""
SHAPE_REMOVE_MIN = 0.2
"""... the model must remove at least this share of that region's excess."""
STAGE_GROUPS = {
    "before contact": ("approach",),
    "entry": ("entry1", "entry2", "entry3"),
    "stable": ("stable",),
    "retract": ("retract",),
}
"""Stage groups of a region."""
CHANNEL_GROUPS = {
    "lateral force": FORCE_CHANNELS[:2],
    "thrust": FORCE_CHANNELS[2:],
    "lateral force HF": HF_CHANNELS[:2],
    "thrust HF": HF_CHANNELS[2:],
    "torque": TORQUE_CHANNELS,
    "tracker": TRACKER_CHANNELS,
    "joint angles": Q_CHANNELS,
}
"""Channel groups of a region."""


def region_masks() -> dict[str, np.ndarray]:
    """Each region's (stage, channel) cells: every stage group crossed with every channel group."""
    out = {}
    for cg, channels in CHANNEL_GROUPS.items():
        for sg, stages in STAGE_GROUPS.items():
            mask = np.zeros((len(STAGES), len(ALL_CHANNELS)), dtype=bool)
            for s in stages:
                for c in channels:
                    mask[STAGES.index(s), ALL_CHANNELS.index(c)] = True
            out[f"{cg}, {sg}"] = mask
    return out


REGIONS = region_masks()
"""Region name (``"channel group, stage group"``) -> its (stage, channel) cells."""


def region_excess(terms: list[Terms], null: list[Terms]) -> dict[str, float]:
    """Excess gap of ``terms`` over the simulator's own level (``null``) summed over each region's cells."""
    excess = excess_cells(terms, null)
    return {name: float(excess[mask].sum()) for name, mask in REGIONS.items()}


def shape_test(model: ModelScore, before: list[Terms], null: list[Terms]) -> dict[str, Any]:
    """Does ``model`` explain every large region of the held-out gap (``before``: the terms without a model)?

    Returns:
        ``name``; ``passes``; ``regions``: each region holding at least :data:`SHAPE_SHARE_MIN` of the excess, with
        its ``share`` of it and the share of its own excess the model ``removed`` (negative: it made it worse);
        ``reason``: for a refused model, the first failing region in words (else None).
    """
    b = region_excess(before, null)
    a = region_excess(model.fit.ho_terms, null)
    total = sum(b.values())
    regions: list[dict[str, Any]] = []
    for name, eb in sorted(b.items(), key=lambda kv: -kv[1]):
        share = eb / total if total > 0 else 0.0
        if share < SHAPE_SHARE_MIN:
            continue
        removed = (eb - a[name]) / eb
        regions.append({"region": name, "share": share, "removed": removed, "passes": removed >= SHAPE_REMOVE_MIN})
    failing = [r for r in regions if not r["passes"]]
    reason = None
    if failing:
        r = failing[0]
        what = "makes it worse" if r["removed"] < 0 else f"removes {100 * r['removed']:.0f} % of it"
        reason = f"the gap has {100 * r['share']:.0f} % of its excess at {r['region']}; the model {what}"
    return {"name": model.name, "passes": not failing, "regions": regions, "reason": reason}
