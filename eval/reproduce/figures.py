"""Figures of the reproduction report, in the spirit of Li 2023 Figs. 9, 10, 12, 13, 14 and Table 1."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from drillgym.envs.metrics import FORCE_FILTER_SAMPLES, moving_average
from drillgym.eval.bench.summary import mean_ci
from drillgym.eval.plots import STAGE_COLOURS, label_span, shade_stages
from drillgym.eval.reproduce.paper import LI2023_COMPENSATED, LI2023_UNCOMPENSATED


def _lateral(trace: dict[str, np.ndarray]) -> np.ndarray:
    f = moving_average(trace["ft_force_n"], FORCE_FILTER_SAMPLES)
    return np.hypot(f[:, 0], f[:, 1])


def _save(fig: plt.Figure, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path.name


def fig9(out: Path, trends: dict[str, Any], none: list) -> str:
    """(a) force model, tip on the axis, vs depth by stage; (b) uncompensated run vs time."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.8))
    d_mm = trends["depth_m"] * 1e3
    stage = trends["stage"]
    a_xlim = (-0.05, 1.2)
    for s, colour in STAGE_COLOURS.items():
        sel = stage == s
        if sel.any():
            a.axvspan(d_mm[sel].min(), d_mm[sel].max(), color=colour, lw=0)
            label_span(a, float(d_mm[sel].min()), float(d_mm[sel].max()), f"stage {s}", a_xlim)
    a.plot(d_mm, trends["lateral_n"], color="C3")
    a.set(xlim=a_xlim, xlabel="tip depth past the surface (mm)", ylabel="unbalanced lateral force (N)")
    a.set_title("(a) force model, tip held on the axis (Li Fig. 9a)", fontsize=9)
    tr = none[0].trace
    shade_stages(b, tr["t_s"], tr["stage"], xlim=(1.5, 8.0))
    b.plot(tr["t_s"], _lateral(tr), color="C3")
    b.set(xlabel="time (s)", ylabel="lateral force |Fxy| (N)")
    b.set_title("(b) full run, no compensation (Li Fig. 9b)", fontsize=9)
    return _save(fig, out / "fig9_force_stages.png")


def fig10(out: Path, trends: dict[str, Any], sim: dict[str, Any] | None) -> str:
    """Max unbalanced force vs β and vs feed: force model (and the full run when given)."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.plot(trends["betas_deg"], trends["peak_vs_beta_n"], "o-", label="force model, tip on the axis")
    b.plot(trends["feeds_mm_s"], trends["peak_vs_feed_n"], "o-", label="force model, tip on the axis")
    if sim is not None:
        a.plot(sim["betas_deg"], sim["force_vs_beta_n"], "s--", label="full run, no compensation")
        b.plot(sim["feeds_mm_s"], sim["force_vs_feed_n"], "s--", label="full run, no compensation")
    a.axvline(20.0, color="0.6", ls=":")
    a.set(xlabel="interaction angle β (deg)", ylabel="max lateral force (N)", title="(a) vs β, 0.5 mm/s (Li Fig. 10a)")
    b.set(xlabel="feed (mm/s)", ylabel="max lateral force (N)", title="(b) vs feed, β 30° (Li Fig. 10b)")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.title.set_fontsize(9)
    return _save(fig, out / "fig10_force_trends.png")


def fig12(out: Path, results: dict[str, list], kp_values: tuple[float, ...]) -> str:
    """Mean tip deviation vs KP with 95% CIs, against Li's three numbers."""
    fig, ax = plt.subplots(figsize=(6, 3.8))
    stats = [mean_ci([r.metrics["deviation_mean_mm"] for r in results[f"sweep_kp{kp:g}"]]) for kp in kp_values]
    m = np.array([s[0] for s in stats])
    err = np.array([[s[0] - s[1] for s in stats], [s[2] - s[0] for s in stats]])
    ax.errorbar(kp_values, m, yerr=err, fmt="o-", capsize=3, label="simulated li2023 (mean, 95% CI)")
    none = mean_ci([r.metrics["deviation_mean_mm"] for r in results["none"]])[0]
    ax.axhline(none, color="C3", ls="--", label=f"simulated none ({none:.3f} mm)")
    li_kp = [LI2023_COMPENSATED["deviation_mean_mm_kp1"], LI2023_COMPENSATED["deviation_mean_mm"]]
    ax.plot([1.0, 4.0], li_kp, "k*", ms=10, label="Li 2023 (KP 1, 4)")
    li_none = LI2023_UNCOMPENSATED["deviation_mean_mm"]
    ax.axhline(li_none, color="k", ls=":", lw=0.8, label=f"Li 2023 none ({li_none:.3f} mm)")
    ax.set(xlabel="KP", ylabel="mean tip deviation (mm)", title="Deviation vs proportional gain (Li Fig. 12)")
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, out / "fig12_deviation_vs_kp.png")


