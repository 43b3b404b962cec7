"""``drillgym separate``'s record: ``separation.json``, ``separation.md`` and a figure of the separation per change."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from drillgym.eval.diagnosis.separate import Change

SEPARATED = 2.0
"""A separation from this on is called one the holes would show (the other model's gap twice the true one's)."""


def change_of(entry: dict[str, Any]) -> Change:
    """The :class:`~drillgym.eval.diagnosis.separate.Change` of a record's entry (``knob``, ``value``)."""
    return Change(entry["knob"], entry["value"])


def change_label(entry: dict[str, Any]) -> str:
    """Words for a change (``knob``, ``value``): ``0.25 x the logged feed``, ``an interaction angle of 0 deg``."""
    return change_of(entry).label()


def row_of(pair: dict[str, Any], change: dict[str, Any], truth: str) -> dict[str, Any]:
    """The row of ``pair`` for ``change`` with ``truth`` playing the reality."""
    return next(r for r in pair["rows"] if change_of(r) == change_of(change) and r["truth"] == truth)


def separation_line(pair: dict[str, Any]) -> str:
    """One sentence: where the two models are furthest apart, and how far apart they are as logged."""
    best = pair["best"]
    logged = next((w["separation"] for w in pair["weakest"] if change_of(w).as_logged), None)
    as_logged = "" if logged is None else f"; as logged {logged:.3g}"
    if logged is not None and logged >= SEPARATED:
        # Either model as the cell would have ruled the other out on holes like the logged ones; the logs did not.
        as_logged += (
            " (already apart there: neither is exactly the cell's form, the physics may still be right; both miss the "
            "logs by more than they differ)"
        )
    if best["separation"] < SEPARATED:
        return f"no change tried separates them (at most {best['separation']:.3g}, at {change_label(best)}{as_logged})"
    return (
        f"furthest apart at {change_label(best)}: the wrong one leaves {best['separation']:.3g} times the right one's "
        f"gap there{as_logged}"
    )


def write_separation(result: dict[str, Any], out: Path, figure: bool = True) -> dict[str, Path]:
    """Write ``separation.json``, ``separation.md`` and (optionally) ``separation.png`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {"json": out / "separation.json", "report": out / "separation.md"}
    paths["json"].write_text(json.dumps(result, indent=2))
    if figure:
        paths["figure"] = plot_separation(result, out / "separation.png")
    paths["report"].write_text(_markdown(result, "figure" in paths))
    return paths


def _markdown(result: dict[str, Any], figure: bool) -> str:
    named = result["named"]
    lines = [
        f"# Telling {named} from the models not ruled out",
        "",
        f"Holes re-simulated: {', '.join(result['holes'])} (their scenario and controller), with each change below "
        "and each model in turn playing the reality at its fitted values. The separation is the other model's gap on "
        "those holes over the true one's (the diagnosis's gap; about 1: the holes cannot tell them apart). A change "
        f"counts by the smaller of the two directions; from {SEPARATED:g} on, such holes would show which one the cell "
        "follows. `*`: the other model's excess is beyond the holes' scatter.",
        "",
    ]
    for pair in result["pairs"]:
        other = pair["other"]
        lines += [
            f"## {named} against {other}",
            "",
            f"**{separation_line(pair)}.**",
            "",
            f"| change | feeds (mm/s) | angles (deg) | {other} judged, {named} true | {named} judged, {other} true |",
            "|---|---|---|---|---|",
        ]
        for c in result["changes"]:
            a, b = row_of(pair, c, named), row_of(pair, c, other)
            feeds = ", ".join(f"{x:.3g}" for x in a["feeds_mm_s"])
            betas = ", ".join(f"{x:.3g}" for x in a["betas_deg"])
            lines.append(f"| {change_label(c)} | {feeds} | {betas} | {_cell(a)} | {_cell(b)} |")
        lines.append("")
    if figure:
        lines += ["![separation per change](separation.png)", ""]
    return "\n".join(lines)


def _cell(row: dict[str, Any]) -> str:
    return f"{row['separation']:.3g}{' *' if row['significant'] else ''}"


def plot_separation(result: dict[str, Any], path: Path) -> Path:
    """Bars of the separation per change, both directions, one panel per model pair (log scale)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    pairs = result["pairs"]
    grid = result["changes"]
    fig, axes = plt.subplots(1, len(pairs), figsize=(max(5.0, 1.1 * len(grid)) * len(pairs), 3.6), squeeze=False)
    x = np.arange(len(grid))
    for ax, pair in zip(axes[0], pairs, strict=True):
        for k, (truth, colour) in enumerate(((result["named"], "#2b8cbe"), (pair["other"], "#e6550d"))):
            values = [row_of(pair, c, truth)["separation"] for c in grid]
            ax.bar(x + (k - 0.5) * 0.38, values, width=0.38, color=colour, label=f"{truth} true")
        ax.axhline(1.0, color="0.3", lw=0.8)
        ax.axhline(SEPARATED, color="0.3", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.set_xticks(x, [change_of(c).label(short=True) for c in grid], fontsize=8)
        ax.set_xlabel("change of the logged holes (feed factor, interaction angle)")
        ax.set_ylabel("other model's gap / true model's")
        ax.set_title(f"{result['named']} vs {pair['other']}", fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
