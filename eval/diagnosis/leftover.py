"""The leftover search: after one effect is named, is what it leaves structured, and does a second effect fit it?

What the named single leaves on the held-out episodes is read as the gap is (:func:`~drillgym.eval.diagnosis.shape.
region_excess`). It is **structured** when it is more than :data:`~drillgym.eval.diagnosis.verdict.
LEFTOVER_REPORT_RATIO` times the simulator's own level and one region holds at least
:data:`~drillgym.eval.diagnosis.shape.SHAPE_SHARE_MIN` of it: the shape of a missing effect rather than scatter
spread over every channel. The second effects were searched as pairs with the named one (forward selection from
the best singles, :mod:`drillgym.eval.diagnosis.diagnose`); the search reports the pair that takes most of the
leftover in that region, and why it was not named, or says that none takes any of it.
"""

from __future__ import annotations

from typing import Any

from drillgym.eval.diagnosis.gap import Terms, pooled
from drillgym.eval.diagnosis.pairs import pair_improves, pair_roles, second_is_real
from drillgym.eval.diagnosis.rank import ModelScore, singles_by_name
from drillgym.eval.diagnosis.shape import SHAPE_REMOVE_MIN, SHAPE_SHARE_MIN, region_excess

STRUCTURED_RATIO = 3.0
"""A leftover above this many times the simulator's own level can be structured (the summary's leftover report's
bar, :data:`drillgym.eval.diagnosis.verdict.LEFTOVER_REPORT_RATIO`)."""


def leftover_search(named: ModelScore, scores: list[ModelScore], null: list[Terms]) -> dict[str, Any] | None:
    """The leftover of a named single and the best second effect for it; None for a named pair.

    Returns:
        ``structured``; ``region`` and ``share`` (the region holding most of the leftover's excess and its share of
        it); ``pairs`` (how many pairs with the named effect were fitted); ``best`` (for a structured leftover: the
        pair removing most of the leftover there, with ``removed`` (share, 0–1) and ``why_not`` (why it was not
        named), or None when no pair was fitted or none removes any); ``note``: the sentence for the report.
    """
    if len(named.fit.names) != 1:
        return None
    left = region_excess(named.fit.ho_terms, null)
    total = sum(left.values())
    region, amount = max(left.items(), key=lambda kv: kv[1]) if left else ("", 0.0)
    share = amount / total if total > 0 else 0.0
    g_null = pooled(null)
    structured = bool(named.leftover_ratio > STRUCTURED_RATIO and share >= SHAPE_SHARE_MIN)
    pairs = [s for s in scores if len(s.fit.names) == 2 and named.fit.names[0] in s.fit.names]
    out: dict[str, Any] = {
        "structured": structured,
        "region": region,
        "share": share,
        "pairs": len(pairs),
        "best": None,
    }
    if not structured:
        out["note"] = (
            "what the named effect leaves is not structured (no region holds much of it above the simulator's level)"
        )
        return out
    best, removed = None, 0.0
    for p in pairs:
        r = (amount - region_excess(p.fit.ho_terms, null)[region]) / amount if amount > 0 else 0.0
        if r > removed:
            best, removed = p, r
    if best is None:
        why = "no pair with it was fitted" if not pairs else "no second effect removes any of it"
        out["note"] = f"the leftover is structured ({100 * share:.0f} % at {region}); {why}"
        return out
    out["best"] = {
        "name": best.name,
        "removed": removed,
        "why_not": "named" if best.named else _why_not(best, named, scores, g_null, null, removed),
    }
    out["note"] = (
        f"the leftover is structured ({100 * share:.0f} % at {region}); the best second effect there is `{best.name}` "
        f"(it removes {100 * removed:.0f} % of it): {out['best']['why_not']}"
    )
    return out


def _why_not(
    pair: ModelScore, named: ModelScore, scores: list[ModelScore], g_null: float, null: list[Terms], removed: float
) -> str:
    """Why ``pair`` was not named on top of ``named``."""
    if removed < SHAPE_REMOVE_MIN:
        return f"it removes less than {100 * SHAPE_REMOVE_MIN:.0f} % of the leftover there: none fits"
    if pair.shape is not None and not pair.shape["passes"]:
        return f"not the gap's shape ({pair.shape['reason']})"
    if not pair_improves(pair, named, g_null):
        return "not surely better than the named effect alone"
    first, second = pair_roles(pair, singles_by_name(scores))
    if first is not None and not second_is_real(pair, first, second, null):
        return "its second effect is not shown to be one (a patch on the first one's form cannot be ruled out)"
    return "not nameable (below the naming bars)"
