"""``drillgym identify-stiffness``: identify the UR5 joint stiffnesses from simulated load tests.

The simulated robot has Li et al. 2023's Kθ; loads of ``--load-n`` along ±x, ±y, ±z of the base frame are
hung at the drill tip in ``--poses`` poses and the tip displacement is read by a tracker with ``--noise-mm``
of noise per axis. Eq. 8 is solved for Kθ with bootstrap 95% intervals; joints the data cannot pin down are
reported as "not identified" with what would identify them. Then Li's Table 1 is reproduced: predicted vs
"measured" tip deflections at three validation poses.
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD
from drillgym.envs.robot.load_tests import (
    DEFAULT_TCP_OFFSET_M,
    IDENTIFICATION_POSES_Q_RAD,
    LI_TABLE1_MEASURED_Z_MM,
    LI_TABLE1_MODEL_Z_MM,
    axis_loads_n,
    simulate_load_experiments,
)
from drillgym.envs.robot.stiffness_id import StiffnessIdentification, identify_joint_stiffness
from drillgym.envs.robot.stiffness_table1 import Table1Comparison, reproduce_li_table1
from drillgym.envs.robot.ur5 import TCP_FRAME, UR5Kinematics


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``identify-stiffness``."""
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.add_argument("--noise-mm", type=float, default=0.05, help="tracker noise per axis (mm)")
    parser.add_argument("--load-n", type=float, default=100.0, help="load magnitude along ±x, ±y, ±z (N)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the tracker noise and the bootstrap")
    parser.add_argument(
        "--poses",
        type=int,
        default=3,
        choices=range(1, len(IDENTIFICATION_POSES_Q_RAD) + 1),
        metavar=f"1..{len(IDENTIFICATION_POSES_Q_RAD)}",
        help="number of load-test poses (the first 3 hold the tool vertical, the rest tilt the wrist)",
    )
    parser.add_argument(
        "--lever-mm", type=float, default=0.0, help="load the tool this far off its axis, along flange x (mm)"
    )
    parser.add_argument("--bootstrap", type=int, default=1000, help="bootstrap resamples for the 95%% CIs")


def _num(x: float) -> float | None:
    """JSON-safe float: ``None`` for inf and nan."""
    return float(x) if math.isfinite(x) else None


def _result_dict(
    args: argparse.Namespace, loads_n: np.ndarray, res: StiffnessIdentification, table: Table1Comparison
) -> dict[str, Any]:
    """Everything the text report shows, as plain JSON types (SI units unless the key says mm)."""
    joints = [
        {
            "joint": j + 1,
            "truth_nm_rad": float(KTHETA_LI2023_NM_RAD[j]),
            "estimate_nm_rad": _num(res.stiffness_nm_rad[j]),
            "ci95_nm_rad": [_num(res.ci95_nm_rad[j, 0]), _num(res.ci95_nm_rad[j, 1])],
            "rel_std_error": _num(res.rel_std_error[j]),
            "identified": bool(res.identified[j]),
            "compliance_rad_nm": float(res.compliance_rad_nm[j]),
        }
        for j in range(6)
    ]
    rows = [
        {
            "pose": i + 1,
            "q_rad": table.q_rad[i].tolist(),
            "force_n": table.force_n[i].tolist(),
            "measured_mm": (table.measured_m[i] * 1e3).tolist(),
            "predicted_mm": (table.predicted_m[i] * 1e3).tolist(),
            "error_mm": (table.error_m[i] * 1e3).tolist(),
        }
        for i in range(len(table.q_rad))
    ]
    return {
        "setup": {
            "truth": "Li et al. 2023 §3.3",
            "noise_mm": args.noise_mm,
            "loads_n": loads_n.tolist(),
            "poses_q_rad": IDENTIFICATION_POSES_Q_RAD[: args.poses].tolist(),
            "tcp_offset_m": DEFAULT_TCP_OFFSET_M,
            "lever_m": args.lever_mm * 1e-3,
            "seed": args.seed,
            "n_bootstrap": args.bootstrap,
            "rel_std_error_max": res.rel_std_error_max,
        },
        "joints": joints,
        "condition_number": res.condition_number,
        "residual_rms_mm": res.residual_rms_m * 1e3,
        "n_measurements": res.n_measurements,
        "suggestions": res.suggestions,
        "table1": {
            "rows": rows,
            "max_abs_error_mm": table.max_abs_error_m * 1e3,
            "li2023_measured_z_mm": LI_TABLE1_MEASURED_Z_MM.tolist(),
            "li2023_model_z_mm": LI_TABLE1_MODEL_Z_MM.tolist(),
            "li2023_abs_error_z_mm": np.abs(LI_TABLE1_MODEL_Z_MM - LI_TABLE1_MEASURED_Z_MM).round(3).tolist(),
        },
    }


def _k(x: float | None) -> str:
    """Stiffness (N·m/rad) printed in kN·m/rad."""
    return "∞" if x is None else f"{x / 1e3:.1f}"


