"""The Markdown of the reproduction report and its headline table."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drillgym.controllers.models import LI2023_MODEL_PEAK_N
from drillgym.eval.bench.summary import md_table, mean_ci
from drillgym.eval.reproduce.paper import LI2023_COMPENSATED as _LI_KP
from drillgym.eval.reproduce.paper import LI2023_UNCOMPENSATED as _LI_NONE

ZERO = 1e-9
"""Magnitudes below this print as 0: the quantities are mm, N and s, and 1e-16 is rounding, not a result."""


def _fmt(v: float | None, digits: int = 3) -> str:
    if v is None:
        return "-"
    return "0" if abs(v) < ZERO else f"{v:.{digits}g}"


def _cells(r: Any) -> list[str]:
    ci = f" [{_fmt(r.ci[0])}, {_fmt(r.ci[1])}]" if r.ci else ""
    rel = f"{100 * r.rel_err:+.0f} %" if r.rel_err is not None else ""
    return [r.name, r.unit, _fmt(r.paper), f"{_fmt(r.sim)}{ci}", rel, r.kind, r.note or ""]


def headline(rows: list) -> str:
    """Plain-text table for the terminal."""
    width = max([len(r.name) for r in rows], default=0)
    lines = [f"{'':{width}s} {'unit':>8s} {'paper':>8s} {'sim':>9s} {'rel.err':>8s}  kind"]
    for r in rows:
        rel = f"{100 * r.rel_err:+7.0f}%" if r.rel_err is not None else f"{'':>8s}"
        lines.append(f"{r.name:{width}s} {r.unit:>8s} {_fmt(r.paper):>8s} {_fmt(r.sim):>9s} {rel}  {r.kind}")
    return "\n".join(lines)


def _paired(a: list, b: list, metric: str) -> str:
    mean, lo, hi, n = mean_ci([x.metrics[metric] - y.metrics[metric] for x, y in zip(a, b, strict=True)])
    return f"{mean:+.3f} [{lo:+.3f}, {hi:+.3f}] (n = {n})"


def write_report(
    out: Path,
    rows: list,
    results: dict[str, list],
    trends: dict[str, Any],
    ident: dict[str, Any],
    figures: list[str],
    seeds: list[int],
    kp_values: tuple[float, ...],
) -> None:
    """Write ``out/report.md``."""
    none, kp1, kp4 = results["none"], results["kp1"], results["kp4"]
    n = len(seeds)
    lines = [
        "# Reproduction of Li et al. 2023 (and Zhang et al. 2005's claims) in the simulated cell",
        "",
        f"Seeds 0-{n - 1} for every compared condition (paired by seed); means with 95% confidence intervals "
        "(Student t). Scenario: β 30°, 0.5 mm/s, 20,000 rpm, 1.5 mm two-lip drill, buffalo cortical bone "
        "(Li Table 2). Kind: **calibration** = fitted to this paper number; **prediction** = not fitted; "
        "**check** = physics or identification test; **baseline** = a classical controller beyond the paper "
        "(`li2023_tuned`, the strongest hand-made baseline, `docs/controllers.md`); **learned** = the shipped "
        "residual policy (not in the paper). Regenerate with `drillgym reproduce`.",
        "",
        md_table(["quantity", "unit", "paper", "sim [95% CI]", "rel. err", "kind", "note"], [_cells(r) for r in rows]),
        "",
        "## Calibration (uncompensated run only)",
        "",
        "The drill stick-out and the lips' lateral edge and chip coefficients were fitted on the uncompensated "
        "run to Li's mean deviation (0.703 mm) and max lateral force (1.3 N); his stable-stage force (1.2 N) "
        "and hole offset (0.8 mm) are checks, not fitted (see `docs/physics.md` §6). The uncompensated run "
        "does not determine the entry structure (skid relief, lateral cut resistance, guidance exponent, "
        "hole-wall floor and length): among 72 structures that each fit it, the shipped one was chosen as one "
        "that predicts every direction Li reports for li2023 (`drillgym calibrate`, `docs/physics.md` §7). No "
        "compensated value was fitted, but that choice used the direction of two compensated results (the "
        "peak force falls, KP = 4 beats KP = 1), so those two rows are not blind predictions. The "
        "controller's own force model (li2023's offline correction) was then fitted by least squares to the "
        "F/T force of the same uncompensated runs over the unbalanced stages, as Li fits his model to his "
        f"uncompensated experiment: peak {LI2023_MODEL_PEAK_N:.2f} N at the paper's operating point.",
        "",
        "## Predictions: the hybrid compensator",
        "",
        "Paired differences to `none` (li2023 minus none):",
        "",
        md_table(
            ["metric", "KP = 1", "KP = 4"],
            [
                [metric, _paired(kp1, none, metric), _paired(kp4, none, metric)]
                for metric in ("deviation_mean_mm", "lateral_force_max_n", "lateral_force_stable_n", "hole_offset_mm")
            ],
        ),
    ]
    lines += [
        "",
        f"KP = 4 minus KP = 1, deviation: {_paired(kp4, kp1, 'deviation_mean_mm')} mm; "
        f"max lateral force: {_paired(kp4, kp1, 'lateral_force_max_n')} N.",
        "",
        "### Where the simulation agrees with the paper and where it does not",
        "",
        f"* **Deviation and hole offset fall** with compensation, more than in Li ({_LI_NONE['deviation_mean_mm']} → "
        f"{_LI_KP['deviation_mean_mm']} mm, {_LI_NONE['hole_offset_mm']} → {_LI_KP['hole_offset_mm']} mm). Most of the reduction comes from the model-based terms, which do not depend on KP: the "
        "offline correction bends the drill uphill *while* the tip enters, and the tip stays movable until "
        "its hole has a wall (about 1 mm after the full diameter is in), so the online loop, slow by "
        "construction (0.2 s filter, 600 ms points, applied two points ahead: ≈ 1.2-1.8 s of delay), still "
        "moves it rather than bending the drill. li2023's models here are fitted to the simulated cell "
        "itself, and are likely closer to its truth than Li's were to his cell.",
        "* **KP matters less than in Li's experiment.** Raising KP from 1 to 4 lowers the deviation by "
        f"≈ 0.05 mm here; Li saw {_LI_KP['deviation_mean_mm_kp1']} → {_LI_KP['deviation_mean_mm']} mm. KP multiplies the change of deviation between two points, "
        "which arrives after most of the entry.",
        "* **Max lateral force falls, but far less than in Li's run.** The entry peak is the skid-and-catch at "
        "first contact: on a planar slope it does not depend on where the drill meets the surface (a constant "
        "uphill offset moves the hole and leaves the peak unchanged), so only a correction that varies during "
        "the first 0.1 mm of feed can lower it, and only the offline profile does. With the lips-only entry "
        "(`CellParams.wall_guidance_floor = 1`, the tip held as soon as the lips bite) li2023 at KP = 4 "
        "*raised* the peak to 2.3 N: its late correction bent a drill its own hole already held. Li's lower "
        "compensated force (and his paper's own arithmetic: 1.3 N × (1 − 0.385) = 0.80 N, not the 0.7 N "
        "quoted) point to effects the quasi-static model leaves out (e.g. the dynamics of first contact), "
        "listed as candidates for the sim-to-real diagnosis.",
        "* **Stable-stage force falls** with every setting (the hole is cut closer to the axis, so the drill "
        "is less bent in it).",
        "",
        "## Force model and robot stiffness (checks)",
        "",
        f"* Fig. 9a: the unbalanced force of the force model (tip on the axis) peaks in stage "
        f"{trends['peak_stage']} at {trends['peak_depth_m'] * 1e3:.2f} mm of depth with {trends['peak_n']:.2f} N and is "
        f"balanced in stage 4 (ratio {trends['stage4_ratio']:.1e}).",
        f"* Fig. 10: peak force vs β is linear below 20° (R² = {trends['beta_r2']:.3f}) and flattens above "
        f"(slope ratio {trends['beta_slope_ratio']:.2f}): the engaged arcs saturate once they span the whole lip. "
        f"Peak force vs feed is linear (R² = {trends['feed_r2']:.4f}). In the full run the peak force is set by "
        "how far the tip skids before it is caught, which keeps growing with β up to 40°.",
        f"* Table 1: the arm's deflection at three poses, predicted with Kθ identified from simulated load tests "
        f"(tracker noise {ident['noise_mm']} mm, loads ±{ident['load_n']:.0f} N), is within "
        f"{ident['table1_max_err_mm']:.3f} mm of the simulated measurement (Li: within 0.15 mm on average). "
        "Kθ₁-Kθ₃ are identified with their CIs; the wrist joints are not identifiable from tip translations "
        "(`drillgym identify-stiffness` says so and suggests poses and tool offsets that would).",
        "",
        "## Zhang et al. 2005 as drilling analogues",
        "",
        "* **Deformation compensation under high thrust** (β 0°, 1.25 mm/s, human femur, ≈ 15 N of thrust): the "
        "arm's coupled compliance turns thrust into a sideways tip deflection; compensating Δq = Kq⁻¹ Jᵀ F on "
        "the joint references (as a tip correction) removes most of it: deviation "
        f"{_paired(results['thrust_zhang'], results['thrust_none'], 'deviation_mean_mm')} mm vs none. Zhang: "
        "milling surface error 0.5 mm → < 0.1 mm.",
        "* **Controlled material removal rate** through 2 mm of cortex over cancellous bone (10 mm deep): the PI "
        "on feed holds the thrust at the 8 N reference in the cortex and speeds up in the cancellous core until "
        "the feed limit (4 × nominal), where the thrust stays below the reference. Drill time "
        f"{_paired(results['mrr_zhang'], results['mrr_none'], 'drill_time_s')} s vs constant feed "
        "(Zhang: cycle time down 30-50 %).",
        "",
        "## Figures",
        "",
        *(f"![{f}]({f})" for f in figures),
        "",
        f"KP sweep: {', '.join(f'{k:g}' for k in kp_values)}.",
    ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
