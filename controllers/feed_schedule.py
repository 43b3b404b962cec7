"""A slow entry on top of any controller: its feed scaled down over the first part of the hole.

On an inclined surface the drill's lips meet the bone on one side first, and the unbalanced chip force
of that one-sided cut pushes the tip down the slope until the hole wall guides it (``docs/physics.md``
§7). The chip force grows with the chip thickness, i.e. with the feed, so drilling the entry slowly
lowers the skid force, and with it the entry deviation and the peak lateral force, at the cost of a
little drill time. This is the classical "slow entry" of drilling practice: a feed schedule in the
nominal depth, applied on top of the base controller's own feed (which it multiplies).

Any spec takes it: ``li2023:entry_feed_scale=0.5,entry_depth_mm=0.5`` is ``li2023`` with half its feed
over the first 0.5 mm of nominal depth (:func:`drillgym.controllers.registry.make_controller`).
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from drillgym.controllers.base import Controller
from drillgym.envs.constants import FEED_OVERRIDE_LOG2_MAX
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan


@dataclass
class EntryFeedSchedule:
    """Feed multiplier over the entry of the hole (1.0: no schedule)."""

    entry_feed_scale: float = 1.0
    """Multiplier of the base controller's feed while the nominal depth is below ``entry_depth_mm`` (-)."""
    entry_depth_mm: float = 0.0
    """Nominal depth past the planned entry point (task z) up to which the entry feed applies (mm)."""

    def __post_init__(self) -> None:
        lo = 2.0**-FEED_OVERRIDE_LOG2_MAX
        if not (math.isfinite(self.entry_feed_scale) and lo <= self.entry_feed_scale <= 1.0):
            raise UserError(
                f"entry_feed_scale={self.entry_feed_scale} must be in [{lo:g}, 1] (a slow entry never speeds up)"
            )
        if not (math.isfinite(self.entry_depth_mm) and 0.0 <= self.entry_depth_mm <= 20.0):
            raise UserError(f"entry_depth_mm={self.entry_depth_mm} must be in [0, 20] mm")

    @property
    def active(self) -> bool:
        """Whether the schedule changes anything."""
        return self.entry_feed_scale < 1.0 and self.entry_depth_mm > 0.0

    def feed_action_offset(self, path_depth_m: float) -> float:
        """What the schedule adds to the action's feed entry at this nominal depth (m): log2 of the multiplier / 2."""
        if path_depth_m < self.entry_depth_mm * 1e-3:
            return math.log2(self.entry_feed_scale) / FEED_OVERRIDE_LOG2_MAX
        return 0.0


SCHEDULE_FIELDS = ("entry_feed_scale", "entry_depth_mm")
"""Spec fields every controller accepts (they build an :class:`EntryFeedSchedule`)."""


class SlowEntry(Controller):
    """A base controller whose feed is multiplied by the schedule's factor over the entry.

    The lateral correction is the base's, unchanged; so is the feed past the entry depth.
    """

    name = "slow_entry"

    def __init__(self, base: Controller, schedule: EntryFeedSchedule) -> None:
        super().__init__()
        self.base = base
        self.schedule = schedule
        self.config = base.config
        self.batchable = base.batchable
        self._entry = (np.array([schedule.entry_depth_mm * 1e-3]), np.array([schedule.feed_action_offset(-math.inf)]))
        """The entry's depth (m) and feed offset: (1,) arrays, or one per episode once stacked ((N,) arrays)."""

    def stack_key(self) -> Hashable | None:
        """The base's key: slow entries of stackable bases stack, each with its own schedule."""
        key = self.base.stack_part().stack_key()
        return None if key is None else ("slow_entry", key)

    @classmethod
    def stack(cls, controllers: Sequence[Controller]) -> SlowEntry:
        """One slow entry over the stacked bases, each episode with its own entry depth and feed."""
        parts = [c for c in controllers if isinstance(c, SlowEntry)]
        if len(parts) != len(controllers):
            raise UserError("only slow entries stack with slow entries")
        bases = [c.base.stack_part() for c in parts]
        out = cls(type(bases[0]).stack(bases), parts[0].schedule)
        out._entry = (np.concatenate([c._entry[0] for c in parts]), np.concatenate([c._entry[1] for c in parts]))
        out.plan, out.num_episodes = parts[0].plan, len(parts)
        return out

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """The base controller gets the plan too."""
        self.base.set_plan(plan, num_episodes)
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """Reset the base controller."""
        self.base.reset()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The base's action with the entry's feed multiplier applied."""
        action = np.array(self.base.act(obs), dtype=np.float32)
        action[3] = np.clip(action[3] + self.schedule.feed_action_offset(float(obs["path_depth_m"][0])), -1.0, 1.0)
        return action

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """:meth:`act` of every episode (the base's :meth:`act_batch`; the same numbers as one episode's)."""
        actions = np.array(self.base.act_batch(obs), dtype=np.float32)
        entry_m, entry_offset = self._entry
        add_entry_feed(actions, obs["path_depth_m"][:, 0], entry_m, entry_offset)
        return actions

    def describe(self) -> dict[str, Any]:
        """The base's description with the schedule's fields added to its configuration."""
        desc = self.base.describe()
        desc["config"] = {**desc["config"], **{k: getattr(self.schedule, k) for k in SCHEDULE_FIELDS}}
        return desc


@numba.njit(cache=True)
def add_entry_feed(
    actions: np.ndarray, depth_m: np.ndarray, entry_m: np.ndarray, offset: np.ndarray
) -> None:  # pragma: no cover
    """Add each episode's entry offset to its feed action (float32), clipped to [-1, 1], in place.

    ``actions`` (N, 4) float32; ``depth_m`` (N,) the nominal depths; ``entry_m`` and ``offset`` (1,) shared or (N,):
    the entry's depth (m) and feed offset. The offset is rounded to float32 and added in float32, as numpy's
    ``actions[:, 3] + np.where(depth < entry_m, offset, 0.0).astype(np.float32)`` does (and one episode's float32
    plus a Python float), then clipped as ``np.clip`` clips.
    """
    shared = entry_m.shape[0] == 1
    for i in range(actions.shape[0]):
        k = 0 if shared else i
        add = np.float32(offset[k] if np.float64(depth_m[i]) < entry_m[k] else 0.0)
        v = actions[i, 3] + add
        actions[i, 3] = -1.0 if v < -1.0 else (1.0 if v > 1.0 else v)