def _print_report(out: dict[str, Any]) -> None:
    """Readable tables of the identification and of the Table 1 reproduction."""
    s = out["setup"]
    print(
        f"Load tests: {len(s['poses_q_rad'])} poses × {len(s['loads_n'])} loads of "
        f"{np.abs(s['loads_n']).max():.0f} N (±x, ±y, ±z) at the drill tip, "
        f"lever {s['lever_m'] * 1e3:.0f} mm; tracker noise {s['noise_mm']:.3f} mm per axis; "
        f"truth Kθ: {s['truth']}."
    )
    print("Kθ in kN·m/rad:")
    print(f"{'joint':>5} {'truth':>8} {'estimate':>15} {'95% CI':>17} {'rel.SE':>8} {'identified':>10}")
    for j in out["joints"]:
        est = _k(j["estimate_nm_rad"]) if j["identified"] else "not identified"
        ci = f"[{_k(j['ci95_nm_rad'][0])}, {_k(j['ci95_nm_rad'][1])}]"
        rse = "∞" if j["rel_std_error"] is None else f"{j['rel_std_error']:.1%}"
        print(
            f"{'J' + str(j['joint']):>5} {_k(j['truth_nm_rad']):>8} {est:>15} {ci:>17} {rse:>8} "
            f"{'yes' if j['identified'] else 'no':>10}"
        )
    print(
        f"Condition number of B: {out['condition_number']:.1f}; residual RMS {out['residual_rms_mm']:.3f} mm "
        f"over {out['n_measurements']} measurements; identified means rel.SE ≤ "
        f"{s['rel_std_error_max']:.0%} and a CI that excludes zero compliance."
    )
    if out["suggestions"]:
        print("To identify the rest:")
        for line in out["suggestions"]:
            print(f"  - {line}")
    t = out["table1"]
    print("\nLi et al. 2023 Table 1 reproduction: tip deflection (mm), simulated robot + tracker noise vs model")
    print(f"{'pose':>4} {'force (N)':>18} {'axis':>4} {'measured':>9} {'predicted':>9} {'error':>7}")
    for row in t["rows"]:
        force = "(" + ", ".join(f"{f:.0f}" for f in row["force_n"]) + ")"
        for a, axis in enumerate("xyz"):
            print(
                f"{row['pose'] if a == 0 else '':>4} {force if a == 0 else '':>18} {axis:>4} "
                f"{row['measured_mm'][a]:>9.3f} {row['predicted_mm'][a]:>9.3f} {row['error_mm'][a]:>7.3f}"
            )
    li = ", ".join(f"{m:.2f}/{p:.2f}" for m, p in zip(t["li2023_measured_z_mm"], t["li2023_model_z_mm"], strict=True))
    li_err = ", ".join(f"{e:.2f}" for e in t["li2023_abs_error_z_mm"])
    within = "yes" if t["max_abs_error_mm"] <= 0.15 else "no"
    print(
        f"Max |error| here: {t['max_abs_error_mm']:.3f} mm (≤ 0.15 mm: {within}). "
        f"Li 2023 Table 1, z, measured/model (mm): {li}; |error| {li_err} mm."
    )


def identify_and_compare(
    noise_mm: float = 0.05, load_n: float = 100.0, seed: int = 0, poses: int = 3, lever_mm: float = 0.0
) -> dict[str, Any]:
    """The default identification and Table 1 comparison as plain numbers (for reports)."""
    args = argparse.Namespace(
        noise_mm=noise_mm, load_n=load_n, seed=seed, poses=poses, lever_mm=lever_mm, bootstrap=1000, json=True
    )
    kin = UR5Kinematics(DEFAULT_TCP_OFFSET_M)
    rng = np.random.default_rng(seed)
    data = simulate_load_experiments(
        kin,
        IDENTIFICATION_POSES_Q_RAD[:poses],
        axis_loads_n(load_n),
        KTHETA_LI2023_NM_RAD,
        noise_mm * 1e-3,
        rng,
        frame=TCP_FRAME,
        point_offset_m=np.array([lever_mm * 1e-3, 0.0, 0.0]),
    )
    res = identify_joint_stiffness(data, n_bootstrap=1000, seed=seed, kin=kin)
    table = reproduce_li_table1(kin, res.compliance_rad_nm, KTHETA_LI2023_NM_RAD, noise_mm * 1e-3, rng)
    with np.errstate(divide="ignore"):
        estimate = np.where(res.compliance_rad_nm > 0, 1.0 / np.maximum(res.compliance_rad_nm, 1e-300), np.inf)
    return {
        "truth_knm": (KTHETA_LI2023_NM_RAD / 1e3).tolist(),
        "estimate_knm": (estimate / 1e3).tolist(),
        "ci_knm": (res.ci95_nm_rad / 1e3).tolist(),
        "rel_std_error": res.rel_std_error.tolist(),
        "identified": res.identified.tolist(),
        "table1_measured_mm": (table.measured_m * 1e3).tolist(),
        "table1_predicted_mm": (table.predicted_m * 1e3).tolist(),
        "table1_force_n": table.force_n.tolist(),
        "table1_max_err_mm": table.max_abs_error_m * 1e3,
        "noise_mm": noise_mm,
        "load_n": load_n,
        "summary": _result_dict(args, axis_loads_n(load_n), res, table),
    }


def run(args: argparse.Namespace) -> int:
    """Simulate the load tests, identify Kθ, reproduce Table 1 and print the result."""
    kin = UR5Kinematics(DEFAULT_TCP_OFFSET_M)
    rng = np.random.default_rng(args.seed)
    loads_n = axis_loads_n(args.load_n)
    noise_m = args.noise_mm * 1e-3
    data = simulate_load_experiments(
        kin,
        IDENTIFICATION_POSES_Q_RAD[: args.poses],
        loads_n,
        KTHETA_LI2023_NM_RAD,
        noise_m,
        rng,
        frame=TCP_FRAME,
        point_offset_m=np.array([args.lever_mm * 1e-3, 0.0, 0.0]),
    )
    res = identify_joint_stiffness(data, n_bootstrap=args.bootstrap, seed=args.seed, kin=kin)
    table = reproduce_li_table1(kin, res.compliance_rad_nm, KTHETA_LI2023_NM_RAD, noise_m, rng)
    out = _result_dict(args, loads_n, res, table)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        _print_report(out)
    return 0
