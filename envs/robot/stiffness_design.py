"""Planning load tests that identify every joint: what to add when the data leave joints unidentified."""

from __future__ import annotations

import numpy as np

from drillgym.envs.robot.load_tests import (
    IDENTIFICATION_POSES_Q_RAD,
    REL_STD_ERROR_MAX,
    LoadExperiments,
    _skew,
    design,
    expected_rel_std_error,
    inverse_information_diag,
    regressor,
)
from drillgym.envs.robot.ur5 import UR5Kinematics


def _lever_jacobians(jacobian: np.ndarray, R_base_frame: np.ndarray, lever_m: float) -> np.ndarray:
    """Jacobians of the point moved by ``lever_m`` along the frame's x axis (perpendicular to joint 6)."""
    out = jacobian.copy()
    for i, R in enumerate(R_base_frame):
        out[i, :3] -= _skew(R[:, 0] * lever_m) @ out[i, 3:]
    return out


LEVER_CANDIDATES_M = (0.025, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3)
"""Lever lengths (m) tried when planning an off-axis load."""


def _fmt_rel(e: np.ndarray, joints: np.ndarray) -> str:
    """``"J4 19%, J6 not separable"`` for the listed joints."""
    return ", ".join(f"J{j + 1} {e[j]:.0%}" if np.isfinite(e[j]) else f"J{j + 1} not separable" for j in joints)


def _why_not(
    data: LoadExperiments, bad: np.ndarray, expected: np.ndarray, prior_compliance_rad_nm: np.ndarray
) -> list[str]:
    """Per unidentified joint: its torque arm, its share of the deflection and how it aliases the others."""
    jv = data.jacobian[:, :3, :]
    arm_m = (np.abs(np.einsum("nij,ni->nj", jv, data.force_n)) / np.linalg.norm(data.force_n, axis=1)[:, None]).mean(
        axis=0
    )
    B = regressor(data.jacobian, data.force_n)
    parts = np.linalg.norm(B * prior_compliance_rad_nm, axis=0)
    share = parts / np.linalg.norm(B @ prior_compliance_rad_nm)
    inflation = inverse_information_diag(B) * np.linalg.norm(B, axis=0) ** 2  # 1 for an orthogonal column
    out = []
    for j in bad:
        if arm_m[j] < 1e-3:
            why = "the loaded point lies on its axis, so the loads exert no torque about it"
        else:
            why = f"its compliance moves the point by only ~{share[j]:.0%} of the deflection"
            if inflation[j] >= 2.0:
                why += f", much like the other joints do (variance inflation ×{inflation[j]:.0f})"
        out.append(
            f"J{j + 1}: mean torque arm of the loads {arm_m[j] * 1e3:.0f} mm; {why}. "
            f"This design gives {_fmt_rel(expected, np.array([j]))}."
        )
    return out


def _scale_up(data: LoadExperiments, bad: np.ndarray, expected: np.ndarray, noise_m: float, limit: float) -> list[str]:
    """How much larger loads, less noise or more repeats the separable unidentified joints need."""
    finite = bad[np.isfinite(expected[bad])]
    if finite.size == 0:
        return []
    factor = max(float(np.max(expected[finite])) / limit, 1.0)
    names = ", ".join(f"J{j + 1}" for j in finite)
    return [
        f"{names} at this design: loads ×{factor:.1f} (to {np.abs(data.force_n).max() * factor:.0f} N), or "
        f"tracker noise ÷{factor:.1f} (to {noise_m / factor * 1e3:.3f} mm per axis), or "
        f"{int(np.ceil(factor**2))}× as many repeats of every load."
    ]


def _lever(
    jacobian: np.ndarray,
    R: np.ndarray,
    force_n: np.ndarray,
    bad: np.ndarray,
    noise_m: float,
    prior: np.ndarray,
    limit: float,
    what: str,
) -> str:
    """The shortest candidate lever perpendicular to the tool axis that identifies all of ``bad``.

    If none does, the lever with the lowest worst-case error and the load factor it still needs.
    """
    best: tuple[float, float, np.ndarray] | None = None
    for lever in LEVER_CANDIDATES_M:
        e = expected_rel_std_error(_lever_jacobians(jacobian, R, lever), force_n, noise_m, prior)
        worst = float(np.max(e[bad]))
        if worst <= limit:
            return (
                f"{what}, apply the loads on a rigid lever {lever * 1e3:.0f} mm off the tool axis "
                f"(perpendicular to joint 6): expected {_fmt_rel(e, bad)}."
            )
        if best is None or worst < best[0]:
            best = (worst, lever, e)
    assert best is not None
    worst, lever, e = best
    return (
        f"{what}, no lever up to {LEVER_CANDIDATES_M[-1] * 1e3:.0f} mm is enough alone; the best, "
        f"{lever * 1e3:.0f} mm off the tool axis, gives {_fmt_rel(e, bad)}, and then needs loads "
        f"×{worst / limit:.1f} (or noise ÷{worst / limit:.1f})."
    )


def suggest_experiments(
    data: LoadExperiments,
    identified: np.ndarray,
    noise_m: float,
    prior_compliance_rad_nm: np.ndarray,
    rel_std_error_max: float = REL_STD_ERROR_MAX,
    kin: UR5Kinematics | None = None,
) -> list[str]:
    """Changes to the test, computed from its design, that would identify the unidentified joints.

    Expected errors use the prior compliances and the estimated noise (m): planning figures, not estimates.
    """
    bad = np.flatnonzero(~identified)
    if bad.size == 0:
        return []
    args = (noise_m, prior_compliance_rad_nm, rel_std_error_max)
    expected = expected_rel_std_error(data.jacobian, data.force_n, noise_m, prior_compliance_rad_nm)
    out = _why_not(data, bad, expected, prior_compliance_rad_nm) + _scale_up(
        data, bad, expected, noise_m, rel_std_error_max
    )
    out.append(_lever(data.jacobian, data.R_base_frame, data.force_n, bad, *args, "With these poses"))
    if kin is None:
        return out
    used = {tuple(np.round(q, 9)) for q in data.q_rad}
    extra = [q for q in IDENTIFICATION_POSES_Q_RAD if tuple(np.round(q, 9)) not in used]
    if extra and np.any(bad >= 3):
        loads = data.force_n[np.all(data.q_rad == data.q_rad[0], axis=1)]
        poses = np.concatenate([np.unique(data.q_rad, axis=0), extra])
        J, R, F = design(kin, poses, loads, data.frame, data.point_offset_m)
        e = expected_rel_std_error(J, F, noise_m, prior_compliance_rad_nm)
        what = f"Adding {len(extra)} poses that tilt and turn the wrist (same loads)"
        out.append(f"{what}: expected {_fmt_rel(e, bad)}.")
        out.append(_lever(J, R, F, bad, *args, "With those poses too"))
    return out
