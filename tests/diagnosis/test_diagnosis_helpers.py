"""Helpers of the diagnosis tests: a simulated episode log, and the same episode as a real cell's
recording session in ``ur_rtde``'s file-recording format plus F/T, tracker and command CSVs."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.eval.logs import EpisodeLogger, build_header, read_episode_log

RTDE_T0 = 5321.25
"""Controller time (s since its start) at the episode's t = 0."""


def sim_log(path: Path, controller: str = "li2023", seed: int = 0, **scenario) -> tuple[dict, pd.DataFrame]:
    """Run one episode and log it (sim schema); return ``read_episode_log``'s answer."""
    kw = {"depth_mm": 3.0, "feed_mm_s": 1.0, **scenario}
    env = gym.make("drillgym/UR5BoneDrill-v1", **kw)
    ctrl = make_controller(controller)
    logger = EpisodeLogger(env, path, build_header(env, ctrl.describe(), seed), overwrite=True)
    obs, _ = logger.reset(seed=seed)
    ctrl.set_plan(env.unwrapped.plan)
    start = True
    while True:
        a, _ = ctrl.predict(obs, episode_start=np.array([start]))
        obs, _, te, tr, _ = logger.step(a)
        start = False
        if te or tr:
            break
    logger.close()
    return read_episode_log(path)


def _fixed6(x: float) -> str:
    return f"{x:.6f}"


def write_rtde_recording(path: Path, t_s: np.ndarray, variables: dict[str, np.ndarray]) -> None:
    """Write a CSV exactly as ``RTDEReceiveInterface::startFileRecording`` does.

    The header line names each variable, a vector expanded as ``name_0,...,name_{n-1}``, comma-separated
    with no trailing comma; each row holds the values in fixed notation with 6 decimals (``std::fixed``,
    ``std::setprecision(6)``), integers as integers.
    """
    names, columns = ["timestamp"], [t_s]
    for name, v in variables.items():
        v = np.asarray(v)
        if v.ndim == 1:
            names.append(name)
            columns.append(v)
        else:
            for j in range(v.shape[1]):
                names.append(f"{name}_{j}")
                columns.append(v[:, j])
    lines = [",".join(names)]
    for row in zip(*columns, strict=True):
        lines.append(",".join(str(int(x)) if isinstance(x, np.integer) else _fixed6(float(x)) for x in row))
    path.write_text("\n".join(lines) + "\n")


def write_session(d: Path, header: dict, df: pd.DataFrame, host_t0: float = 100.0) -> Path:
    """A recording session of a logged episode: what a real cell's recorders would have written."""
    d.mkdir(parents=True, exist_ok=True)
    first = np.flatnonzero(np.diff(np.concatenate([[-1], df["step"].to_numpy()])) != 0)
    n_steps = first.size
    t_cmd = np.arange(n_steps) * 0.05
    step_vals = df.iloc[first]
    # RTDE at 125 Hz; the state at time t is the step's end-of-step reading for the step it falls in.
    t_rtde = np.arange(1, int(n_steps * 0.05 * 125) + 1) / 125.0
    k = np.clip(np.ceil(t_rtde / 0.05 - 1e-9).astype(int) - 1, 0, n_steps - 1)
    q = step_vals[[f"q{i}_rad" for i in range(6)]].to_numpy()[k]
    tcp = step_vals[["tcp_x_base_m", "tcp_y_base_m", "tcp_z_base_m"]].to_numpy()[k]
    pose = np.column_stack([tcp, np.tile([2.2, -2.2, 0.0], (k.size, 1))])
    write_rtde_recording(
        d / "rtde.csv",
        RTDE_T0 + t_rtde,
        {
            "target_q": q,
            "actual_q": q,
            "actual_qd": np.zeros_like(q),
            "actual_TCP_pose": pose,
            "robot_mode": np.full(k.size, 7),
        },
    )
    ft = pd.DataFrame(
        {
            "t_s": host_t0 + df["t_s"],
            "fx_n": df["ft_fx_n"],
            "fy_n": df["ft_fy_n"],
            "fz_n": df["ft_fz_n"],
            "tx_nm": df["ft_tx_nm"],
            "ty_nm": df["ft_ty_nm"],
            "tz_nm": df["ft_tz_nm"],
        }
    )
    ft.to_csv(d / "ft.csv", index=False, float_format="%.6f")
    tr_t = np.arange(1, int(n_steps * 0.05 * 60) + 1) / 60.0
    kt = np.clip(np.ceil(tr_t / 0.05 - 1e-9).astype(int) - 1, 0, n_steps - 1)
    trk = step_vals[["tracker_x_base_m", "tracker_y_base_m", "tracker_z_base_m"]].to_numpy()[kt]
    pd.DataFrame({"t_s": host_t0 + tr_t, "x_m": trk[:, 0], "y_m": trk[:, 1], "z_m": trk[:, 2], "valid": 1}).to_csv(
        d / "tracker.csv", index=False, float_format="%.7f"
    )
    cmd = pd.DataFrame(
        {
            "t_s": host_t0 + t_cmd,
            "phase": df["phase"].to_numpy()[first],
            "depth_cmd_m": df["depth_cmd_m"].to_numpy()[first],
            "cmd_dx_base_m": step_vals["cmd_dx_base_m"].to_numpy(),
            "cmd_dy_base_m": step_vals["cmd_dy_base_m"].to_numpy(),
            "cmd_dz_base_m": step_vals["cmd_dz_base_m"].to_numpy(),
            "cmd_feed_scale": step_vals["cmd_feed_scale"].to_numpy(),
        }
    )
    cmd.to_csv(d / "commands.csv", index=False, float_format="%.9g")
    meta = {
        "scenario": header["scenario"],
        "controller": header["controller"],
        "plan": header["plan"],
        "clock": {"rtde_timestamp_at_t0_s": RTDE_T0, "host_t0_s": host_t0},
    }
    (d / "header.json").write_text(json.dumps(meta))
    return d


