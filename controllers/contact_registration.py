"""Contact registration on top of any controller: find where the drill really meets the bone, and drill from there.

Every compensator indexes its models by the nominal depth, the path's depth past the planned entry point
(``path_depth_m``): li2023's offline correction is the predicted bending at that depth, a slow entry slows the
first millimetre of it. Both assume that the tip meets the bone where the plan says. A tool whose stick-out
differs from the bench measurement by Δl (a re-grip, a drill seated less deep in the chuck) meets it Δl
early or late, and the cell's metrics show what that costs (the robustness suite's ``tool_long`` and
``tool_short`` cells, ``docs/controllers.md``): a long tool meets the bone during the approach, at four times
the feed, and drills its entry with the slow entry still ahead; a short one is pushed across the drill by the
offline correction before it has touched anything.

The thrust tells when the tip meets the bone: the F/T's axial force (noise 0.02 N per sample) jumps to newtons
within a few hundredths of a millimetre of contact. Registration:

* **Detect**: the first step whose latest thrust sample ``|ft_wrench[2]|`` exceeds ``contact_threshold_n``, before
  the retract, is the contact; its nominal depth ``p_c`` is recorded.
* **Estimate** the tool's offset along its axis, ``δ = d_expected − p_c``, with ``d_expected`` the nominal depth at
  which the planned tool's thrust reaches the threshold (:func:`expected_contact_depth_m`). Within
  ``contact_dead_band_mm`` of 0 the estimate is 0: the tool is where the plan says, and the controller is its base
  exactly.
* **Hold** a tool that meets the bone early (δ > 0): an axial correction of ``−min(δ, path_depth − p_c + b)`` along
  the drill pulls it back by ``b`` (``contact_backoff_mm``, the detection's overshoot) and keeps it there until the
  nominal path has caught up, after which the tip follows the planned path to the planned depth. Only the one
  step of the approach before the detection cuts at the approach's speed.
* **Re-index** the base: it sees the depth the tip has reached, ``path_depth + δ − hold``, so its offline profile
  and slow entry start where the drilling starts.
* **Wait in the air**: once the path is past the expected contact (by more than the dead band) with nothing
  touched, the tool is short. The base is not stepped: no correction (a compensator's loops, fed by corrections
  that meet no bone, swing the tip by millimetres there) and the plan's feed (``air_feed_scale``); at the contact
  it starts afresh. A short tool's hole is Δl shallower, as without registration: reaching the planned depth
  would take an axial correction that cuts at the servo's speed.

* **Re-plan** the base for the tool found (``replan_tool``): at a registered offset it is given the plan with the
  stick-out and TCP offset + δ, so its model of the drill's bending (with the cube of the stick-out) and of the
  arm's lever are the real tool's, and starts afresh at the contact.

The tracker cannot see this (its marker is on the spindle) and neither can the joints.
Units SI; the correction in the base frame.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.envs.constants import FEED_OVERRIDE_LOG2_MAX, MAX_CORRECTION_M
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan
from drillgym.envs.real.metrics import CONTACT_FORCE_N


@dataclass
class ContactRegistration:
    """Whether and how the contact is registered (``register_contact=0``: not at all)."""

    register_contact: bool = False
    """Register the contact (detect it from the thrust, hold an early tool, re-index the base)."""
    contact_threshold_n: float = CONTACT_FORCE_N
    """Axial force of one F/T sample that counts as contact (N): the real cell's contact force, 15 times the F/T
    noise, reached within about a tenth of a millimetre of cutting."""
    contact_dead_band_mm: float = 0.1
    """Offsets below this are taken as none (mm): one approach step's travel, the detection's resolution, twice the
    spread of the thrust's build-up (:func:`expected_contact_depth_m`)."""
    contact_backoff_mm: float = 0.1
    """How far an early tool is pulled back when its contact is detected (mm): the approach's travel in one
    agent step (2 mm/s × 50 ms), by which the detection overshoots. The drill springs back from the skid of its
    first touch and meets the bone again at the feed."""
    air_feed_scale: float = 1.0
    """Feed multiplier once the path is past the expected contact with nothing touched (a short tool drilling
    air): the base's own slow entry waits for the bone; 1 feeds at the plan's feed until contact."""
    replan_tool: bool = True
    """At a registered offset, give the base the plan of the tool found: stick-out and TCP offset + δ (its models
    of the drill's bending, ``3EI/l³``, and of the arm's lever), and let it start afresh at the contact."""
    point_angle_deg: float = 118.0
    """The drill's full point angle (deg), as measured on the bench: where on the lips the tool first touches."""

    def __post_init__(self) -> None:
        for name, (lo, hi, unit) in _BOUNDS.items():
            value = getattr(self, name)
            if not (math.isfinite(value) and lo <= value <= hi):
                raise UserError(f"{name}={value} must be in [{lo:g}, {hi:g}] {unit}")


_BOUNDS: dict[str, tuple[float, float, str]] = {
    "contact_threshold_n": (0.01, 50.0, "N"),
    "contact_dead_band_mm": (0.0, 2.0, "mm"),
    "contact_backoff_mm": (0.0, 1.0, "mm"),
    "air_feed_scale": (0.25, 1.0, "(never faster than the plan)"),
    "point_angle_deg": (60.0, 180.0, "deg"),
}
"""The numeric fields' allowed ranges and what the error adds after them."""
REGISTRATION_FIELDS = tuple(f.name for f in dataclasses.fields(ContactRegistration))
"""Spec fields every controller accepts (they build a :class:`ContactRegistration`)."""


