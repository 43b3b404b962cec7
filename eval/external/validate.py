"""The force model on published conditions: one calibration per series, the rest predicted.

For each :class:`~drillgym.eval.external.studies.Series`, the model's steady, fully engaged thrust and torque
(:class:`~drillgym.envs.drilling.force_model.EngagementTable` of the series' drill, perpendicular entry, cortical
bone of its closest preset; the cycle-averaged force at the chip of each condition's feed and speed) is scaled to the
series' first condition, thrust and torque each by its own factor (the preset's hardness is a guess for another
lab's bone, and the thrust and tangential coefficients are separate families). Every other condition is a
prediction: its measured value against the calibration condition's measurement times the model's ratio. Where a
source does not give the feed, every feed of :data:`FEED_RANGE_M_S` is run and the worst error counts.

The rules, fixed before any run: a prediction is within the magnitude bar when its relative error is at most
:data:`MAGNITUDE_TOL`; the validation passes on magnitudes when at least :data:`MAGNITUDE_SHARE_MIN` of the held-out
predictions (thrust and torque of every held-out condition) are within it; a speed trend is right when the model
moves thrust (torque) from the first to the last speed of a series in the measured direction at every feed run; a
feed effect is right when the model's thrust ratio over the source's feed range is within the magnitude bar of the
published ratio at every spindle speed of :data:`SPINDLE_RANGE_RPM` (the source gives none).
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import numpy as np

from drillgym.envs.drilling.bone import get_bone_preset
from drillgym.envs.drilling.force_model import EngagementTable
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.eval.external.studies import FEED_RATIOS, SERIES, SOURCES, FeedRatio, Series

FEED_RANGE_M_S = (0.5e-3, 1.0e-3, 2.0e-3)
"""Feeds run where a source omits its own (m/s): surgical drilling feeds, within the 0.5–3 mm/s of the feed study."""
SPINDLE_RANGE_RPM = (600.0, 1000.0, 2000.0)
"""Spindle speeds run where a source omits its own (rev/min): the range of the other studies' surgical drills."""
DEFAULT_POINT_ANGLE_DEG = 118.0
"""Point angle used where a source gives none (deg): the standard twist-drill point."""
MAGNITUDE_TOL = 0.30
"""A prediction is within the magnitude bar when ``|predicted / measured − 1|`` is at most this."""
MAGNITUDE_SHARE_MIN = 0.70
"""... and the magnitudes pass when at least this share of the held-out predictions are."""
ALL_CORTICAL_M = 1.0
"""Cortical thickness given to the table (m): the studies drilled cortical specimens, so no cancellous core."""


@cache
def _table(diameter_m: float, point_angle_deg: float, preset: str) -> tuple[DrillGeometry, EngagementTable]:
    geometry = DrillGeometry(diameter_m=diameter_m, point_angle_deg=point_angle_deg)
    depth = geometry.full_engagement_depth_m(0.0) + 1e-3
    return geometry, EngagementTable.build(geometry, get_bone_preset(preset), 0.0, ALL_CORTICAL_M, depth)


def steady_wrench(
    diameter_m: float, point_angle_deg: float, preset: str, feed_m_s: float, spindle_rpm: float
) -> tuple[float, float]:
    """The model's thrust (N) and drilling torque (N·m) with both lips fully engaged, perpendicular to the bone."""
    geometry, table = _table(diameter_m, point_angle_deg, preset)
    h = geometry.chip_thickness_m(feed_m_s, spindle_rpm)
    row = table.edge[-1] + h * table.per_chip[-1]
    return float(-row[2]), float(-row[3])


def _within(err: float) -> bool:
    return bool(abs(err) <= MAGNITUDE_TOL)