def test_the_ranking_says_why_a_model_above_the_named_one_was_not_named():
    from drillgym.eval.diagnosis.report import why_not_named

    def model(name, shrink, low, named=False):
        return {"name": name, "effects": name.split("+"), "shrink": shrink, "ci_low": low, "named": named}

    effects = [model("a+b", 0.9, 0.6), model("c", 0.4, 0.1), model("a", 0.8, 0.5, named=True), model("d", 0.1, 0.0)]
    res = {"effects": effects, "verdict": "explained", "possible_second_effects": [{"name": "a+b"}]}
    assert "second effect is not shown" in why_not_named(effects[0], res)
    assert "below the bar" in why_not_named(effects[1], res)
    assert why_not_named(effects[3], res) == ""  # ranked below the named model: nothing to explain


def test_the_ranking_gives_the_rescue_bar_as_the_reason_a_refined_single_was_refused():
    from drillgym.eval.diagnosis.report import why_not_named

    effects = [{"name": "a", "effects": ["a"], "shrink": 0.7, "ci_low": 0.3, "named": False}]
    reason = "named only after the best single was refined, and its shrink interval starts at 30 %"
    rescue = {"effect": "a", "decided": "a", "named": False, "reason": reason}
    res = {"effects": effects, "verdict": "unexplained", "rescue": rescue}
    assert why_not_named(effects[0], res) == "no: " + reason
    assert why_not_named(effects[0], {**res, "rescue": None}) == "no: unexplained"


def test_gap_map_cells_print_noise_as_below_the_floor():
    from drillgym.eval.diagnosis.figures import gap_text

    assert (
        gap_text(5.5e-12) == "<0.01"
        and gap_text(0.5) == "0.5"
        and gap_text(3.14159) == "3.1"
        and gap_text(152.3) == "152"
    )


def test_the_diagnosis_tries_every_library_effect_but_the_opt_in_ones_by_default():
    from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES, EFFECTS
    from drillgym.eval.diagnosis.diagnose import DiagnoseOptions

    assert set(DIAGNOSIS_CANDIDATES) == set(EFFECTS) - {
        "servo_deadband",
        "ft_gain",
        "ft_contact_bias",
        "registration",
        "kinematic_offset_trend",
    }
    assert DiagnoseOptions().candidates == DIAGNOSIS_CANDIDATES