def first_touch_depth_m(plan: DrillPlan, point_angle_deg: float = 118.0) -> float:
    """Nominal depth (m, task z) at which the planned drill first touches the planned surface.

    The surface rises by ``x · tan β`` toward the uphill side (task x); a lip runs from the tip back to its
    outer corner at radius ``r``, ``r · cot(κ)`` behind the tip (κ half the point angle). The tip touches first
    while the lips are steeper than the surface (``cot κ > tan β``, β below 31° for a 118° point): depth 0;
    otherwise the uphill corner does, at ``r (cot κ − tan β)`` < 0.
    """
    r = 0.5 * plan.drill_diameter_m
    cot_kappa = 1.0 / math.tan(math.radians(0.5 * point_angle_deg))
    return min(0.0, r * (cot_kappa - math.tan(abs(plan.beta_rad))))


def expected_contact_depth_m(plan: DrillPlan, point_angle_deg: float = 118.0, lag_m: float = 0.04e-3) -> float:
    """Nominal depth (m) at which the planned tool's thrust reaches the contact threshold.

    The thrust of a corner's first touch is small: it reaches 0.3 N once the corner has cut about halfway to
    the depth where the tip touches, plus ``lag_m`` of chip build-up. Measured in the ideal cell on 40 plans
    drawn across the training ranges (β −40° to 35°, feed 0.3 to 1 mm/s, three bones): detection 0.019 to
    0.118 mm after the first touch, within ±0.05 mm of this.
    """
    return 0.5 * first_touch_depth_m(plan, point_angle_deg) + lag_m


class ContactRegistered(Controller):
    """A base controller re-indexed at the measured contact, an early tool held until the path catches up.

    One episode at a time: a short tool's base is reset when it meets the bone (the batched engine runs one copy
    per episode of it, :func:`drillgym.controllers.rollout.run_episodes`).
    """

    name = "contact_registered"

    def __init__(self, base: Controller, registration: ContactRegistration) -> None:
        super().__init__()
        self.base = base
        self.registration = registration
        self.config = getattr(base, "config", None)

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """The base gets the plan too; the expected contact and the drill axis come from it."""
        self.expected_m = expected_contact_depth_m(plan, self.registration.point_angle_deg)
        self.axis_base = np.asarray(plan.R_base_task[:, 2], dtype=float)
        self.base.set_plan(plan, num_episodes)
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """No contact yet; reset the base."""
        self.contact_depth_m = math.nan
        """Nominal depth at the detected contact, ``p_c`` (m); NaN before it."""
        self.offset_m = 0.0
        """Estimated tool offset along the drill, ``δ`` (m; > 0: the tip is further out than planned)."""
        self.hold_m = 0.0
        """Axial hold of an early tool (m, back along the drill): grows with the path until it reaches ``δ``."""
        self.in_air = False
        """Whether the path went past the expected contact with nothing touched (a short tool)."""
        self.base.reset()

    @property
    def contact(self) -> bool:
        """Whether the contact has been detected."""
        return not math.isnan(self.contact_depth_m)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The base's action on the registered depth plus the axial hold; the plan's feed and no correction in air."""
        reg = self.registration
        depth = float(obs["path_depth_m"][0])
        retracting = float(obs["phase"][2]) > 0.5
        if not self.contact and not retracting and abs(float(obs["ft_wrench"][2])) > reg.contact_threshold_n:
            self._register(depth)
        elif not self.contact and depth > self.expected_m + reg.contact_dead_band_mm * 1e-3:
            self.in_air = True  # past the expected contact, nothing touched: the base waits for the bone
            feed = math.log2(reg.air_feed_scale) / FEED_OVERRIDE_LOG2_MAX
            return np.array([0.0, 0.0, 0.0, feed], dtype=np.float32)
        if self.offset_m > 0.0:  # the hold only grows: the retract takes the tip back as it is
            reach = min(self.offset_m, depth - self.contact_depth_m + reg.contact_backoff_mm * 1e-3)
            self.hold_m = min(max(self.hold_m, reach), MAX_CORRECTION_M)
        seen = depth + self.offset_m - self.hold_m if self.contact else depth
        action = np.array(self.base.act({**obs, "path_depth_m": np.array([seen], dtype=np.float32)}), np.float32)
        if self.hold_m > 0.0:
            axial = (-self.hold_m / MAX_CORRECTION_M) * self.axis_base
            action[:3] = np.clip(action[:3] + axial.astype(np.float32), -1.0, 1.0)
        return action

    def _register(self, depth_m: float) -> None:
        """The contact at nominal depth ``depth_m``: the tool's offset; the base starts afresh, for the tool found."""
        offset = self.expected_m - depth_m
        self.offset_m = 0.0 if abs(offset) < self.registration.contact_dead_band_mm * 1e-3 else offset
        self.contact_depth_m = depth_m
        if self.registration.replan_tool and self.offset_m != 0.0 and self.plan is not None:
            found = dataclasses.replace(
                self.plan,
                stickout_m=self.plan.stickout_m + self.offset_m,
                tcp_offset_m=self.plan.tcp_offset_m + self.offset_m,
            )
            self.base.set_plan(found, self.num_episodes)  # its models of the drill and the arm, for the tool found
        elif self.in_air:  # what its loops saw in the air was no drilling: forget it
            self.base.reset()

    def describe(self) -> dict[str, Any]:
        """The base's description with the registration's fields added to its configuration."""
        desc = self.base.describe()
        fields = {k: getattr(self.registration, k) for k in REGISTRATION_FIELDS}
        desc["config"] = {**desc["config"], **fields}
        return desc
