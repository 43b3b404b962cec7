"""The experiments behind the reproduction report: episodes, force-model trends, stiffness identification."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import EpisodeResult, run_episode
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.drilling import DrillGeometry, EngagementTable, get_bone_preset, stage_from_depth
from drillgym.envs.robot.stiffness_experiment import identify_and_compare

KP_SWEEP = (0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
"""KP values of the deviation-vs-KP figure (Li Fig. 12)."""
ENV_ID = SIM_ENV_ID


@dataclass
class Condition:
    """A scenario (env kwargs) drilled by a controller (spec)."""

    scenario_name: str
    scenario: dict[str, Any]
    controller: str


@dataclass
class ConditionResult(EpisodeResult):
    """An episode result plus the hole it cut (privileged: for the report's hole figure only)."""

    hole_depth_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hole_centre_task_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def run_condition(cond: Condition, seeds: list[int], keep_hole: bool = False, progress: Any = None) -> list:
    """Run ``cond`` once per seed (same seeds for every condition: paired comparisons)."""
    env = gym.make(ENV_ID, **cond.scenario)
    controller = make_controller(cond.controller)
    out = []
    try:
        for seed in seeds:
            env.reset(seed=seed)
            controller.set_plan(env.unwrapped.plan)  # type: ignore[attr-defined]
            res = run_episode(env, controller, seed)
            r = ConditionResult(res.seed, res.metrics, res.trace)
            if keep_hole:
                r.hole_depth_m, r.hole_centre_task_m = env.unwrapped.cell.hole.profile()  # type: ignore[attr-defined]
            out.append(r)
            if progress is not None:
                progress.update(1)
    finally:
        env.close()
    return out


def _lateral_table(beta_deg: float, feed_mm_s: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    geom = DrillGeometry()
    tab = EngagementTable.build(geom, get_bone_preset("buffalo_femur"), math.radians(beta_deg), 8e-3, 3e-3)
    rows = tab.edge + geom.chip_thickness_m(feed_mm_s * 1e-3, 20000.0) * tab.per_chip
    return tab.depth_m, np.hypot(rows[:, 0], rows[:, 1])


def _r2(x: np.ndarray, y: np.ndarray) -> float:
    coef = np.polyfit(x, y, 1)
    resid = y - np.polyval(coef, x)
    return 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())


def force_model_trends() -> dict[str, Any]:
    """Li Figs. 9a and 10 from the force model with the tip held on the planned axis."""
    geom = DrillGeometry()
    depth, lat = _lateral_table(30.0)
    i = int(np.argmax(lat))
    beta = math.radians(30.0)
    stages = np.array([stage_from_depth(float(d), geom, beta) for d in depth])
    betas = np.arange(0.0, 40.01, 2.5)
    peak_beta = np.array([_lateral_table(b)[1].max() for b in betas])
    low, high = betas <= 20.0, betas >= 20.0
    feeds = np.linspace(0.25, 1.25, 5)
    peak_feed = np.array([_lateral_table(30.0, f)[1].max() for f in feeds])
    slope_low = np.polyfit(betas[low], peak_beta[low], 1)[0]
    slope_high = np.polyfit(betas[high], peak_beta[high], 1)[0]
    return {
        "depth_m": depth,
        "lateral_n": lat,
        "stage": stages,
        "peak_n": float(lat[i]),
        "peak_depth_m": float(depth[i]),
        "peak_stage": int(stages[i]),
        "stage4_ratio": float(lat[stages == 4].max() / lat[i]),
        "betas_deg": betas,
        "peak_vs_beta_n": peak_beta,
        "beta_r2": _r2(betas[low], peak_beta[low]),
        "beta_slope_ratio": float(slope_high / slope_low),
        "feeds_mm_s": feeds,
        "peak_vs_feed_n": peak_feed,
        "feed_r2": _r2(feeds, peak_feed),
    }


def stiffness_identification(noise_mm: float = 0.05, load_n: float = 100.0, seed: int = 0) -> dict[str, Any]:
    """Li §3.3 and Table 1: identify Kθ from simulated load tests, predict three validation poses."""
    return identify_and_compare(noise_mm=noise_mm, load_n=load_n, seed=seed)


def sim_trends(seeds: list[int], progress: Any = None) -> dict[str, Any]:
    """Li Fig. 10 in the full simulation (uncompensated, the drill free to skid)."""
    betas = [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0]
    feeds = [0.25, 0.5, 0.75, 1.0, 1.25]
    by_beta = [run_condition(Condition("b", {"beta_deg": b}, "none"), seeds, progress=progress) for b in betas]
    by_feed = [run_condition(Condition("f", {"feed_mm_s": f}, "none"), seeds, progress=progress) for f in feeds]
    return {
        "betas_deg": np.array(betas),
        "force_vs_beta_n": np.array([np.mean([r.metrics["lateral_force_max_n"] for r in rs]) for rs in by_beta]),
        "feeds_mm_s": np.array(feeds),
        "force_vs_feed_n": np.array([np.mean([r.metrics["lateral_force_max_n"] for r in rs]) for rs in by_feed]),
    }
