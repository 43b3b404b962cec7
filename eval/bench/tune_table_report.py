"""``tune_table.md``, ``tune_table.png`` and ``evaluations.csv`` of a ``drillgym tune-table`` run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from drillgym.controllers.schedule_table import ScheduleTable


def evaluations_frame(results: list[dict[str, Any]], fields: tuple[str, ...]) -> pd.DataFrame:
    """One row per candidate of every anchor: its action per field, mean reward, deviation, force, time."""
    rows = []
    for res in results:
        for e in res["evaluations"]:
            row = {"anchor": res["name"], "eval": e["eval"]}
            row.update({f"a_{f}": v for f, v in zip(fields, e["action"], strict=True)})
            row.update({k: e[k] for k in ("reward", "deviation_mm", "force_n", "time_s")})
            rows.append(row)
    return pd.DataFrame(rows)


def write_report(out: Path, table: ScheduleTable, results: list[dict[str, Any]]) -> None:
    """Write the three files into ``out``."""
    spec = table.spec
    frame = evaluations_frame(results, spec.fields)
    frame.to_csv(out / "evaluations.csv", index=False)
    meta = table.meta
    lines = [
        f"# Gain-scheduling table on `{spec.base}`",
        "",
        f"{len(table.anchors)} anchors, {meta.get('seeds_per_anchor')} tuning episodes each (seed namespace "
        f"`tune`, from index {meta.get('seed_offset')}), at most {meta.get('evals_per_anchor')} candidates per "
        f"anchor (SciPy Nelder–Mead from `{spec.base}`): {meta.get('holes')} holes in {meta.get('wall_time_s')} s. "
        "Objective: mean paired schedule reward against the base on the same episodes (0 = the base).",
        "",
        "| anchor | reward | "
        + " | ".join(spec.fields)
        + " | deviation (mm) | base (mm) | peak force (N) | base (N) | time (s) | base (s) |",
        "|---|---|" + "---|" * (len(spec.fields) + 6),
    ]
    for anchor, res in zip(table.anchors, results, strict=True):
        values = spec.values(np.asarray(anchor.action))
        kept, b = res["chosen"], res["base"]
        lines.append(
            f"| {anchor.name} | {res['reward']:+.4f} | "
            + " | ".join(f"{values[f]:.3g}" for f in spec.fields)
            + f" | {kept['deviation_mm']:.4f} | {b['deviation_mm']:.4f} | {kept['force_n']:.3f} | {b['force_n']:.3f}"
            + f" | {kept['time_s']:.1f} | {b['time_s']:.1f} |"
        )
    (out / "tune_table.md").write_text("\n".join(lines) + "\n")
    _plot(out / "tune_table.png", frame)


def _plot(path: Path, frame: pd.DataFrame) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for name, group in frame.groupby("anchor", sort=False):
        ax.plot(group["eval"], group["reward"].cummax(), label=str(name), lw=1.2)
    ax.axhline(0.0, color="k", lw=0.8, ls=":")
    ax.set_xlabel("candidates evaluated (-)")
    ax.set_ylabel("best mean paired reward so far (-)")
    ax.set_title("tune-table: each anchor's Nelder–Mead search", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
