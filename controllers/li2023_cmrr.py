"""``li2023_cmrr``: Li et al. 2023's lateral compensation with Zhang et al. 2005's controlled material removal.

The two papers act on different parts of the action: Li's hybrid compensator corrects the tip across
the drill and leaves the feed at the plan's; Zhang's controlled material removal rate (CMRR) sets the
feed with a PI on the thrust. Combined, the lateral correction is :class:`Li2023Controller`'s and the
feed is :class:`Zhang2005Controller`'s with its deformation compensation off (Li's already corrects the
tip, and two lateral corrections would add up). Units: SI; frames: base unless named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.li2023 import Li2023Config, Li2023Controller
from drillgym.controllers.zhang2005 import Zhang2005Config, Zhang2005Controller
from drillgym.envs.plan import DrillPlan


@dataclass
class Li2023CmrrConfig:
    """li2023's gains and the CMRR's thrust loop (defaults: each paper's own)."""

    kp: float = Li2023Config.kp
    """li2023's proportional gain on the change of deviation between points."""
    ki: float = Li2023Config.ki
    """li2023's gain on the accumulated deviation."""
    thrust_ref_n: float = Zhang2005Config.thrust_ref_n
    """CMRR's reference thrust (N)."""
    kp_feed_mm_s_per_n: float = Zhang2005Config.kp_feed_mm_s_per_n
    """CMRR's proportional gain ((mm/s)/N)."""
    ki_feed_mm_s_per_ns: float = Zhang2005Config.ki_feed_mm_s_per_ns
    """CMRR's integral gain ((mm/s)/(N·s))."""
    cmrr_start_margin_mm: float = Zhang2005Config.cmrr_start_margin_mm
    """CMRR engages this far past full engagement of the planned entry (mm)."""
    feed_scale_max: float = Zhang2005Config.feed_scale_max
    """Highest feed the CMRR may command relative to the plan's (1: it only ever slows the feed)."""

    def __post_init__(self) -> None:
        self.li2023(), self.cmrr()  # validate both parts now, not at the first episode

    def li2023(self) -> Li2023Config:
        """The lateral part's configuration."""
        return Li2023Config(kp=self.kp, ki=self.ki)

    def cmrr(self) -> Zhang2005Config:
        """The feed part's configuration (Zhang's controller with its deformation compensation off)."""
        return Zhang2005Config(
            deformation=False,
            cmrr=True,
            thrust_ref_n=self.thrust_ref_n,
            kp_feed_mm_s_per_n=self.kp_feed_mm_s_per_n,
            ki_feed_mm_s_per_ns=self.ki_feed_mm_s_per_ns,
            cmrr_start_margin_mm=self.cmrr_start_margin_mm,
            feed_scale_max=self.feed_scale_max,
        )


class Li2023CmrrController(Controller):
    """Lateral correction from li2023, feed from Zhang's thrust-regulating PI."""

    name = "li2023_cmrr"
    batchable = True

    def __init__(self, config: Li2023CmrrConfig | None = None) -> None:
        super().__init__()
        self.config = config or Li2023CmrrConfig()
        self.lateral = Li2023Controller(self.config.li2023())
        self.feed = Zhang2005Controller(self.config.cmrr())

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Both parts get the plan."""
        self.lateral.set_plan(plan, num_episodes)
        self.feed.set_plan(plan, num_episodes)
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """Reset both parts."""
        self.lateral.reset()
        self.feed.reset()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """li2023's correction (entries 0-2) with the CMRR's feed (entry 3)."""
        action = np.array(self.lateral.act(obs), dtype=np.float32)
        action[3] = self.feed.act(obs)[3]
        return action

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """:meth:`act` of every episode (both parts batched)."""
        actions = np.array(self.lateral.act_batch(obs), dtype=np.float32)
        actions[:, 3] = self.feed.act_batch(obs)[:, 3]
        return actions
