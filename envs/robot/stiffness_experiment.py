"""Identify the UR5 joint stiffnesses from simulated load tests and reproduce Li et al. 2023's Table 1.

The simulated robot has Li's Kθ; loads along ±x, ±y, ±z of the base frame are hung at the drill tip in a
few poses and the tip displacement is read by a tracker with some noise per axis. Eq. 8 is solved for Kθ
with bootstrap 95 % intervals; joints the data cannot pin down are reported as not identified. Then Li's
Table 1 is reproduced: predicted vs "measured" tip deflections at three validation poses.
``drillgym identify-stiffness`` (:mod:`drillgym.eval.cli.identify_stiffness`) prints it; the reproduction
report uses :func:`identify_and_compare`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
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


@dataclass(frozen=True)
class LoadTestSettings:
    """The simulated load tests.

    Attributes:
        noise_mm: tracker noise per axis (mm).
        load_n: load magnitude along ±x, ±y, ±z (N).
        seed: seed of the tracker noise and the bootstrap.
        poses: number of load-test poses (the first 3 hold the tool vertical, the rest tilt the wrist).
        lever_mm: the load hangs this far off the tool axis, along flange x (mm).
        bootstrap: bootstrap resamples for the 95 % intervals.
    """

    noise_mm: float = 0.05
    load_n: float = 100.0
    seed: int = 0
    poses: int = 3
    lever_mm: float = 0.0
    bootstrap: int = 1000

    def __post_init__(self) -> None:
        if not 1 <= self.poses <= len(IDENTIFICATION_POSES_Q_RAD):
            raise UserError(f"poses={self.poses} must lie in 1..{len(IDENTIFICATION_POSES_Q_RAD)}")
        if not (math.isfinite(self.noise_mm) and self.noise_mm >= 0.0):
            raise UserError(f"noise_mm={self.noise_mm} must be a finite number >= 0")
        if not (math.isfinite(self.load_n) and self.load_n > 0.0):
            raise UserError(f"load_n={self.load_n} must be a finite number > 0")
        if not math.isfinite(self.lever_mm):
            raise UserError(f"lever_mm={self.lever_mm} must be finite")
        if self.bootstrap < 1:
            raise UserError(f"bootstrap={self.bootstrap} must be >= 1")


def run_load_tests(settings: LoadTestSettings) -> tuple[np.ndarray, StiffnessIdentification, Table1Comparison]:
    """Simulate the load tests, identify Kθ, reproduce Table 1: ``(loads_n, identification, table1)``."""
    kin = UR5Kinematics(DEFAULT_TCP_OFFSET_M)
    rng = np.random.default_rng(settings.seed)
    loads_n = axis_loads_n(settings.load_n)
    noise_m = settings.noise_mm * 1e-3
    data = simulate_load_experiments(
        kin,
        IDENTIFICATION_POSES_Q_RAD[: settings.poses],
        loads_n,
        KTHETA_LI2023_NM_RAD,
        noise_m,
        rng,
        frame=TCP_FRAME,
        point_offset_m=np.array([settings.lever_mm * 1e-3, 0.0, 0.0]),
    )
    res = identify_joint_stiffness(data, n_bootstrap=settings.bootstrap, seed=settings.seed, kin=kin)
    table = reproduce_li_table1(kin, res.compliance_rad_nm, KTHETA_LI2023_NM_RAD, noise_m, rng)
    return loads_n, res, table


def _num(x: float) -> float | None:
    """JSON-safe float: ``None`` for inf and nan."""
    return float(x) if math.isfinite(x) else None


def result_dict(
    settings: LoadTestSettings, loads_n: np.ndarray, res: StiffnessIdentification, table: Table1Comparison
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
            "noise_mm": settings.noise_mm,
            "loads_n": loads_n.tolist(),
            "poses_q_rad": IDENTIFICATION_POSES_Q_RAD[: settings.poses].tolist(),
            "tcp_offset_m": DEFAULT_TCP_OFFSET_M,
            "lever_m": settings.lever_mm * 1e-3,
            "seed": settings.seed,
            "n_bootstrap": settings.bootstrap,
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


def identify_and_compare(noise_mm: float = 0.05, load_n: float = 100.0, seed: int = 0) -> dict[str, Any]:
    """The default identification and Table 1 comparison as plain numbers (for reports)."""
    settings = LoadTestSettings(noise_mm=noise_mm, load_n=load_n, seed=seed)
    loads_n, res, table = run_load_tests(settings)
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
        "summary": result_dict(settings, loads_n, res, table),
    }
