"""Where the gap lies before and after the per-specimen hardness fit, and whether the fit moved it.

The location (:func:`~drillgym.eval.diagnosis.where.locate`: the cells holding the most excess gap over all
episodes) is read twice, each against the null replays read the same way: on the **raw** gap, every specimen
taken as preset, and on the gap **after the per-specimen fit**, each episode's specimen hardness profiled out
(:func:`~drillgym.eval.diagnosis.gap.gap_terms`). The fit can move it: where one channel is wrong in a way a harder
or softer specimen partly mimics (a torque gain error), the fit bends the specimen to match that channel, and
another channel the specimen also moves (the thrust, read correctly) then holds the largest excess. The two reads
agree when their top cells lie in the same channel group (force, torque, tracker, joint angles:
:data:`~drillgym.eval.diagnosis.channels.GROUP_OF`); when they do not, the report gives both.
"""

from __future__ import annotations

from typing import Any

from drillgym.eval.diagnosis.channels import GROUP_OF
from drillgym.eval.diagnosis.context import DiagnosisData
from drillgym.eval.diagnosis.where import locate


def location_check(data: DiagnosisData, top: int = 3) -> dict[str, Any]:
    """The gap's location on the raw gap and after the per-specimen fit.

    Returns:
        ``raw`` and ``after_specimen_fit``: up to ``top`` cells each (``channel``, ``stage``, ``share`` of that
        read's total excess, 0–1); ``agree``: whether the two top cells lie in one channel group; ``note``: a
        sentence for the report when they do not (else None).
    """
    raw = locate(data.raw_terms, data.null_raw_terms, top)
    fitted = locate(data.baseline_terms, data.null_terms, top)
    agree = GROUP_OF[raw[0]["channel"]] == GROUP_OF[fitted[0]["channel"]]
    note = None
    if not agree:
        note = (
            f"the per-specimen hardness fit moves the gap's location: before it, most of the excess lies at "
            f"{_cell(raw[0])}; after it, at {_cell(fitted[0])}. A gap that a harder or softer specimen partly "
            f"mimics in one channel is absorbed there and shows in another the specimen also moves: read both"
        )
    return {"raw": raw, "after_specimen_fit": fitted, "agree": agree, "note": note}


def _cell(c: dict[str, Any]) -> str:
    return f"{c['channel']}, {c['stage']} ({100 * c['share']:.0f} %)"
