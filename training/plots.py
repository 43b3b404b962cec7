"""Training curves: the residual policy against its base controller over training."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def plot_curves(curve: list[dict[str, float]], path: Path, episodes: str = "paper scenario") -> None:
    """Deviation and max lateral force of the policy vs the base, per evaluation (means over ``episodes``)."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    if curve:
        t = [r["timesteps"] for r in curve]
        a.plot(t, [r["policy_deviation_mean_mm"] for r in curve], "o-", label="residual policy")
        a.plot(t, [r["base_deviation_mean_mm"] for r in curve], "--", label="base controller")
        b.plot(t, [r["policy_lateral_force_max_n"] for r in curve], "o-", label="residual policy")
        b.plot(t, [r["base_lateral_force_max_n"] for r in curve], "--", label="base controller")
    title = f"{episodes}, deterministic evaluation"
    a.set(xlabel="agent steps (thousands)", ylabel="mean tip deviation (mm)", title=title)
    b.set(xlabel="agent steps (thousands)", ylabel="max lateral force (N)", title=title)
    for ax in (a, b):
        ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:g}")
        ax.grid(alpha=0.3)
        if curve:
            ax.legend(fontsize=8)
        else:  # a run shorter than eval_freq: say so rather than leave blank axes
            ax.text(0.5, 0.5, "no evaluation yet", transform=ax.transAxes, ha="center", va="center", color="0.4")
        ax.title.set_fontsize(9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
