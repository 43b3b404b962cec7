"""Reality: gear backlash of its own size in each of the first three joints."""

from __future__ import annotations

import numpy as np

from drillgym.envs.effects.base import EffectHost, Param
from drillgym.envs.effects.joints import link_offsets, move_links
from drillgym.eval.diagnosis.reality.base import RealityEffect


class GearBacklash(RealityEffect):
    """Play ``b_j`` in joint j (0–2): the link angle stays put until the motor reaches either end of the play.

    The tool and the marker follow the links; the encoders, on the motors, read the command. The links start at
    a random place inside their play (the last motion before the episode is unknown). The candidate
    (``joint_backlash``) has one play for the three joints, its links centred at the start.
    """

    name = "gear_backlash"
    summary = "per-joint gear play between motor (encoder) and link"
    explains = "joint_backlash"
    params = (
        Param("play0_rad", 0.0, 1e-3, 0.0, "play of the base joint (rad)"),
        Param("play1_rad", 0.0, 1e-3, 0.0, "play of the shoulder (rad)"),
        Param("play2_rad", 0.0, 1e-3, 0.0, "play of the elbow (rad)"),
    )
    channels = frozenset({"force", "torque", "tracker"})

    def _plays(self) -> np.ndarray:
        return np.array([self.values["play0_rad"], self.values["play1_rad"], self.values["play2_rad"]])

    def attach(self, env: EffectHost) -> None:
        """Links somewhere inside their play."""
        lag = (self.rng.uniform(-0.5, 0.5, 3) * self._plays()) if np.any(self._plays() > 0.0) else np.zeros(3)
        self.q_link = np.asarray(env.cell.q_motor_rad, dtype=float)[:3] + lag
        """Link angles of joints 0–2 (rad)."""
        self.offsets = (np.zeros(3), np.zeros(3))
        self._move(env, at_attach=True)

    def begin_step(self, env: EffectHost) -> None:
        """Links dragged by the motors' last motion."""
        if np.any(self._plays() > 0.0):
            self._move(env, at_attach=False)

    def _move(self, env: EffectHost, at_attach: bool) -> None:
        cell = env.cell
        half = 0.5 * self._plays()
        q = np.asarray(cell.q_motor_rad, dtype=float)
        if not at_attach:  # the link angle holds while the motor moves inside the play
            self.q_link = q[:3] + np.clip(self.q_link - q[:3], -half, half)
        q_link = q.copy()
        q_link[:3] = self.q_link
        new = link_offsets(cell, q_link, q)
        move_links(cell, self.offsets, new, with_tip=at_attach)  # at attach the tool starts where the links put it
        self.offsets = new

    def candidate_values(self) -> dict[str, float] | None:
        """One play for the three joints where they are one (the start's random place aside)."""
        b = self._plays()
        return {"play_rad": float(b[0])} if b[0] == b[1] == b[2] else None
