"""What the data say directly of an effect, before any fit: the starting points of :func:`~drillgym.eval.diagnosis.fit.fit_model`.

Each reading compares the calibration episodes with their nominal replays where one kind of effect shows
alone: the tracker before contact (a kinematic offset), where the force residuals ring (a structural mode),
and how much later or earlier the drill touches bone (a registration error).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs.scenario import Scenario
from drillgym.eval.diagnosis.channels import FORCE

DEFAULT_BETA_DEG = Scenario().beta_deg
"""The surface inclination of a log whose header leaves it out: the one the replay's scenario then has."""
CONTACT_FORCE_N = 0.3
"""Force magnitude (N) taken as the first touch: 20 times the F/T's noise before contact (~0.015 N), a few
samples into the contact's rise at the paper's feed."""


def first_contact(force_n: np.ndarray, threshold_n: float = CONTACT_FORCE_N) -> int | None:
    """Index of the first sample whose force magnitude exceeds ``threshold_n`` (None: never)."""
    above = np.linalg.norm(np.nan_to_num(force_n), axis=1) > threshold_n
    return int(np.argmax(above)) if above.any() else None


def contact_shift_m(real_force_n: np.ndarray, sim_force_n: np.ndarray, depth_cmd_m: np.ndarray) -> float | None:
    """How much further along the axis (m) the real drill was commanded when it touched than the replay's.

    Both traces follow the same commands, so the commanded depth at each one's first contact tells the two
    apart in length, whatever the feed. None where either never touches.
    """
    k_real, k_sim = first_contact(real_force_n), first_contact(sim_force_n)
    if k_real is None or k_sim is None:
        return None
    return float(depth_cmd_m[k_real] - depth_cmd_m[k_sim])


def evidence(d: Any) -> dict[str, Any] | None:
    """The readings of a :class:`~drillgym.eval.diagnosis.context.DiagnosisData` (calibration episodes only).

    Made once, with the baseline replays, as ``d.evidence``.

    ``tracker_offset_task_m`` (mean real-minus-sim tracker position before contact, m, task frame), per episode
    ``tracker_offsets_task_m`` (n, 3) at ``series_positions`` (each episode's place in the series, 0 to 1),
    ``R_base_task`` (3x3), ``excess_peaks_hz`` (where the force residuals ring most above the simulator's own:
    ``all``, ``lateral``, ``axial``; Hz or None), ``contact_shift_m`` and ``beta_rad`` (each episode's contact
    shift, :func:`contact_shift_m`, and its planned surface inclination; episodes that touch in both). None
    without a tracker reading before contact.
    """
    offsets, positions, shifts, betas = [], [], [], []
    for i in d.cal:
        rows = d.blocks[i].stage == 0
        r = d.real[i].lf[rows, 6:9] - d.nominal_features[i].lf[rows, 6:9]
        if np.isfinite(r).any():
            offsets.append(np.nanmean(r, axis=0))
            positions.append(float(d.episodes[i].series_position))
        ep = d.episodes[i]
        shift = contact_shift_m(ep.lf[:, FORCE], d.nominal[i].lf[:, FORCE], ep.depth_cmd_m)
        if shift is not None:
            shifts.append(shift)
            betas.append(math.radians(float(ep.scenario.get("beta_deg", DEFAULT_BETA_DEG))))
    if not offsets:
        return None
    return {
        "tracker_offset_task_m": np.mean(offsets, axis=0),
        "tracker_offsets_task_m": np.asarray(offsets),
        "series_positions": np.asarray(positions),
        "R_base_task": d.episodes[d.cal[0]].r_base_task,
        "excess_peaks_hz": d.excess_peaks_hz,
        "contact_shift_m": np.asarray(shifts),
        "beta_rad": np.asarray(betas),
    }
