"""Reality: a spindle motor that slows under load with its own inertia."""

from __future__ import annotations

import math

from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.effects.base import EffectHost, Param
from drillgym.envs.effects.spindle import MIN_SPEED_SHARE
from drillgym.eval.diagnosis.reality.base import RealityEffect


class SpindleMotor(RealityEffect):
    """An unregulated DC spindle motor with inertia: ``τ dω/dt = ω₀ (1 − k |M|) − ω``.

    The speed relaxes towards the motor's torque-speed line with the mechanical time constant τ (rotor and
    chuck inertia over the line's slope), integrated exactly over each agent step from the last sample's
    cutting torque M. The candidate (``spindle_sag``) sits on the line at once; the two agree once the cut
    is steady, and differ where the torque changes (the entry, the retract) by about τ times its rate.
    """

    name = "spindle_motor"
    summary = "spindle speed follows a linear torque-speed line with the motor's time constant"
    explains = "spindle_sag"
    params = (
        Param("sag_per_nm", 0.0, 500.0, 0.0, "speed loss per N·m of cutting torque at steady state (1/(N·m))"),
        Param("time_constant_s", 0.01, 2.0, 0.3, "mechanical time constant of motor, chuck and drill (s)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def attach(self, env: EffectHost) -> None:
        """The spindle runs at its no-load speed."""
        self.share = 1.0

    def begin_step(self, env: EffectHost) -> None:
        """Relax the speed over the last step towards the torque-speed line at the last sample's torque."""
        v = self.values
        if v["sag_per_nm"] == 0.0:
            return
        target = max(1.0 - v["sag_per_nm"] * abs(env.cell.sample.torque_axis), MIN_SPEED_SHARE)
        self.share = target + (self.share - target) * math.exp(-CONTROL_DT_S / v["time_constant_s"])
        env.cell.spindle_rpm = env.scenario.spindle_rpm * self.share

    def candidate_values(self) -> dict[str, float] | None:
        """``spindle_sag``'s speed loss is the line's (the motor's lag aside)."""
        return {"sag_per_nm": self.values["sag_per_nm"]}
