"""Which training seed ships: a rule in the configuration, applied to held-in data only.

``drillgym train --seeds`` trains several seeds of one configuration; one of them becomes the shipped
policy. Picking the seed that judges best would pick it on the judge's episodes, so the rule
(``ship_rule`` of :class:`drillgym.training.config.TrainConfig`) reads only what each run measured on its own
selection episodes (``selection.json``, :mod:`drillgym.training.selection`: seeds of the selection namespace)
before the judge ran:

* ``selection_deviation``: among the seeds whose chosen model beat the base on its selection episodes
  (paired deviation CI below 0, peak force not significantly higher, drill time within the limit), the one
  with the lowest mean deviation there; if none beat the base, the lowest deviation of all; ties: the lower
  seed;
* ``none``: no seed is named.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drillgym.envs.errors import UserError, read_json


def selection_rows(out: Path, seeds: list[int]) -> list[dict[str, Any]]:
    """Each seed's chosen model's held-in figures from ``OUT/seedN/selection.json`` (missing: ``found`` False)."""
    rows = []
    for seed in seeds:
        path = out / f"seed{seed}" / "selection.json"
        row: dict[str, Any] = {"seed": seed, "found": path.exists()}
        if path.exists():
            selection = read_json(path)
            chosen = next(c for c in selection["candidates"] if c["candidate"] == selection["chosen"])
            row |= {
                "chosen": selection["chosen"],
                "deviation_mean_mm": float(chosen["deviation_mean_mm"]),
                "d_deviation_mm": float(chosen["d_deviation_mm"]),
                "beats_base": bool(chosen["better"] and chosen["feasible"]),
                "episodes": int(selection["episodes"]),
            }
        rows.append(row)
    return rows


def ship_seed(rows: list[dict[str, Any]], rule: str) -> int | None:
    """The seed the rule ships, from :func:`selection_rows` (None for ``none`` or when no seed has a selection).

    Raises:
        ValueError: an unknown rule.
    """
    if rule == "none":
        return None
    if rule != "selection_deviation":
        raise UserError(f"unknown ship rule {rule!r}; choose selection_deviation or none")
    found = [r for r in rows if r["found"]]
    if not found:
        return None
    pool = [r for r in found if r["beats_base"]] or found
    return int(min(pool, key=lambda r: (r["deviation_mean_mm"], r["seed"]))["seed"])


def describe(rows: list[dict[str, Any]], rule: str, shipped: int | None) -> list[str]:
    """Markdown lines: the rule, each seed's held-in figures, the seed it ships."""
    lines = [
        "## Which seed ships",
        "",
        f"Rule `{rule}` (from the configuration, held-in data only): {_RULE_TEXT.get(rule, rule)}",
        "",
    ]
    lines += [
        "| seed | chosen model | held-in deviation (mm) | Δ vs base (mm) | beats the base |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        if not r["found"]:
            lines.append(f"| {r['seed']} | (no selection.json) | | | |")
            continue
        beats = "yes" if r["beats_base"] else "no"
        lines.append(
            f"| {r['seed']} | {r['chosen']} | {r['deviation_mean_mm']:.4f} | {r['d_deviation_mm']:+.4f} | {beats} |"
        )
    lines += ["", f"**Ships: seed {shipped}**" if shipped is not None else "**No seed named.**", ""]
    return lines


_RULE_TEXT = {
    "selection_deviation": "the lowest deviation on its own selection episodes among the seeds whose model beat "
    "the base there (all seeds if none did); ties go to the lower seed.",
    "none": "no seed is named.",
}