def test_the_excess_peak_is_where_the_real_residuals_ring_above_the_null_ones():
    from drillgym.eval.diagnosis.spectrum import excess_peak_hz, excess_peaks_hz

    rng = np.random.default_rng(3)
    t = np.arange(1500) * 0.01
    null = [0.02 * rng.standard_normal((1500, 3)) for _ in range(4)]
    ringing = [
        x + 0.05 * np.sin(2 * np.pi * 25.0 * t)[:, None]
        for x in (0.02 * rng.standard_normal((1500, 3)) for _ in range(4))
    ]
    assert excess_peak_hz(ringing, null) == pytest.approx(25.0, abs=100.0 / 128)  # one Welch bin
    assert excess_peak_hz(null[:2], null[2:]) is None  # noise against noise: nothing to read
    lateral = [x + 0.1 * np.sin(2 * np.pi * 15.0 * t)[:, None] * [1, 1, 0] for x in ringing]
    peaks = excess_peaks_hz(lateral, null)  # the axial axis rings at 25 Hz, the lateral ones most at 15
    assert peaks["axial"] == pytest.approx(25.0, abs=100.0 / 128)
    assert peaks["lateral"] == pytest.approx(15.0, abs=100.0 / 128)


def _report_of(effects, calibration=6, heldout=6, leftover=None):
    from drillgym.eval.diagnosis.report import _markdown

    res = {
        "verdict": "explained",
        "summary": "test",
        "significance": {"gap": 2.0, "null": 1.0, "median_episode_ratio": 2.0, "significant": True},
        "episodes": {
            "n": calibration + heldout,
            "calibration": [f"c{i}" for i in range(calibration)],
            "heldout": [f"h{i}" for i in range(heldout)],
            "repairs": {},
        },
        "effects": effects,
        "leftover": leftover,
        "where": {"largest_excess": []},
        "timing": {
            "total_s": 1,
            "workers": 1,
            "baseline_s": 0,
            "singles_s": 0,
            "pairs_s": 0,
            "candidates": 2,
            "pairs": 2,
        },
    }
    return _markdown(res, {})


def _model(name, params, named=False):
    return {
        "name": name,
        "effects": name.split("+"),
        "params": params,
        "heldout_gap_before": 2.0,
        "heldout_gap_after": 1.0,
        "shrink": 0.5,
        "ci_low": 0.3,
        "ci_high": 0.7,
        "p_best": 0.5,
        "named": named,
        "param_intervals": {},
    }


def test_the_report_shows_a_pair_fitted_in_both_orders_once():
    lat, fric = {"extra_latency_s": 0.05}, {"coulomb_rad": 2e-4, "viscous_s": 0.0}
    effects = [
        _model("latency", {"latency": lat}, named=True),
        _model("latency+joint_friction", {"latency": lat, "joint_friction": fric}),
        _model("joint_friction+latency", {"joint_friction": fric, "latency": lat}),
        _model("joint_friction", {"joint_friction": fric}),
    ]
    text = _report_of(effects)
    assert "| latency+joint_friction |" in text and "| joint_friction+latency |" not in text
    assert "| joint_friction |" in text


def test_the_report_flags_a_parameter_at_its_search_bound():
    effects = [_model("latency", {"latency": {"extra_latency_s": 0.3}}, named=True)]
    assert "extra_latency_s=0.3 (**at its upper bound**)" in _report_of(effects)
    inside = [_model("latency", {"latency": {"extra_latency_s": 0.05}}, named=True)]
    assert "bound" not in _report_of(inside)
    off = [_model("joint_friction", {"joint_friction": {"coulomb_rad": 2e-4, "viscous_s": 0.0}}, named=True)]
    assert "bound" not in _report_of(off)  # 0 at the lower end is the off value, not a limit


def test_the_report_warns_when_fewer_episodes_back_it_than_its_intervals_need():
    effects = [_model("latency", {"latency": {"extra_latency_s": 0.05}}, named=True)]
    assert "Few episodes" in _report_of(effects, calibration=2, heldout=2)
    assert "Few episodes" not in _report_of(effects, calibration=6, heldout=6)


def test_the_rest_after_the_named_model_is_put_beside_the_gap_before_it_on_the_same_scale():
    """449x the simulator's level left reads as a contradiction of a 99.8 % shrink unless the gap before is
    given in the same units: before/G0 = after/G0 · before/after (here 449 · 2 / 1 = 898)."""
    named = _model("latency", {"latency": {"delay_s": 0.01}}, named=True)
    leftover = {"ratio": 449.0, "cells": [{"channel": "ty_nm", "stage": "retract", "share": 0.67}]}
    text = _report_of([named], leftover=leftover)
    assert "**449× the simulator's own level**" in text and "(before it, the gap was 898× that level)" in text
