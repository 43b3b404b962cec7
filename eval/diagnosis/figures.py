"""Figures of a diagnosis: the gap map, the ranking, overlays of one episode, force-residual spectra."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy import signal

from drillgym.envs.constants import FT_RATE_HZ
from drillgym.eval.diagnosis.channels import LF_CHANNELS, STAGES

STAGE_COLOURS = ("#ffffff", "#fde0c5", "#facba6", "#f8b58b", "#dfe7f2", "#eeeeee")


def gap_text(value: float) -> str:
    """A normalised gap as printed in a cell: ``<0.01`` below the map's floor (no ``5.5e-12``), else 2-3 digits."""
    if value < 0.01:
        return "<0.01"
    return f"{value:.2g}" if value < 10 else f"{value:.0f}"


def plot_gap_map(where: dict[str, Any], after: dict[str, Any] | None, path: Path) -> Path:
    """Heat map of the normalised gap (channel × stage; 1 = the simulator's own scatter), before/after."""
    panels = [("gap before (all episodes)", where)] + (
        [("held-out gap with the named effect(s)", after)] if after else []
    )
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 7.5), squeeze=False)
    tables = [
        np.array([[np.nan if v is None else v for v in row] for row in m["normalised"]], dtype=float) for _, m in panels
    ]
    top = max(3.0, *(float(np.nanmax(np.log10(np.clip(t, 1e-2, None)), initial=0.0)) for t in tables))
    for ax, (title, m), values in zip(axes[0], panels, tables, strict=True):
        shown = np.log10(np.clip(values, 1e-2, None))
        im = ax.imshow(shown, cmap="magma_r", vmin=-1, vmax=top, aspect="auto")  # one colour scale for all panels
        ax.set_xticks(range(len(m["stages"])), m["stages"], rotation=35, ha="right")
        ax.set_yticks(range(len(m["channels"])), m["channels"])
        for (r, c), v in np.ndenumerate(values):
            if np.isfinite(v):
                ax.text(
                    c,
                    r,
                    gap_text(v),
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="white" if shown[r, c] > 1.5 else "black",
                )
        ax.set_title(title, fontsize=10)
        fig.colorbar(im, ax=ax, fraction=0.04, label="log10 normalised gap (0 = sim's own scatter)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_ranking(effects: list[dict[str, Any]], path: Path, top: int = 10) -> Path:
    """Held-out shrink of each model with its 95 % interval, best score first."""
    rows = effects[:top][::-1]
    fig, ax = plt.subplots(figsize=(7.5, max(2.6, 0.45 * len(rows) + 1.4)))
    y = np.arange(len(rows))
    shrink = np.array([r["shrink"] for r in rows], dtype=float)
    lo = np.array([r["ci_low"] for r in rows], dtype=float)
    hi = np.array([r["ci_high"] for r in rows], dtype=float)
    colours = ["#2a7f62" if r["named"] else "#9aa5b1" for r in rows]
    ax.barh(y, np.nan_to_num(shrink), color=colours)
    ax.errorbar(
        np.nan_to_num(shrink), y, xerr=[np.nan_to_num(shrink - lo), np.nan_to_num(hi - shrink)], fmt="none", ecolor="k"
    )
    ax.set_yticks(y, [r["name"] for r in rows])
    ax.axvline(0.5, color="k", ls=":", lw=0.8)
    ax.set_xlim(-0.2, 1.1)
    ax.set_xlabel("held-out gap shrink (share of the excess removed; green = named)")
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")  # the x label is never clipped
    plt.close(fig)
    return path


def plot_overlays(
    name: str, t_s: np.ndarray, stage: np.ndarray, traces: dict[str, np.ndarray], path: Path, channels: list[str]
) -> Path:
    """Real vs replays of one episode on a few channels, stages shaded."""
    fig, axes = plt.subplots(len(channels), 1, figsize=(9, 2.1 * len(channels)), sharex=True)
    axes = np.atleast_1d(axes)
    edges = np.flatnonzero(np.diff(stage)) + 1
    bounds = np.concatenate([[0], edges, [len(stage)]])
    for ax, ch in zip(axes, channels, strict=True):
        c = LF_CHANNELS.index(ch)
        for a, b in itertools.pairwise(bounds):
            ax.axvspan(t_s[a], t_s[b - 1], color=STAGE_COLOURS[int(stage[a])], lw=0)
        for label, x in traces.items():
            ax.plot(
                t_s, x[:, c], lw=0.9 if label == "real" else 1.1, label=label, alpha=0.8 if label == "real" else 1.0
            )
        ax.set_ylabel(ch, fontsize=8)
    axes[0].legend(fontsize=7, ncol=len(traces))
    axes[0].set_title(f"{name}: real vs replays (shading: {', '.join(STAGES)})", fontsize=9)
    axes[-1].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_spectra(residuals: dict[str, np.ndarray], path: Path) -> Path:
    """Welch PSD of force residuals (real − nominal replay) against the simulator's own (null − nominal)."""
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2), sharey=True)
    for k, ax in enumerate(axes):
        for label, r in residuals.items():
            x = r[:, k][np.isfinite(r[:, k])]
            if x.size > 64:
                f, p = signal.welch(x, fs=FT_RATE_HZ, nperseg=min(256, x.size))
                ax.semilogy(f, p, label=label, lw=1)
        ax.set_title(LF_CHANNELS[k], fontsize=9)
        ax.set_xlabel("Hz")
    axes[0].set_ylabel("PSD of residual (N²/Hz)")
    if axes[0].get_legend_handles_labels()[0]:  # no line when every residual is too short for a spectrum
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
