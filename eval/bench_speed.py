"""``drillgym bench-speed``: real-time factor and peak memory of the simulated cell.

One core, the paper scenario, zero action: each run is ``reset`` + a whole episode through
``gym.make``; the real-time factor is simulated seconds per wall second. Reports the median over runs.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import time
from typing import Any

import numpy as np

from drillgym.envs import SIM_ENV_ID


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--runs", type=int, default=7, help="episodes to time (median reported; default 7)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def measure(runs: int = 7) -> dict[str, Any]:
    """Time ``runs`` paper-scenario episodes; return RTF statistics and peak memory."""
    import gymnasium as gym

    from drillgym.envs.constants import ACTION_DIM

    if runs < 1:
        raise ValueError(f"runs={runs} must be >= 1")
    t0 = time.perf_counter()
    env = gym.make(SIM_ENV_ID)
    construct_s = time.perf_counter() - t0
    action = np.zeros(ACTION_DIM, dtype=np.float32)
    rtf, wall, steps = [], [], 0
    for seed in range(runs + 1):  # the first episode warms caches and is not counted
        t0 = time.perf_counter()
        env.reset(seed=seed)
        n = 0
        while True:
            _, _, terminated, truncated, info = env.step(action)
            n += 1
            if terminated or truncated:
                break
        dt = time.perf_counter() - t0
        if seed > 0:
            rtf.append(info["t_s"] / dt)
            wall.append(dt)
            steps = n
    env.close()
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "real_time_factor_median": statistics.median(rtf),
        "real_time_factor_min": min(rtf),
        "real_time_factor_max": max(rtf),
        "episode_wall_s_median": statistics.median(wall),
        "episode_sim_s": float(info["t_s"]),
        "agent_steps_per_episode": steps,
        "wall_us_per_agent_step": statistics.median(wall) / steps * 1e6,
        "construct_s": construct_s,
        "peak_rss_mib": peak_kib / 1024.0,
        "runs": runs,
        "cpu_count": os.cpu_count(),
    }


def controller_cycle_times(
    specs: tuple[str, ...] = ("none", "li2023", "zhang2005"), episodes: int = 2
) -> dict[str, Any]:
    """Per-call ``predict`` time of each controller over whole paper-scenario episodes (µs: p50, p99, max)."""
    import gymnasium as gym

    from drillgym.controllers import make_controller

    env = gym.make(SIM_ENV_ID)
    out: dict[str, Any] = {}
    for spec in specs:
        controller = make_controller(spec)
        times = []
        for seed in range(episodes):
            obs, _ = env.reset(seed=seed)
            controller.set_plan(env.unwrapped.plan)  # type: ignore[attr-defined]
            start = True
            while True:
                t0 = time.perf_counter()
                action, _ = controller.predict(obs, episode_start=np.array([start]))
                times.append(time.perf_counter() - t0)
                start = False
                obs, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    break
        us = np.asarray(times) * 1e6
        out[spec] = {
            "p50_us": float(np.percentile(us, 50)),
            "p99_us": float(np.percentile(us, 99)),
            "max_us": float(us.max()),
            "calls": int(us.size),
        }
    env.close()
    return out


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym bench-speed``."""
    result = measure(args.runs)
    result["controllers"] = controller_cycle_times()
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"paper scenario, zero action, {result['runs']} runs (median), one core")
    print(
        f"  real-time factor   {result['real_time_factor_median']:8.1f}  "
        f"(min {result['real_time_factor_min']:.1f}, max {result['real_time_factor_max']:.1f})"
    )
    print(
        f"  episode            {result['episode_sim_s']:.2f} s simulated in {result['episode_wall_s_median'] * 1e3:.1f} ms "
        f"({result['agent_steps_per_episode']} agent steps, {result['wall_us_per_agent_step']:.0f} µs each)"
    )
    print(f"  env construction   {result['construct_s'] * 1e3:.0f} ms")
    print(f"  peak memory (RSS)  {result['peak_rss_mib']:.0f} MiB")
    print("controller cycle time (one predict per 50 ms agent step; Li's budget: 50 ms)")
    for spec, t in result["controllers"].items():
        print(f"  {spec:10s} p50 {t['p50_us']:7.1f} µs   p99 {t['p99_us']:7.1f} µs   max {t['max_us']:7.1f} µs")
    return 0
