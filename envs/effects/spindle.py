"""Spindle candidate effect: the spindle slows under the cutting torque (speed sag)."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.record_fields import float_field

MIN_SPEED_SHARE = 0.1
"""Floor of the spindle speed as a share of its no-load speed (a drill near stall still turns)."""


def sagged_rpm(no_load_rpm: float, sag_per_nm: float, torque_nm: float) -> float:
    """Spindle speed (rpm) at a cutting torque ``torque_nm`` (N·m, either sign) on a linear torque-speed line.

    ``ω = ω₀ (1 − k |M|)`` (floored at :data:`MIN_SPEED_SHARE` of ω₀); ``k = 1 / M_stall``, the motor's
    speed loss per N·m (1/(N·m)).
    """
    return no_load_rpm * max(1.0 - sag_per_nm * abs(torque_nm), MIN_SPEED_SHARE)


class SpindleSag(Effect):
    """Spindle speed sag: the drill turns slower as it cuts harder, so each lip takes a thicker chip.

    An unregulated DC spindle motor has a linear torque-speed line, ``ω = ω₀ (1 − M / M_stall)``. At the
    start of every agent step the speed is set from the last sample's cutting torque about the drill axis
    (quasi-static: the motor's own time constant is taken as short against the feed); the chip per lip
    ``h = v / (n ω)`` and with it the chip-dependent part of every cutting force grow by ``ω₀ / ω``.
    Nothing changes before contact (no torque, no sag). A 1.5 mm drill in cortical bone takes ~1 mN·m; a
    small direct-drive motor stalls at 5–20 mN·m, so 5–20 % sag in the cut.

    The cell's ``spindle_rpm`` carries the speed (``clear_effects`` restores the scenario's); thermal
    softening's cutting power stays at the scenario's speed.
    """

    name = "spindle_sag"
    summary = "spindle speed falls linearly with the cutting torque: thicker chips, larger forces"
    params = (Param("sag_per_nm", 0.0, 500.0, 0.0, "speed loss per N·m of cutting torque, 1 / stall torque (1/(N·m))"),)
    channels = frozenset({"force", "torque", "tracker"})
    compiled = True
    kernel_params = (
        float_field("spindle_sag_per_nm", "Spindle speed loss per N·m of cutting torque (1/(N·m); 0: off)."),
    )

    def set_kernel_params(self, p: np.void) -> None:
        """The speed loss per N·m."""
        p["spindle_sag_per_nm"] = self.values["sag_per_nm"]

    def begin_step(self, env: EffectHost) -> None:
        """Set the spindle speed from the last sample's cutting torque."""
        k = self.values["sag_per_nm"]
        if k == 0.0:
            return
        cell = env.cell
        cell.spindle_rpm = sagged_rpm(env.scenario.spindle_rpm, k, cell.sample.torque_axis)


@numba.njit(cache=True)
def sag(s: Any, p: Any) -> None:  # pragma: no cover (compiled)
    """:class:`SpindleSag`'s ``begin_step`` on an episode's records: the speed share from the last sample's torque."""
    s.spindle_share = max(1.0 - p.spindle_sag_per_nm * abs(s.sample[9]), MIN_SPEED_SHARE)
