"""Benchmark figures (matplotlib, headless) from the long-form summary (:mod:`drillgym.eval.bench.summary`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

BAR_METRICS = {"deviation_mean_mm": "mean tip deviation (mm)", "lateral_force_max_n": "max lateral force (N)"}


def _stat(summary: pd.DataFrame, scenario: str, controller: str, metric: str) -> tuple[float, float, float]:
    sel = summary[(summary.scenario == scenario) & (summary.controller == controller) & (summary.metric == metric)]
    if sel.empty:
        return np.nan, np.nan, np.nan
    r = sel.iloc[0]
    return float(r["mean"]), float(r["ci_low"]), float(r["ci_high"])


def _yerr(stats: list[tuple[float, float, float]]) -> np.ndarray:
    m, lo, hi = (np.array(v) for v in zip(*stats, strict=True))
    return np.nan_to_num(np.vstack([m - lo, hi - m]))


def plot_bars(summary: pd.DataFrame, controllers: Sequence[str], path: Path, title: str = "") -> None:
    """Mean deviation and max lateral force per scenario and controller, 95% CI error bars."""
    scenarios = list(dict.fromkeys(summary["scenario"]))
    x = np.arange(len(scenarios))
    width = 0.8 / max(len(controllers), 1)
    stacked = len(scenarios) > 3
    size = (max(7.0, 0.9 * len(scenarios) + 2.0), 7.0) if stacked else (8.0, 4.0)
    fig, axes = plt.subplots(2 if stacked else 1, 1 if stacked else 2, figsize=size, squeeze=False)
    for ax, (metric, label) in zip(axes.flat, BAR_METRICS.items(), strict=True):
        for i, c in enumerate(controllers):
            st = [_stat(summary, s, c, metric) for s in scenarios]
            ax.bar(
                x + (i - (len(controllers) - 1) / 2) * width,
                [v[0] for v in st],
                width,
                yerr=_yerr(st),
                capsize=3,
                label=c,
            )
        ax.set_xticks(
            x, scenarios, rotation=30 if len(scenarios) > 3 else 0, ha="right" if len(scenarios) > 3 else "center"
        )
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(title or "mean ± 95% CI")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_sweep(
    summary: pd.DataFrame,
    params: pd.DataFrame,
    controllers: Sequence[str],
    metric: str,
    x_param: str,
    line_param: str,
    path: Path,
) -> None:
    """``metric`` against ``x_param``, one line per ``line_param`` value, one panel per controller, CI bars.

    ``params`` maps each scenario (column ``scenario``) to its parameters (columns ``x_param``, ``line_param``).
    """
    p = params.drop_duplicates("scenario").set_index("scenario")
    fig, axes = plt.subplots(1, len(controllers), figsize=(4.2 * len(controllers), 3.8), sharey=True, squeeze=False)
    for ax, c in zip(axes[0], controllers, strict=True):
        for value in sorted(p[line_param].unique()):
            scen = p[p[line_param] == value].sort_values(x_param)
            st = [_stat(summary, s, c, metric) for s in scen.index]
            ax.errorbar(
                scen[x_param],
                [v[0] for v in st],
                yerr=_yerr(st),
                marker="o",
                capsize=3,
                label=f"{line_param} {value:g}",
            )
        ax.set_title(c, fontsize=10)
        ax.set_xlabel(x_param)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(metric)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
