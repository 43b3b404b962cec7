"""Joint-stiffness identification from load tests (Li et al. 2023 §2.2.1 eq. 8, Zhang et al. 2005 §II).

With the small torsion of the tool ignored, the translation ``U`` (m, base axes) of a point under a pure
force ``F`` (N, base axes) at that point is linear in the joint compliances ``D = 1/Kθ`` (rad/(N·m)):
``U = B·D``, column ``j`` of ``B`` being ``J_v[:, j] · (J_v[:, j]ᵀ F)`` (``J_v``: the point's three
translational Jacobian rows). Stacking (pose, force, displacement) triples over poses and loads and solving
for ``D ≥ 0`` by non-negative least squares gives ``Kθ = 1/D``.

The loaded and measured point is the drill tip (``tcp``), optionally moved by a rigid lever
(``point_offset_m``, frame axes) so that a tip force can torque joint 6. An optical tracker follows the
tool's rigid body and the tip displacement is derived from it; its noise is stated per axis on the
measured tip displacement (the CLI's default, 0.05 mm, stands for an NDI Polaris-class tracker after
averaging many frames of a static load).

The simulated "real" robot deflects by the nonlinear static equilibrium ``q = q0 + Kθ⁻¹ J(q)ᵀ W``, so the
linear model of eq. 8 is tested against something it does not assume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD
from drillgym.envs.robot.load_tests import (
    REL_STD_ERROR_MAX,
    LoadExperiments,
    _unit_columns,
    inverse_information_diag,
    regressor,
)
from drillgym.envs.robot.stiffness_design import suggest_experiments
from drillgym.envs.robot.ur5 import UR5Kinematics


def _nnls(B: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``argmin |B·D − u|`` over ``D ≥ 0``; joints the loads do not excite get ``D = 0``."""
    B_unit, scale, excited = _unit_columns(B)
    d = np.zeros(B.shape[1])
    d_unit, _ = nnls(B_unit[:, excited], u, maxiter=50 * B.shape[1])
    d[excited] = d_unit / scale[excited]
    return d


@dataclass(frozen=True)
class StiffnessIdentification:
    """Identified joint stiffnesses with their uncertainty (joints ordered shoulder pan to wrist 3)."""

    stiffness_nm_rad: np.ndarray
    """Kθ = 1/D (N·m/rad) where identified, ``nan`` elsewhere: no number is given for those."""
    compliance_rad_nm: np.ndarray
    """D, the non-negative least-squares estimate for every joint (rad/(N·m)); what predictions use."""
    ci95_nm_rad: np.ndarray
    """(6, 2) 95% interval of Kθ (N·m/rad) from a seeded residual bootstrap of the compliances; the upper
    end is ``inf`` where the compliance interval reaches zero, ``(0, inf)`` for joints the data cannot
    separate at all."""
    rel_std_error: np.ndarray
    """Relative standard error of Kθ (= of D, delta method) from the residual variance and (BᵀB)⁻¹."""
    identified: np.ndarray
    """Per joint: rel. std. error ≤ ``rel_std_error_max`` and the compliance CI excludes zero."""
    rel_std_error_max: float
    """The threshold used for ``identified``."""
    condition_number: float
    """Condition number of ``B`` over the joints the loads excite (``B`` of a joint they do not is zero)."""
    residual_rms_m: float
    """RMS of the fit residuals (m): should match the tracker noise."""
    n_measurements: int
    """Number of (pose, force) experiments, three equations each."""
    suggestions: list[str]
    """What would identify the joints that are not identified (empty when all are)."""


def identify_joint_stiffness(
    data: LoadExperiments,
    n_bootstrap: int = 1000,
    seed: int = 0,
    rel_std_error_max: float = REL_STD_ERROR_MAX,
    planning_stiffness_nm_rad: np.ndarray | None = None,
    kin: UR5Kinematics | None = None,
) -> StiffnessIdentification:
    """Solve eq. 8 for ``D ≥ 0`` and attach confidence intervals, identifiability and suggestions.

    Args:
        data: the stacked load tests.
        n_bootstrap: residual-bootstrap resamples (the design is held fixed, the residuals resampled).
        seed: bootstrap seed.
        rel_std_error_max: largest relative standard error of an identified joint.
        planning_stiffness_nm_rad: prior Kθ used only to plan the suggested experiments (never reported as
            an estimate); defaults to Li et al. 2023.
        kin: the arm, to plan extra poses in the suggestions; ``None`` skips that suggestion.
    """
    B = regressor(data.jacobian, data.force_n)
    u = data.displacement_m.reshape(-1)
    _, _, excited = _unit_columns(B)
    m, p = B.shape[0], int(excited.sum())
    d_hat = _nnls(B, u)
    resid = u - B @ d_hat
    sigma2 = float(resid @ resid) / max(m - p, 1)
    info_diag = inverse_information_diag(B)
    resolved = np.isfinite(info_diag)
    se = np.sqrt(sigma2 * np.where(resolved, info_diag, 0.0))
    safe_d = np.where(d_hat > 0.0, d_hat, 1.0)
    rel_se = np.where(resolved & (d_hat > 0.0), se / safe_d, np.inf)

    rng = np.random.default_rng(seed)
    centred = (resid - resid.mean()) * np.sqrt(m / max(m - p, 1))
    fitted = B @ d_hat
    boot = np.array([_nnls(B, fitted + rng.choice(centred, m)) for _ in range(n_bootstrap)])
    d_lo, d_hi = np.percentile(boot, [2.5, 97.5], axis=0)
    d_lo = np.where(resolved, d_lo, 0.0)
    d_hi = np.where(resolved, d_hi, np.inf)
    with np.errstate(divide="ignore"):
        ci = np.column_stack([1.0 / d_hi, 1.0 / d_lo])
    identified = (rel_se <= rel_std_error_max) & (d_lo > 0.0)
    prior = KTHETA_LI2023_NM_RAD if planning_stiffness_nm_rad is None else planning_stiffness_nm_rad
    return StiffnessIdentification(
        stiffness_nm_rad=np.where(identified, 1.0 / safe_d, np.nan),
        compliance_rad_nm=d_hat,
        ci95_nm_rad=ci,
        rel_std_error=rel_se,
        identified=identified,
        rel_std_error_max=rel_std_error_max,
        condition_number=float(np.linalg.cond(B[:, excited])),
        residual_rms_m=float(np.sqrt(np.mean(resid**2))),
        n_measurements=len(data.force_n),
        suggestions=suggest_experiments(data, identified, float(np.sqrt(sigma2)), 1.0 / prior, rel_std_error_max, kin),
    )
