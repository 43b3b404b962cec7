"""Joint candidate effect: gear backlash, the links lag the motors by up to the play (encoders on the motors)."""

from __future__ import annotations

import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.robot import ur5_kernel

JOINTS = 3
"""The joints with play: base, shoulder and elbow (the wrist's lever to the tip is short)."""


class JointBacklash(Effect):
    """Gear backlash in the first three joints: each link follows its motor only once the motor has crossed the play.

    Per joint, the link angle is the motor angle kept within ``± b/2``: ``q_link = clip(q_link, q_m − b/2, q_m + b/2)``
    (a play operator, updated at each agent step; the link starts centred). The tool, the drill tip and the tracker
    marker sit where the links put them; the encoders, on the motors, read the commanded motion, and so do the
    RTDE joint angles and TCP. Moving one way, the tip trails the command by the play's lever; reversing (the
    retract, a correction), the motor crosses the play before the tip moves. A harmonic drive has ~0.1–1 arcmin
    (3e-5–3e-4 rad) when new, more when worn.
    """

    name = "joint_backlash"
    summary = "gear play: the links (tool, marker) trail the motors by up to half the play; encoders unaware"
    params = (Param("play_rad", 0.0, 1e-3, 0.0, "full play of each of the first three joints (rad)"),)
    channels = frozenset({"force", "torque", "tracker"})
    channels_before_contact = frozenset({"tracker"})

    def attach(self, env: EffectHost) -> None:
        """Links centred in their play; no offset yet."""
        self.q_link = np.array(env.cell.q_motor_rad, dtype=float)
        self.share = (np.zeros(3), np.zeros(3))

    def begin_step(self, env: EffectHost) -> None:
        """Move the links within their play and carry the tool and the marker where they put them."""
        half = 0.5 * self.values["play_rad"]
        if half == 0.0:
            return
        cell = env.cell
        q_m = np.asarray(cell.q_motor_rad, dtype=float)
        self.q_link[:JOINTS] = np.clip(self.q_link[:JOINTS], q_m[:JOINTS] - half, q_m[:JOINTS] + half)
        self.q_link[JOINTS:] = q_m[JOINTS:]
        tcp_chain, marker_chain = cell._tcp_chain, cell._marker_chain
        tip = cell.R_base_task.T @ (
            ur5_kernel.frame_pose(self.q_link, tcp_chain)[1] - ur5_kernel.frame_pose(q_m, tcp_chain)[1]
        )
        marker = ur5_kernel.frame_pose(self.q_link, marker_chain)[1] - ur5_kernel.frame_pose(q_m, marker_chain)[1]
        old_tip, old_marker = self.share
        self.share = (tip, marker)
        geometry = np.zeros(3) if cell.geometry_offset_task_m is None else cell.geometry_offset_task_m
        markers = np.zeros(3) if cell.marker_offset_base_m is None else cell.marker_offset_base_m
        cell.geometry_offset_task_m = geometry - old_tip + tip
        cell.marker_offset_base_m = markers - old_marker + marker
        # The link moved the servo-held point itself (not its target): no servo transient, the encoders unaware.
        s = cell.solver
        s.rigid = [r + d for r, d in zip(s.rigid, (tip - old_tip).tolist(), strict=True)]
