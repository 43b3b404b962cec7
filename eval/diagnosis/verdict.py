"""The diagnosis's decision: the verdict, the named model, where an unexplained gap lies, the summary line.

Pure functions of the held-out scores (:mod:`drillgym.eval.diagnosis.rank`); no replay is run here. The rules
(the bars are :mod:`~drillgym.eval.diagnosis.rank`'s constants):

* ``no_gap`` when the gap is not significant (:func:`~drillgym.eval.diagnosis.where.gap_significance`), whatever
  the models do;
* else the best-scoring single effect is named when it is
  :func:`~drillgym.eval.diagnosis.rank.nameable` (shrink ≥ 50 %, its 95 % interval's low end ≥ 20 %, a penalised
  score below "no effect"), does not fail the before-contact guard
  (:func:`~drillgym.eval.diagnosis.pairs.single_contradicted`) and passes the shape test
  (:func:`~drillgym.eval.diagnosis.shape.shape_test`, run on every nameable model);
* a pair is named instead when it is nameable, passes the shape test and
  :func:`~drillgym.eval.diagnosis.pairs.pair_beats` the best single (judged with its effects in
  :func:`~drillgym.eval.diagnosis.pairs.pair_roles`' order); of several such pairs, the best-scoring;
* otherwise ``unexplained``, located at the (channel, stage) cell holding the most excess gap over all episodes.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from drillgym.eval.diagnosis.channels import GROUP_OF
from drillgym.eval.diagnosis.context import DiagnosisData
from drillgym.eval.diagnosis.gap import pooled
from drillgym.eval.diagnosis.pairs import pair_beats, pair_roles, single_contradicted
from drillgym.eval.diagnosis.rank import ModelScore, baseline_score, nameable, singles_by_name
from drillgym.eval.diagnosis.shape import shape_test
from drillgym.eval.diagnosis.where import locate

LEFTOVER_REPORT_RATIO = 3.0
"""When a named model leaves a held-out gap above this many times the simulator's own level (``leftover_ratio``),
the summary says how much is left and where. It is a report, not a verdict: on the withheld-effect benchmark the
right candidate leaves from 1 to over 1000 times that level (the candidates are other forms of the same physics,
and the simulator's own level in the kinematic channels is tiny), so no ratio tells a missing effect apart."""


class Decision(NamedTuple):
    """The verdict and what it rests on."""

    verdict: str
    chosen: ModelScore | None
    location: dict[str, Any] | None
    guard: dict[str, Any] | None
    off_point: list[str]
    scores: list[ModelScore]
    rescue: dict[str, Any] | None = None
    """Where a significant gap had nothing named and the best single effect was refined: ``effect``, the model
    ``decided`` on after that (None: none), whether it was ``named`` and, when refused, the ``reason``."""


def decide(
    significance: dict[str, Any], scores: list[ModelScore], before: list[Any], data: DiagnosisData, null: list[Any]
) -> tuple[str, ModelScore | None, dict[str, Any] | None, dict[str, Any] | None]:
    """Verdict, named model, location and the best single's before-contact guard (``single_guard``).

    The guard is judged for the best-scoring single only, and only when it is nameable: then ``single_guard`` is
    ``{"effect", "contradicted"}`` and a contradicted single is not named (:func:`verdict`); else it is None.
    """
    s0 = baseline_score(before)
    for s in scores:
        s.shape = shape_test(s, before, null, data) if nameable(s, s0) else None
    single = best_single(scores)
    guard: dict[str, Any] | None = None
    contradicted = False
    if single is not None and nameable(single, s0):
        contradicted = single_contradicted(single, before, null)
        guard = {"effect": single.name, "contradicted": contradicted}
    name, chosen, location = verdict(significance, scores, before, data, null, contradicted)
    return name, chosen, location, guard


def best_single(scores: list[ModelScore]) -> ModelScore | None:
    """The best-scoring single effect (``scores`` best first, as ranked), or None."""
    return next((s for s in scores if len(s.fit.names) == 1), None)


def verdict(
    significance: dict[str, Any],
    scores: list[ModelScore],
    before: list[Any],
    data: DiagnosisData,
    null: list[Any],
    single_contradicted: bool = False,
) -> tuple[str, ModelScore | None, dict[str, Any] | None]:
    """Verdict, the named model (marked ``named``) and, when unexplained, where the gap lies.

    ``scores`` best first (as :func:`~drillgym.eval.diagnosis.rank.score_models` sorts them); ``before`` and
    ``null``: the held-out episodes' terms without a model and the simulator's own. ``single_contradicted``: the
    best single effect fails the before-contact guard (:func:`drillgym.eval.diagnosis.pairs.single_contradicted`)
    and is not named. The rules are the module docstring's.
    """
    if not significance["significant"]:
        return "no_gap", None, None
    s0 = baseline_score(before)
    singles = [s for s in scores if len(s.fit.names) == 1]
    best_single = singles[0] if singles else None
    chosen: ModelScore | None = None
    if best_single is not None and nameable(best_single, s0) and not single_contradicted and _shaped(best_single):
        chosen = best_single
    by_name = singles_by_name(singles)
    g_null = pooled(null)
    for p in (s for s in scores if len(s.fit.names) == 2):
        first, second = pair_roles(p, by_name)
        if best_single is None or first is None:
            continue
        if nameable(p, s0) and _shaped(p) and pair_beats(p, best_single, first, second, g_null, null):
            if chosen is None or chosen is best_single or p.score < chosen.score:
                chosen = p
    if chosen is None:
        return "unexplained", None, gap_location(data)
    chosen.named = True
    return "explained", chosen, None


def _shaped(s: ModelScore) -> bool:
    """Does ``s`` pass the shape test? (a model whose test was not run, e.g. a stub, passes)."""
    return s.shape is None or bool(s.shape["passes"])


def gap_location(data: DiagnosisData) -> dict[str, Any]:
    """Where the gap lies when nothing is named: the cell holding the most excess gap.

    Over all episodes (``data.baseline_terms`` against ``data.null_terms``): ``channel``, ``stage`` and ``share``
    (that cell's excess over the total, 0–1; :func:`~drillgym.eval.diagnosis.where.locate`).
    """
    top = locate(data.baseline_terms, data.null_terms, top=1)[0]
    return {"channel": top["channel"], "stage": top["stage"], "share": top["share"]}


def summary(
    verdict: str,
    chosen: ModelScore | None,
    location: dict[str, Any] | None,
    alts: list[dict[str, Any]],
    seconds: list[dict[str, Any]],
    leftover: dict[str, Any] | None = None,
    raw_location: dict[str, Any] | None = None,
) -> str:
    """The one-line ``summary`` of ``diagnosis.json``.

    ``no_gap``: "no significant gap …"; unexplained: "unexplained — located at CHANNEL, STAGE", followed by
    "(before the per-specimen hardness fit: CHANNEL, STAGE)" where ``raw_location``, the raw gap's top cell
    (:mod:`~drillgym.eval.diagnosis.location`), lies in another channel group; explained:
    "explained by A + B: held-out gap shrinks by S (LOW to HIGH)", shares in per cent rounded to whole ones, or to a
    tenth from 99.5 % up to (not including) 100 %, "nan" where not finite; then, where the model leaves more than
    :data:`LEFTOVER_REPORT_RATIO` times the simulator's own level, how much (and what it was before: the ratio times
    gap before over gap after) and in which cell; up to three alternatives (``alts``, with ``p_better``) and up to
    three possible second effects (``seconds``).
    """
    if verdict == "no_gap":
        return "no significant gap: the simulator explains these episodes within its own noise and specimen scatter"
    if chosen is None:
        assert location is not None
        text = f"unexplained — located at {location['channel']}, {location['stage']}"
        if raw_location is not None and GROUP_OF[raw_location["channel"]] != GROUP_OF[location["channel"]]:
            text += f" (before the per-specimen hardness fit: {raw_location['channel']}, {raw_location['stage']})"
        return text
    s = chosen
    pct = lambda v: "nan" if not math.isfinite(v) else (f"{100 * v:.1f} %" if 0.995 <= v < 1.0 else f"{100 * v:.0f} %")  # noqa: E731
    text = f"explained by {' + '.join(s.fit.names)}: held-out gap shrinks by {pct(s.shrink)} ({pct(s.ci_low)} to {pct(s.ci_high)})"
    if leftover is not None and leftover["ratio"] > LEFTOVER_REPORT_RATIO and leftover["cells"]:
        cell = leftover["cells"][0]
        was = leftover["ratio"] * s.before / s.after if s.after > 0 and math.isfinite(s.before) else math.nan
        before = f" (it was {was:.3g}x before)" if math.isfinite(was) else ""
        text += (
            f"; what is left is still {leftover['ratio']:.3g}x the simulator's own level{before}, most of it at "
            f"{cell['channel']}, {cell['stage']} ({pct(cell['share'])})"
        )
    if alts:
        text += "; not ruled out: " + ", ".join(f"{a['name']} (better in {pct(a['p_better'])})" for a in alts[:3])
    if seconds:
        names = ", ".join(x["second"] for x in seconds[:3])
        text += f"; a second effect may be present ({names}: better on top, not shown to act alone)"
    return text


__all__ = ["LEFTOVER_REPORT_RATIO", "Decision", "decide", "gap_location", "summary", "verdict"]