def validate_series(series: Series) -> dict[str, Any]:
    """Calibrate ``series`` on its first condition and predict the others (see the module docstring)."""
    angle = series.point_angle_deg or DEFAULT_POINT_ANGLE_DEG
    feeds = (series.feed_m_s,) if series.feed_m_s is not None else FEED_RANGE_M_S
    cal = series.conditions[0]
    model = {
        f: [
            steady_wrench(series.drill_diameter_m, angle, series.bone_preset, f, c.spindle_rpm)
            for c in series.conditions
        ]
        for f in feeds
    }
    rows = []
    for k, c in enumerate(series.conditions):
        row: dict[str, Any] = {"spindle_rpm": c.spindle_rpm, "calibration": k == 0}
        for q, measured, sd, cal_value in (
            ("thrust", c.thrust_n, c.thrust_sd_n, cal.thrust_n),
            ("torque", c.torque_nm, c.torque_sd_nm, cal.torque_nm),
        ):
            if measured is None or cal_value is None:
                continue
            i = 0 if q == "thrust" else 1
            preds = [cal_value * model[f][k][i] / model[f][0][i] for f in feeds]
            errs = [p / measured - 1.0 for p in preds]
            worst = max(errs, key=abs)
            row[q] = {
                "measured": measured,
                "measured_sd": sd,
                "predicted": preds[len(preds) // 2],
                "predicted_range": [min(preds), max(preds)],
                "rel_err": errs[len(errs) // 2],
                "worst_rel_err": worst,
                "within": None if k == 0 else _within(worst),
            }
        rows.append(row)
    directions = {}
    for q, i in (("thrust", 0), ("torque", 1)):
        if q not in rows[0] or q not in rows[-1]:
            continue
        measured = float(np.sign(rows[-1][q]["measured"] - rows[0][q]["measured"]))
        predicted = [float(np.sign(model[f][-1][i] - model[f][0][i])) for f in feeds]
        directions[q] = {"measured": measured, "predicted": predicted, "right": all(p == measured for p in predicted)}
    uncalibrated = {
        q: [model[f][0][i] / v for f in feeds]
        for q, i, v in (("thrust", 0, cal.thrust_n), ("torque", 1, cal.torque_nm))
        if v is not None
    }
    return {
        "study": series.study,
        "material": series.material,
        "bone_preset": series.bone_preset,
        "drill_diameter_mm": 1e3 * series.drill_diameter_m,
        "point_angle_deg": series.point_angle_deg,
        "point_angle_used_deg": angle,
        "feed_mm_s": None if series.feed_m_s is None else 1e3 * series.feed_m_s,
        "feeds_run_mm_s": [1e3 * f for f in feeds],
        "conditions": rows,
        "directions": directions,
        "uncalibrated_over_measured": uncalibrated,
    }


def validate_feed_ratio(fr: FeedRatio) -> dict[str, Any]:
    """The model's thrust ratio over ``fr``'s feed range against the published one, at every speed run."""
    speeds = (fr.spindle_rpm,) if fr.spindle_rpm is not None else SPINDLE_RANGE_RPM
    ratios = []
    for n in speeds:
        lo = steady_wrench(fr.drill_diameter_m, DEFAULT_POINT_ANGLE_DEG, "bovine_tibia", fr.feed_low_m_s, n)[0]
        hi = steady_wrench(fr.drill_diameter_m, DEFAULT_POINT_ANGLE_DEG, "bovine_tibia", fr.feed_high_m_s, n)[0]
        ratios.append(hi / lo)
    span = math.log(fr.feed_high_m_s / fr.feed_low_m_s)
    errs = [r / fr.thrust_ratio - 1.0 for r in ratios]
    worst = max(errs, key=abs)
    return {
        "study": fr.study,
        "material": fr.material,
        "drill_diameter_mm": 1e3 * fr.drill_diameter_m,
        "feeds_mm_s": [1e3 * fr.feed_low_m_s, 1e3 * fr.feed_high_m_s],
        "spindle_rpm_run": list(speeds),
        "measured_ratio": fr.thrust_ratio,
        "measured_exponent": math.log(fr.thrust_ratio) / span,
        "predicted_ratio": ratios,
        "predicted_exponent": [math.log(r) / span for r in ratios],
        "worst_rel_err": worst,
        "right": _within(worst),
    }


def validate(studies: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Every series and feed ratio of ``studies`` (default: all of :data:`SOURCES`), and the acceptance figures."""
    keep = set(SOURCES if studies is None else studies)
    series = [validate_series(s) for s in SERIES if s.study in keep]
    feeds = [validate_feed_ratio(f) for f in FEED_RATIOS if f.study in keep]
    held = [
        r[q] for s in series for r in s["conditions"] if not r["calibration"] for q in ("thrust", "torque") if q in r
    ]
    within = sum(bool(h["within"]) for h in held)
    directions = [d["right"] for s in series for d in s["directions"].values()]
    share = within / len(held) if held else math.nan
    return {
        "sources": {k: v for k, v in SOURCES.items() if k in keep},
        "rules": {
            "magnitude_tol": MAGNITUDE_TOL,
            "magnitude_share_min": MAGNITUDE_SHARE_MIN,
            "feeds_run_where_unstated_mm_s": [1e3 * f for f in FEED_RANGE_M_S],
            "spindle_rpm_run_where_unstated": list(SPINDLE_RANGE_RPM),
            "point_angle_where_unstated_deg": DEFAULT_POINT_ANGLE_DEG,
        },
        "series": series,
        "feed_ratios": feeds,
        "summary": {
            "held_out_predictions": len(held),
            "within_magnitude_bar": within,
            "share_within": share,
            "magnitudes_pass": bool(share >= MAGNITUDE_SHARE_MIN),
            "speed_directions_right": sum(directions),
            "speed_directions": len(directions),
            "feed_effects_right": sum(f["right"] for f in feeds),
            "feed_effects": len(feeds),
        },
    }
