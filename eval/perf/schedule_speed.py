"""A schedule residual's training holes per second: one-hole envs against the batched engine, in one run.

The schedule residual's training drills each hole twice (its tuning and the base's). :func:`schedule_throughput`
steps ``holes`` one-hole envs one after another (SB3's ``DummyVecEnv`` of
:class:`~drillgym.training.schedule_env.ScheduleEnv`, what a worker of the original training ran) and the batched
engine's :class:`~drillgym.training.schedule_vec_env.ScheduleVecEnv` of ``holes`` slots in this process, on the same
holes and tunings, interleaved; both give the same rewards (checked here too).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np


def schedule_throughput(holes: int = 20, runs: int = 3, config: str = "residual_schedule_sac") -> dict[str, Any]:
    """Holes per second on one core, one-hole envs and the batched engine, ``runs`` interleaved steps of ``holes``."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from drillgym.training.config import load_config, resolve_config
    from drillgym.training.env_factory import schedule_env, schedule_vec_env

    cfg = load_config(resolve_config(config), {"env_workers": 1})
    one = DummyVecEnv([lambda r=r: schedule_env(cfg, rank=r) for r in range(holes)])  # type: ignore[misc]
    batched = schedule_vec_env(cfg, holes)
    rng = np.random.default_rng(0)
    single_rate, batched_rate, ratio = [], [], []
    try:
        one.seed(cfg.seed)
        batched.seed(cfg.seed)
        one.reset()
        batched.reset()
        for _ in range(runs):
            actions = rng.uniform(-1.0, 1.0, (holes, cfg.schedule_spec().dims)).astype(np.float32)
            t0 = time.perf_counter()
            _, r_one, _, _ = one.step(actions)
            single_rate.append(holes / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            _, r_batched, _, _ = batched.step(actions)
            batched_rate.append(holes / (time.perf_counter() - t0))
            ratio.append(batched_rate[-1] / single_rate[-1])
            if not np.array_equal(np.asarray(r_one, np.float32), np.asarray(r_batched, np.float32)):
                raise RuntimeError("the batched schedule env's rewards differ from the one-hole envs'")
    finally:
        one.close()
        batched.close()
    return {
        "holes": holes,
        "runs": runs,
        "one_hole_envs_holes_per_s_median": statistics.median(single_rate),
        "batched_holes_per_s_median": statistics.median(batched_rate),
        "speedup_median": statistics.median(ratio),
        "speedup_runs": ratio,
    }
