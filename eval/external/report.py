"""``validate-forces``' report: the markdown tables and one figure per study."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def _pct(v: float | None) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{100 * v:+.0f} %"


def _value(q: str, v: float) -> str:
    return f"{v:.1f} N" if q == "thrust" else f"{1e3 * v:.1f} N·mm"


def markdown(result: dict[str, Any], figures: dict[str, Path]) -> str:
    """The report: rules, each series' predictions, the feed effect, the summary."""
    s, r = result["summary"], result["rules"]
    lines = [
        "# The force model against published bone-drilling measurements",
        "",
        f"Held-out predictions within ±{100 * r['magnitude_tol']:.0f} %: **{s['within_magnitude_bar']} / "
        f"{s['held_out_predictions']}** ({100 * s['share_within']:.0f} %; the bar: "
        f"≥ {100 * r['magnitude_share_min']:.0f} %). Speed trends right: **{s['speed_directions_right']} / "
        f"{s['speed_directions']}**. Feed effects right: **{s['feed_effects_right']} / {s['feed_effects']}**.",
        "",
        "Each series is calibrated on its first condition (thrust and torque each scaled by one factor); the "
        "others are predictions. Where a source omits the feed, the feeds "
        f"{', '.join(f'{f:g}' for f in r['feeds_run_where_unstated_mm_s'])} mm/s are run and the worst error "
        "counts (the value shown is the middle feed's, the range in brackets).",
        "",
        "| study | material | drill | feed | rpm | quantity | measured | predicted | error (worst) | within |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for ser in result["series"]:
        feed = "not stated" if ser["feed_mm_s"] is None else f"{ser['feed_mm_s']:g} mm/s"
        for row in ser["conditions"]:
            for q in ("thrust", "torque"):
                if q not in row:
                    continue
                c = row[q]
                sd = "" if c["measured_sd"] is None else f" ± {_value(q, c['measured_sd']).split()[0]}"
                lo, hi = c["predicted_range"]
                same = row["calibration"] or math.isclose(lo, hi, rel_tol=1e-9)
                pred = _value(q, c["predicted"]) + ("" if same else f" [{_value(q, lo)}–{_value(q, hi)}]")
                within = "calibration" if row["calibration"] else ("yes" if c["within"] else "**no**")
                lines.append(
                    f"| {ser['study']} | {ser['material']} | {ser['drill_diameter_mm']:g} mm | {feed} | "
                    f"{row['spindle_rpm']:g} | {q} | {_value(q, c['measured'])}{sd} | {pred} | "
                    f"{'–' if row['calibration'] else _pct(c['worst_rel_err'])} | {within} |"
                )
    lines += ["", "## Uncalibrated magnitudes", ""]
    lines += [
        "The model as shipped (buffalo cortex calibrated on Li 2023 at a 0.6 µm chip, the preset's hardness) over the "
        "measurement at each series' calibration condition (one value per feed run):",
        "",
    ]
    for ser in result["series"]:
        parts = [f"{q} {', '.join(f'{x:.2g}×' for x in v)}" for q, v in ser["uncalibrated_over_measured"].items()]
        lines.append(f"* {ser['study']}, {ser['material']}: {'; '.join(parts)}")
    lines += ["", "## Feed rate", ""] if result["feed_ratios"] else []
    for f in result["feed_ratios"]:
        pr = ", ".join(f"{x:.2f}" for x in f["predicted_ratio"])
        pe = ", ".join(f"{x:.2f}" for x in f["predicted_exponent"])
        rpm = ", ".join(f"{x:g}" for x in f["spindle_rpm_run"])
        lines.append(
            f"* {f['study']} ({f['material']}, {f['drill_diameter_mm']:g} mm, {f['feeds_mm_s'][0]:g}→"
            f"{f['feeds_mm_s'][1]:g} mm/s): thrust ratio measured {f['measured_ratio']:.2f} (exponent "
            f"{f['measured_exponent']:.2f}), model {pr} at {rpm} rpm (exponent {pe}); worst error "
            f"{_pct(f['worst_rel_err'])}: {'right' if f['right'] else '**not right**'}"
        )
    lines += ["", "## Sources", ""]
    lines += [f"* `{k}`: {v}" for k, v in result["sources"].items()]
    for name, path in figures.items():
        lines += ["", f"![{name}]({path.name})"]
    return "\n".join(lines) + "\n"


def plot_study(result: dict[str, Any], study: str, path: Path) -> Path:
    """Measured (± SD) and predicted thrust and torque against spindle speed for every series of ``study``."""
    series = [s for s in result["series"] if s["study"] == study]
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6))
    for k, ser in enumerate(series):
        colour = f"C{k}"
        rpm = [row["spindle_rpm"] for row in ser["conditions"]]
        for ax, q, scale, unit in ((axes[0], "thrust", 1.0, "N"), (axes[1], "torque", 1e3, "N·mm")):
            rows = [row[q] for row in ser["conditions"] if q in row]
            if len(rows) != len(rpm):
                continue
            measured = [scale * c["measured"] for c in rows]
            sd = [scale * (c["measured_sd"] or 0.0) for c in rows]
            ax.errorbar(rpm, measured, yerr=sd, fmt="o", color=colour, capsize=3, label=f"{ser['material']} (measured)")
            label = "model, calibrated at the lowest speed" if k == 0 else None
            ax.plot(rpm, [scale * c["predicted"] for c in rows], "-", color=colour, label=label)
            lo = [scale * c["predicted_range"][0] for c in rows]
            hi = [scale * c["predicted_range"][1] for c in rows]
            if lo != hi:
                ax.fill_between(rpm, lo, hi, color=colour, alpha=0.15, lw=0)
            ax.set_xlabel("spindle speed (rpm)")
            ax.set_ylabel(f"{q} ({unit})")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{study}: calibrated on the lowest speed, the rest predicted", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
