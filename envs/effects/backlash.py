"""Joint candidate effect: gear backlash, the links lag the motors by up to the play (encoders on the motors)."""

from __future__ import annotations

import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.effects.joints import link_offsets, move_links

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
    compiled = True

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
        new = link_offsets(cell, self.q_link, q_m)
        move_links(cell, self.share, new)
        self.share = new
