"""The calibration screen as one picture: what each calibrated structure predicts for li2023 (matplotlib, headless)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from drillgym.eval.reproduce.paper import LI2023_COMPENSATED, LI2023_UNCOMPENSATED

LI2023_KP_GAP_MM = LI2023_COMPENSATED["deviation_mean_mm_kp1"] - LI2023_COMPENSATED["deviation_mean_mm"]
"""Li's deviation at KP 1 minus KP 4 (mm)."""
LI2023_FORCE_CHANGE_PCT = 100.0 * (
    LI2023_COMPENSATED["lateral_force_max_n"] / LI2023_UNCOMPENSATED["lateral_force_max_n"] - 1.0
)
"""Li's change of the peak lateral force with compensation (%)."""


def plot_screen(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """Peak-force change of li2023 (KP 4) vs none against the KP 1 − KP 4 deviation gap, one point per structure.

    Li's experiment sits in the lower-right quadrant (KP matters, force falls); the colour is the
    guidance exponent.
    """
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    gap = [r["kp1_deviation_mean_mm"] - r["kp4_deviation_mean_mm"] for r in rows]
    change = [100.0 * (r["kp4_lateral_force_max_n"] / r["none_lateral_force_max_n"] - 1.0) for r in rows]
    colour = [r["guidance_exponent"] for r in rows]
    sc = ax.scatter(gap, change, c=colour, cmap="viridis", s=28, edgecolors="k", linewidths=0.3)
    fig.colorbar(sc, ax=ax, label="guidance exponent")
    ax.scatter([LI2023_KP_GAP_MM], [LI2023_FORCE_CHANGE_PCT], marker="*", s=220, c="crimson", label="Li 2023")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.axvline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("deviation, li2023 KP 1 − KP 4 (mm)")
    ax.set_ylabel("peak lateral force, li2023 KP 4 vs none (%)")
    ax.set_title(f"{len(rows)} structures, each calibrated on the uncompensated run")
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
