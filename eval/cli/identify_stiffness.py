"""``drillgym identify-stiffness``: identify the UR5 joint stiffnesses from simulated load tests.

Loads of ``--load-n`` along ±x, ±y, ±z of the base frame hang at the drill tip in ``--poses`` poses, a
tracker with ``--noise-mm`` of noise per axis reads the tip (:mod:`drillgym.envs.robot.stiffness_experiment`).
Prints Kθ with bootstrap 95 % intervals ("not identified" where the data cannot pin a joint down, with what
would) and the reproduction of Li's Table 1.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from drillgym.envs.robot.load_tests import IDENTIFICATION_POSES_Q_RAD
from drillgym.envs.robot.stiffness_experiment import LoadTestSettings, result_dict, run_load_tests


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


def run(args: argparse.Namespace) -> int:
    """Simulate the load tests, identify Kθ, reproduce Table 1 and print the result."""
    settings = LoadTestSettings(
        noise_mm=args.noise_mm,
        load_n=args.load_n,
        seed=args.seed,
        poses=args.poses,
        lever_mm=args.lever_mm,
        bootstrap=args.bootstrap,
    )
    out = result_dict(settings, *run_load_tests(settings))
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        _print_report(out)
    return 0
