"""Effects whose parameters drift over a series of holes, in the order the holes were drilled.

A static effect has one value for every episode; a trend form has its value at the series' first hole and at its
last, and each episode takes the straight line between them at its :attr:`~drillgym.envs.effects.base.Effect.
series_position` (0 first, 1 last), which the diagnosis sets from the logs' order. Its held-out episodes are then
predicted, not fitted: their values follow from where they sit in the series.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from drillgym.envs.effects.base import EffectHost, Param
from drillgym.envs.effects.joints import KinematicOffset, add_geometry_offset


class KinematicOffsetTrend(KinematicOffset):
    """A kinematic offset that drifts linearly from hole to hole (a warming arm, a loosening mount).

    The tool and marker sit ``δ = δ_first + (δ_last − δ_first) · position`` away from where the controller's model
    puts them (base frame), ``position`` this episode's place in the series.
    """

    name = "kinematic_offset_trend"
    summary = "kinematic offset drifting linearly over the series of holes"
    params: ClassVar[tuple[Param, ...]] = (
        Param("dx_first_m", -2e-3, 2e-3, 0.0, "tool offset along base x at the series' first hole (m)"),
        Param("dy_first_m", -2e-3, 2e-3, 0.0, "tool offset along base y at the first hole (m)"),
        Param("dz_first_m", -2e-3, 2e-3, 0.0, "tool offset along base z at the first hole (m)"),
        Param("dx_last_m", -2e-3, 2e-3, 0.0, "tool offset along base x at the series' last hole (m)"),
        Param("dy_last_m", -2e-3, 2e-3, 0.0, "tool offset along base y at the last hole (m)"),
        Param("dz_last_m", -2e-3, 2e-3, 0.0, "tool offset along base z at the last hole (m)"),
    )
    variant_of = "kinematic_offset"
    in_series = True
    compiled = True

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """A straight line through each hole's tracker offset before contact, over its place in the series.

        The tracker before contact reads each hole's offset itself; the line's values at the series' first and
        last place are the start. Without two holes at different places (or their readings), the static offset's
        reading at both ends.
        """
        static = KinematicOffset.initial_guess(evidence)
        if static is None:
            return None
        ends = np.array([[static[f"d{axis}_base_m"] for axis in "xyz"]] * 2)
        offsets = np.asarray(evidence.get("tracker_offsets_task_m", ()), dtype=float).reshape(-1, 3)
        positions = np.asarray(evidence.get("series_positions", ()), dtype=float)
        ok = np.isfinite(offsets).all(axis=1) & np.isfinite(positions)
        if ok.sum() >= 2 and np.ptp(positions[ok]) > 0.0:
            base = offsets[ok] @ np.asarray(evidence["R_base_task"]).T  # task -> base frame, per hole
            slope, intercept = np.polyfit(positions[ok], base, 1)
            ends = np.array([intercept, intercept + slope])
        limits = {p.name: (p.low, p.high) for p in cls.params}
        return {
            name: float(np.clip(v, *limits[name]))
            for which, end in zip(("first", "last"), ends, strict=True)
            for name, v in zip((f"d{axis}_{which}_m" for axis in "xyz"), end, strict=True)
        }

    def offset_base_m(self) -> np.ndarray:
        """This episode's offset (m, base frame)."""
        v, s = self.values, float(self.series_position)
        first = np.array([v["dx_first_m"], v["dy_first_m"], v["dz_first_m"]])
        last = np.array([v["dx_last_m"], v["dy_last_m"], v["dz_last_m"]])
        return first + (last - first) * s

    def attach(self, env: EffectHost) -> None:
        """Shift the physical tool and the marker by this episode's offset."""
        d = self.offset_base_m()
        if np.any(d != 0.0):
            add_geometry_offset(env.cell, env.cell.R_base_task.T @ d, d)