def fig13(out: Path, results: dict[str, list]) -> str:
    """Lateral force with and without compensation, stages of the uncompensated run shaded."""
    fig, ax = plt.subplots(figsize=(8, 3.6))
    tr = results["none"][0].trace
    shade_stages(ax, tr["t_s"], tr["stage"], xlim=(1.5, 14.5))
    lines = [("none", "no compensation", "C3"), ("kp1", "li2023 KP = 1", "C1"), ("kp4", "li2023 KP = 4", "C0")]
    if "residual" in results:
        lines.append(("residual", "learned schedule (shipped)", "C2"))
    for key, label, colour in lines:
        t = results[key][0].trace
        ax.plot(t["t_s"], _lateral(t), color=colour, label=label)
    ax.set(xlabel="time (s)", ylabel="lateral force |Fxy| (N)")
    ax.set_title("Deflection force with and without compensation (Li Fig. 13)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, out / "fig13_force_compensation.png")


def fig14(out: Path, results: dict[str, list], radius_mm: float = 0.75) -> str:
    """Entry hole seen from the drill: planned vs cut, without and with compensation."""
    fig, axes = plt.subplots(1, 2, figsize=(8, 4))
    circle = np.linspace(0, 2 * np.pi, 200)
    for ax, key, title in zip(axes, ("none", "kp4"), ("(a) no compensation", "(b) li2023 KP = 4"), strict=True):
        r = results[key][0]
        depth, centre = r.hole_depth_m * 1e3, r.hole_centre_task_m * 1e3
        entry = depth <= 1.0
        ax.plot(radius_mm * np.cos(circle), radius_mm * np.sin(circle), "k--", lw=1, label="planned hole")
        if entry.any():
            c = centre[entry][-1]
            ax.plot(c[0] + radius_mm * np.cos(circle), c[1] + radius_mm * np.sin(circle), color="C3", label="cut hole")
            ax.plot(centre[entry][:, 0], centre[entry][:, 1], color="C0", lw=1, label="tip path, first 1 mm")
            ax.plot(*c, "C3+", ms=10)
            ax.set_title(f"{title}: centre offset {np.hypot(*c):.2f} mm", fontsize=9)
        ax.plot(0, 0, "k+", ms=10)
        ax.set(aspect="equal", xlim=(-2, 1.5), ylim=(-1.5, 1.5), xlabel="task x, uphill (mm)", ylabel="task y (mm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
    return _save(fig, out / "fig14_entry_hole.png")


def table1(out: Path, ident: dict[str, Any]) -> str:
    """Measured vs predicted arm deflection at three poses (Li Table 1)."""
    meas = np.asarray(ident["table1_measured_mm"])
    pred = np.asarray(ident["table1_predicted_mm"])
    labels = [f"pose {p + 1} {ax}" for p in range(meas.shape[0]) for ax in "xyz"]
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(9, 3.4))
    ax.bar(x - 0.2, meas.ravel(), 0.4, label="measured (simulated arm + tracker noise)")
    ax.bar(x + 0.2, pred.ravel(), 0.4, label="predicted, J Kθ⁻¹ Jᵀ F with identified Kθ")
    ax.set_xticks(x, labels, rotation=45, fontsize=7)
    ax.set(
        ylabel="deflection (mm)",
        title=f"Robot-stiffness deflections (Li Table 1): max error {ident['table1_max_err_mm']:.3f} mm",
    )
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    return _save(fig, out / "table1_stiffness.png")


def zhang(out: Path, results: dict[str, list]) -> str:
    """Controlled MRR: thrust and progress with and without it; deformation compensation under thrust."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11.5, 3.6))
    depth_ax = a.twinx()  # depth in mm on its own axis, never on the force axis
    for key, label, colour in (("mrr_none", "constant feed", "C3"), ("mrr_zhang", "controlled MRR", "C0")):
        t = results[key][0].trace
        f = moving_average(t["ft_force_n"], FORCE_FILTER_SAMPLES)
        feed = t["phase"] == 1
        a.plot(t["t_s"][feed], -f[feed, 2], color=colour, label=f"{label}: thrust")
        depth_ax.plot(t["t_s"][feed], t["depth_cmd_m"][feed] * 1e3, color=colour, ls=":", label=f"{label}: depth")
    a.axhline(8.0, color="0.5", ls="--", lw=0.8, label="thrust reference 8 N")
    a.set(xlabel="time (s)", ylabel="thrust (N), solid", title="(a) cortical 2 mm over cancellous: controlled MRR")
    depth_ax.set_ylabel("commanded depth (mm), dotted")
    depth_ax.legend(fontsize=7, loc="lower right")
    for key, label, colour in (
        ("thrust_none", "no compensation", "C3"),
        ("thrust_zhang", "deformation compensation", "C0"),
    ):
        t = results[key][0].trace
        b.plot(t["t_s"], t["deviation_m"] * 1e3, color=colour, label=label)
    b.set(
        xlabel="time (s)",
        ylabel="tip deviation (mm)",
        title="(b) β 0°, 1.25 mm/s, human femur: deformation compensation",
    )
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        ax.title.set_fontsize(9)
    return _save(fig, out / "zhang_analogues.png")


def write_figures(
    out: Path,
    results: dict[str, list],
    trends: dict[str, Any],
    ident: dict[str, Any],
    kp_values: tuple[float, ...],
    sim_trends: dict[str, Any] | None = None,
) -> list[str]:
    """All figures; returns their file names."""
    return [
        fig9(out, trends, results["none"]),
        fig10(out, trends, sim_trends),
        fig12(out, results, kp_values),
        fig13(out, results),
        fig14(out, results),
        table1(out, ident),
        zhang(out, results),
    ]
