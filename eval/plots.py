"""Figures a reader would rather look at than read (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from drillgym.controllers.rollout import EpisodeResult
from drillgym.envs.metrics import FORCE_FILTER_SAMPLES, moving_average

STAGE_COLOURS = {1: "#fde0c5", 2: "#facba6", 3: "#f8b58b", 4: "#e0ecf4"}


def label_span(ax: plt.Axes, lo: float, hi: float, text: str, xlim: tuple[float, float]) -> None:
    """Label the part of ``[lo, hi]`` inside ``xlim`` at its centre, at the top of the axes; nothing outside.

    A span narrower than 8 % of the axis gets its text without the word "stage".
    """
    lo, hi = max(lo, xlim[0]), min(hi, xlim[1])
    if hi <= lo:
        return
    short = (hi - lo) < 0.08 * (xlim[1] - xlim[0])
    ax.text(
        0.5 * (lo + hi),
        0.97,
        text.removeprefix("stage ") if short else text,
        transform=ax.get_xaxis_transform(),
        ha="center",
        va="top",
        fontsize=7,
        color="0.35",
        clip_on=True,
    )


def shade_stages(ax: plt.Axes, t_s: np.ndarray, stage: np.ndarray, xlim: tuple[float, float] | None = None) -> None:
    """Shade the engagement stages 1-4 behind a time plot and label each inside ``xlim`` (default: the data)."""
    if xlim is None:
        xlim = (float(t_s[0]), float(t_s[-1]))
    ax.set_xlim(*xlim)
    start = 0
    for i in range(1, len(stage) + 1):
        if i == len(stage) or stage[i] != stage[start]:
            s = int(stage[start])
            if s in STAGE_COLOURS:
                ax.axvspan(t_s[start], t_s[i - 1], color=STAGE_COLOURS[s], lw=0, zorder=0)
                label_span(ax, float(t_s[start]), float(t_s[i - 1]), f"stage {s}", xlim)
            start = i


def plot_episode(result: EpisodeResult, path: Path, title: str = "") -> None:
    """Lateral force (F/T, 0.2 s filter) and tip deviation over time, engagement stages shaded."""
    tr = result.trace
    t, stage = tr["t_s"], tr["stage"]
    force = moving_average(tr["ft_force_n"], FORCE_FILTER_SAMPLES)
    lateral = np.hypot(force[:, 0], force[:, 1])
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.5, 5.2), sharex=True)
    for ax in (a1, a2):
        shade_stages(ax, t, stage)
        ax.grid(alpha=0.3)
    a1.plot(t, lateral, color="C3", lw=1.2, label="lateral force |Fxy| (F/T, 20-sample mean)")
    a1.plot(t, -force[:, 2] / 10.0, color="0.4", lw=0.8, ls="--", label="thrust / 10")
    a1.set_ylabel("force (N)")
    a1.legend(loc="upper right", fontsize=8)
    a2.plot(t, tr["deviation_m"] * 1e3, color="C0", lw=1.2, label="tip deviation from the planned axis")
    a2.set_ylabel("deviation (mm)")
    a2.set_xlabel("time (s)")
    a2.legend(loc="upper right", fontsize=8)
    m = result.metrics
    a1.set_title(
        (title + "\n" if title else "")
        + f"mean dev {m['deviation_mean_mm']:.3f} mm, max |Fxy| {m['lateral_force_max_n']:.2f} N, "
        f"stable {m['lateral_force_stable_n']:.2f} N, hole offset {m['hole_offset_mm']:.2f} mm",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
