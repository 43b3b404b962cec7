"""``drillgym validate-forces``: the force model against published thrust and torque (eval/external/).

The model's fully engaged wrench is checked against the closed form of the element forces (independent of the
table's code); the calibration and prediction against that same closed form; the rules on both sides of their bars;
and the published figures of docs/external-validation.md, which are deterministic (no random draw anywhere).
"""

from __future__ import annotations

import json
import math

import pytest

from drillgym.envs.drilling.bone import get_bone_preset
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.eval.cli import main
from drillgym.eval.external import validate as v
from drillgym.eval.external.studies import SERIES, Condition, Series

LIP_BOUNDARY_TOL = 0.03
"""The table's 24 radial elements put the lip/chisel boundary at the first element centre beyond w = 0.18 R (the
element from 4/24 R), where the closed form cuts at 0.18 R: the lip length differs by 1.6 % and its torque moment
by 0.4 %; 3 % covers both with room."""


def closed_form(diameter_m, preset, feed_m_s, rpm):
    """Thrust and torque of two fully engaged lips and the chisel, perpendicular entry: ``n [(K_f h + K_fe) (R − w)
    + K_ch w] / sin κ`` and ``n (K_t h + K_te) (R² − w²) / (2 sin κ)``."""
    g = DrillGeometry(diameter_m=diameter_m)
    m = get_bone_preset(preset).cortical
    big_r, w, s = g.radius_m, g.web_radius_m, math.sin(g.kappa_rad)
    h = feed_m_s / (2 * rpm / 60.0) * s
    thrust = 2 * ((m.k_fc_pa * h + m.k_fe_n_m) * (big_r - w) + m.k_chisel_n_m * w) / s
    torque = 2 * (m.k_tc_pa * h + m.k_te_n_m) * (big_r**2 - w**2) / (2 * s)
    return thrust, torque


@pytest.mark.parametrize(
    ("diameter_m", "preset", "feed_m_s", "rpm"),
    [(3.2e-3, "human_femur", 2e-3, 1000), (1.5e-3, "buffalo_femur", 0.5e-3, 20000)],
)
def test_the_fully_engaged_wrench_matches_the_closed_form_of_the_element_forces(diameter_m, preset, feed_m_s, rpm):
    thrust, torque = v.steady_wrench(diameter_m, 118.0, preset, feed_m_s, rpm)
    want_thrust, want_torque = closed_form(diameter_m, preset, feed_m_s, rpm)
    assert thrust == pytest.approx(want_thrust, rel=LIP_BOUNDARY_TOL)
    assert torque == pytest.approx(want_torque, rel=LIP_BOUNDARY_TOL)


def test_a_series_is_calibrated_on_its_first_condition_and_predicts_the_rest_by_the_models_ratio():
    series = Series(
        "s",
        "m",
        "human_femur",
        3.2e-3,
        None,
        2e-3,
        (Condition(1000, 100.0, 5.0, 0.1, None), Condition(2000, 60.0, None, 0.05, None)),
    )
    out = v.validate_series(series)
    cal, held = out["conditions"]
    assert cal["calibration"] and cal["thrust"]["predicted"] == pytest.approx(100.0) and cal["thrust"]["within"] is None
    t1, q1 = closed_form(3.2e-3, "human_femur", 2e-3, 1000)
    t2, q2 = closed_form(3.2e-3, "human_femur", 2e-3, 2000)
    assert held["thrust"]["predicted"] == pytest.approx(100.0 * t2 / t1, rel=0.01)
    assert held["torque"]["predicted"] == pytest.approx(0.1 * q2 / q1, rel=0.01)
    assert held["thrust"]["rel_err"] == pytest.approx(held["thrust"]["predicted"] / 60.0 - 1.0)
    assert out["directions"]["thrust"] == {"measured": -1.0, "predicted": [-1.0], "right": True}


def test_an_unstated_feed_runs_every_feed_of_the_range_and_the_worst_error_counts():
    series = Series(
        "s",
        "m",
        "bovine_tibia",
        2.5e-3,
        None,
        None,
        (Condition(1000, 20.0, None, None, None), Condition(1500, 14.0, None, None, None)),
    )
    held = v.validate_series(series)["conditions"][1]["thrust"]
    preds = [
        20.0 * closed_form(2.5e-3, "bovine_tibia", f, 1500)[0] / closed_form(2.5e-3, "bovine_tibia", f, 1000)[0]
        for f in v.FEED_RANGE_M_S
    ]
    assert held["predicted_range"] == pytest.approx([min(preds), max(preds)], rel=0.01)
    errs = [p / 14.0 - 1.0 for p in preds]
    # the ratios agree to 1 % (the lip boundary's share cancels in a ratio but for its edge term): so do the errors
    assert held["worst_rel_err"] == pytest.approx(max(errs, key=abs), abs=0.01)


def test_the_magnitude_bar_is_thirty_percent_on_either_side():
    assert v._within(0.30) and v._within(-0.30) and not v._within(0.3001) and not v._within(-0.3001)
    assert (v.MAGNITUDE_TOL, v.MAGNITUDE_SHARE_MIN) == (0.30, 0.70)


def test_the_published_figures_of_the_docs_hold():
    """docs/external-validation.md: 13 of 14 held-out predictions within 30 % (the miss: Orelaja's artificial femur
    torque at 1500 rpm, +39 %), every speed trend right, the feed effect not (model thrust ratio 5.1–5.7 against 4.35)."""
    result = v.validate()
    s = result["summary"]
    assert (s["held_out_predictions"], s["within_magnitude_bar"], s["magnitudes_pass"]) == (14, 13, True)
    assert (s["speed_directions_right"], s["speed_directions"], s["feed_effects_right"]) == (10, 10, 0)
    misses = [
        (x["material"], r["spindle_rpm"], q)
        for x in result["series"]
        for r in x["conditions"]
        for q in ("thrust", "torque")
        if q in r and r[q]["within"] is False
    ]
    assert misses == [("artificial femur", 1500, "torque")]
    feed = result["feed_ratios"][0]
    assert min(feed["predicted_ratio"]) == pytest.approx(5.08, abs=0.01) and max(
        feed["predicted_ratio"]
    ) == pytest.approx(5.68, abs=0.01)
    assert len(result["series"]) == len(SERIES) == 5


def test_the_command_writes_a_report_with_a_figure_per_study_and_never_overwrites_one(tmp_path, capsys):
    out = tmp_path / "v"
    assert main(["validate-forces", "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {
        "validation.json",
        "validation.md",
        "macavelia2012.png",
        "orelaja2020.png",
    }
    assert json.loads((out / "validation.json").read_text())["summary"]["within_magnitude_bar"] == 13
    assert "13 / 14" in capsys.readouterr().out
    before = (out / "validation.json").read_bytes()
    assert main(["validate-forces", "--out", str(out)]) == 2
    assert "never overwritten" in capsys.readouterr().err and (out / "validation.json").read_bytes() == before
