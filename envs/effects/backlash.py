"""Joint candidate effect: gear backlash, the links lag the motors by up to the play (encoders on the motors)."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost, Param
from drillgym.envs.effects.joints import link_offsets, move_links
from drillgym.envs.record_fields import float_field
from drillgym.envs.robot.ur5_kernel import frame_pose

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
    kernel_params = (
        float_field(
            "backlash_half_rad", "Joint backlash: half the play of each of the first three joints (rad; 0: off)."
        ),
    )
    kernel_state = (
        float_field("link_q_rad", "Joint backlash: the link angles of the first three joints (rad).", JOINTS),
        float_field("link_tip_task_m", "Joint backlash: its share of the geometry offset (m, task frame).", 3),
        float_field("link_marker_base_m", "Joint backlash: its share of the marker offset (m, base frame).", 3),
    )

    def attach(self, env: EffectHost) -> None:
        """Links centred in their play; no offset yet."""
        self.q_link = np.array(env.cell.q_motor_rad, dtype=float)
        self.share = (np.zeros(3), np.zeros(3))

    def set_kernel_params(self, p: np.void) -> None:
        """Half the play; with play, the links move the tool and the marker from the first step on."""
        half = 0.5 * self.values["play_rad"]
        p["backlash_half_rad"] = half
        if half > 0.0:
            p["geometry_on"] = p["marker_on"] = p["target_offset_on"] = True

    def load_kernel_state(self, s: np.void) -> None:
        """The link angles and the links' shares of the offsets."""
        s["link_q_rad"] = self.q_link[:JOINTS]
        s["link_tip_task_m"], s["link_marker_base_m"] = self.share

    def store_kernel_state(self, s: np.void) -> None:
        """The link angles and the links' shares of the offsets."""
        self.q_link[:JOINTS] = s["link_q_rad"]
        self.share = (s["link_tip_task_m"].copy(), s["link_marker_base_m"].copy())

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


@numba.njit(cache=True)
def move_links_kernel(s: Any, p: Any, chains: np.ndarray) -> None:  # pragma: no cover (compiled)
    """:class:`JointBacklash`'s ``begin_step`` on an episode's records (``chains``: the TCP's and the marker's).

    The links of the first three joints kept within half the play of their motors; their offsets of the tool tip
    (task frame) and the marker (base frame) replace the effect's earlier share of the geometry offsets, and the
    servo-held point moves with the tip.
    """
    half = p.backlash_half_rad
    q_m = s.q_motor_rad  # read only here
    q_link = q_m.copy()
    for j in range(JOINTS):
        q_link[j] = min(max(s.link_q_rad[j], q_m[j] - half), q_m[j] + half)
        s.link_q_rad[j] = q_link[j]
    tip = p.R_base_task.T @ (frame_pose(q_link, chains[0])[1] - frame_pose(q_m, chains[0])[1])
    marker = frame_pose(q_link, chains[1])[1] - frame_pose(q_m, chains[1])[1]
    geo, mark = s.geometry_offset_task_m, s.marker_offset_base_m
    link_tip, link_marker = s.link_tip_task_m, s.link_marker_base_m
    for i in range(3):
        geo[i] = geo[i] - link_tip[i] + tip[i]
        mark[i] = mark[i] - link_marker[i] + marker[i]
        s.tip_balance[i] = s.tip_balance[i] + (tip[i] - link_tip[i])
        link_tip[i], link_marker[i] = tip[i], marker[i]
        s.target_offset_task_m[i] = geo[i]
