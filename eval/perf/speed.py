"""The simulated cell's speed as ratios measured in the same run, and its memory.

The command is :mod:`drillgym.eval.cli.bench_speed`.

One core, the paper scenario, zero action. Each run times a block of bare PyBullet steps of the same UR5
(DIRECT, torque mode, 1 ms: :meth:`drillgym.envs.pybullet_world.PyBulletWorld.torque_mode`), one whole
episode through ``gym.make`` (reset + steps), and the bare block again; the run's ratio is the env step's
wall time over the mean of the two bare blocks' per-step times, so a machine that slows down (a shared
one) slows both sides alike. Reported: the median over runs of that ratio and of the real-time factor
(simulated seconds per wall second), the construction and warm-up times, and peak memory.
"""

from __future__ import annotations

import functools
import os
import resource
import statistics
import time
import tracemalloc
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode, run_episodes
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.errors import UserError
from drillgym.envs.pybullet_world import PyBulletWorld

BARE_STEPS_PER_BLOCK = 2000
"""Bare PyBullet steps per timed block (~20 ms on a 2020s core)."""


def _bare_block_s(step: Any, n: int) -> float:
    """Wall time (s) of ``n`` bare PyBullet steps."""
    t0 = time.perf_counter()
    for _ in range(n):
        step()
    return time.perf_counter() - t0


def _episode(env: Any, seed: int, action: np.ndarray) -> tuple[float, int, float]:
    """Wall time (s), agent steps and simulated time (s) of one zero-action episode (reset included)."""
    t0 = time.perf_counter()
    env.reset(seed=seed)
    n = 0
    while True:
        _, _, terminated, truncated, info = env.step(action)
        n += 1
        if terminated or truncated:
            break
    return time.perf_counter() - t0, n, float(info["t_s"])


def measure(runs: int = 7) -> dict[str, Any]:
    """Time ``runs`` paper-scenario episodes against bare PyBullet steps; ratios, times and memory."""
    if runs < 1:
        raise UserError(f"runs={runs} must be >= 1")
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    env = gym.make(SIM_ENV_ID)
    env.reset(seed=0)
    construct_s = time.perf_counter() - t0
    action = np.zeros(ACTION_DIM, dtype=np.float32)
    warmup_s, _, _ = _episode(env, 0, action)  # the first episode fills caches and is not counted
    world = PyBulletWorld(visual_meshes=False)
    bare_step = world.torque_mode(1e-3)
    _bare_block_s(bare_step, BARE_STEPS_PER_BLOCK)  # warm-up
    ratio, rtf, wall, step_us, bare_us = [], [], [], [], []
    steps, sim_s = 0, 0.0
    for seed in range(1, runs + 1):
        before = _bare_block_s(bare_step, BARE_STEPS_PER_BLOCK)
        dt, steps, sim_s = _episode(env, seed, action)
        after = _bare_block_s(bare_step, BARE_STEPS_PER_BLOCK)
        bare = 0.5 * (before + after) / BARE_STEPS_PER_BLOCK
        ratio.append(dt / steps / bare)
        rtf.append(sim_s / dt)
        wall.append(dt)
        step_us.append(dt / steps * 1e6)
        bare_us.append(bare * 1e6)
    world.close()
    tracemalloc.start()
    _episode(env, runs + 1, action)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    env.close()
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "env_step_per_bare_pybullet_step_median": statistics.median(ratio),
        "env_step_per_bare_pybullet_step_min": min(ratio),
        "env_step_per_bare_pybullet_step_max": max(ratio),
        "env_step_per_bare_pybullet_step_runs": ratio,
        "env_step_us_median": statistics.median(step_us),
        "bare_pybullet_step_us_median": statistics.median(bare_us),
        "real_time_factor_median": statistics.median(rtf),
        "real_time_factor_min": min(rtf),
        "real_time_factor_max": max(rtf),
        "episode_wall_s_median": statistics.median(wall),
        "episode_sim_s": sim_s,
        "agent_steps_per_episode": steps,
        "wall_us_per_agent_step": statistics.median(step_us),
        "construct_s": construct_s,
        "warmup_episode_s": warmup_s,
        "episode_python_peak_mib": traced_peak / 2**20,
        "peak_rss_mib": peak_kib / 1024.0,
        "runs": runs,
        "cpu_count": os.cpu_count(),
        "loadavg_before": list(load_before),
        "loadavg_after": list(os.getloadavg()),
    }


def controller_cycle_times(
    specs: tuple[str, ...] = ("none", "li2023", "zhang2005"), episodes: int = 2
) -> dict[str, Any]:
    """Per-call ``predict`` time of each controller over whole paper-scenario episodes (µs: p50, p99, max)."""
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


def _single_env_steps_per_s(seconds: float) -> tuple[float, float]:
    """Zero-action agent steps per second of one single env (whole episodes, resets included), and steps per episode."""
    env = UR5BoneDrillEnv(pybullet_world=False)
    action = np.zeros(4, dtype=np.float32)
    _episode(env, 0, action)
    steps = episodes = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, n, _ = _episode(env, episodes + 1, action)
        steps += n
        episodes += 1
    dt = time.perf_counter() - t0
    env.close()
    return steps / dt, steps / episodes


def _batched_steps_per_s(num_envs: int, seconds: float, threads: int = 1) -> tuple[float, float]:
    """Zero-action episode-steps per second of a :class:`~drillgym.envs.batched.BatchedDrillEnv` of ``num_envs``.

    Also the share of the wall time spent in its compiled step (:attr:`~drillgym.envs.batched.BatchedDrillEnv.kernel_s`).
    """
    env = BatchedDrillEnv(num_envs, threads=threads)
    env.reset(seed=0)
    actions = np.zeros((num_envs, 4), dtype=np.float32)
    for _ in range(20):
        env.step(actions)
    steps = 0
    kernel0 = env.kernel_s
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        env.step(actions)
        steps += 1
    dt = time.perf_counter() - t0
    kernel_share = (env.kernel_s - kernel0) / dt
    env.close()
    return steps * num_envs / dt, kernel_share


def batched_throughput(
    sizes: tuple[int, ...] = (1, 16, 64), seconds: float = 3.0, runs: int = 3, threads: int = 1
) -> dict[str, Any]:
    """Episodes per second: the single env (one core) and the batched env at each size, interleaved in one run.

    Each of ``runs`` rounds times the single env, then each batch size, for ``seconds`` each (ended
    episodes are reset inside the batch, so resets count); reported: the medians and each batch's
    speed-up over the single env of its own round, the compiled step's time per episode-step, and the speed-up the
    batch would reach if everything but the compiled step were free (its speed-up over the compiled step's share).
    With ``threads`` > 1 each size is also timed with its compiled step on that many threads (``"N/T"`` keys,
    :class:`~drillgym.envs.batched.BatchedDrillEnv`'s ``threads``), in the same rounds.
    """
    keys = [(n, 1) for n in sizes] + ([(n, threads) for n in sizes] if threads > 1 else [])
    single: list[float] = []
    per_size: dict[tuple[int, int], list[float]] = {k: [] for k in keys}
    ratio: dict[tuple[int, int], list[float]] = {k: [] for k in keys}
    ceiling: dict[tuple[int, int], list[float]] = {k: [] for k in keys}
    kernel_us: dict[tuple[int, int], list[float]] = {k: [] for k in keys}
    steps_per_episode = 0.0
    for _ in range(runs):
        s, steps_per_episode = _single_env_steps_per_s(seconds)
        single.append(s / steps_per_episode)
        for k in keys:
            steps_per_s, kernel_share = _batched_steps_per_s(k[0], seconds, k[1])
            b = steps_per_s / steps_per_episode
            per_size[k].append(b)
            ratio[k].append(b / single[-1])
            kernel_us[k].append(kernel_share / steps_per_s * 1e6)  # compiled step's µs per episode-step
            ceiling[k].append(ratio[k][-1] / kernel_share)  # the speed-up with the Python around it free
    return {
        "steps_per_episode": steps_per_episode,
        "single_env_episodes_per_s_median": statistics.median(single),
        "batched": {
            (str(n) if t == 1 else f"{n}/{t}"): {
                "threads": t,
                "episodes_per_s_median": statistics.median(per_size[(n, t)]),
                "speedup_over_single_median": statistics.median(ratio[(n, t)]),
                "speedup_runs": ratio[(n, t)],
                "kernel_us_per_episode_step_median": statistics.median(kernel_us[(n, t)]),
                "kernel_only_speedup_ceiling_median": statistics.median(ceiling[(n, t)]),
            }
            for n, t in keys
        },
        "seconds_per_measure": seconds,
        "runs": runs,
        "threads": threads,
    }


def rollout_throughput(
    specs: tuple[str, ...] = ("li2023", "zhang2005"), seeds: int = 20, runs: int = 3
) -> dict[str, Any]:
    """Controller episodes per second on one core, on the single env and on the batched engine.

    ``seeds`` episodes one by one on the single env (:func:`~drillgym.controllers.rollout.run_episode`, one
    controller), together on the batched engine (:func:`~drillgym.controllers.rollout.run_episodes`, as
    ``drillgym bench`` runs them) and together again with the compiled loop off (``compiled=False``: the Python loop,
    a step at a time; the same as the batched run for controllers the compiled loop does not take), interleaved in
    ``runs`` rounds per controller after a warm-up of two episodes each way; the medians and each round's ratios (the
    results are the same, bit for bit).
    """
    out: dict[str, Any] = {"seeds": seeds, "runs": runs}
    env = gym.make(SIM_ENV_ID)
    for spec in specs:
        make_controller(spec)  # a bad spec fails before any timing
        for compiled in (True, False):  # load each path's compiled code before the clock runs
            run_episodes(functools.partial(make_controller, spec), [0, 1], compiled=compiled)
        single, ratio, loop_ratio = [], [], []
        batched: list[float] = []
        python: list[float] = []
        for _ in range(runs):
            controller = make_controller(spec)
            t0 = time.perf_counter()
            for s in range(seeds):
                run_episode(env, controller, s, keep_trace=False)
            single.append(seeds / (time.perf_counter() - t0))
            for compiled, into in ((True, batched), (False, python)):
                t0 = time.perf_counter()
                run_episodes(functools.partial(make_controller, spec), list(range(seeds)), compiled=compiled)
                into.append(seeds / (time.perf_counter() - t0))
            ratio.append(batched[-1] / single[-1])
            loop_ratio.append(batched[-1] / python[-1])
        out[spec] = {
            "single_env_episodes_per_s_median": statistics.median(single),
            "batched_episodes_per_s_median": statistics.median(batched),
            "python_loop_episodes_per_s_median": statistics.median(python),
            "speedup_median": statistics.median(ratio),
            "speedup_runs": ratio,
            "compiled_loop_speedup_median": statistics.median(loop_ratio),
            "compiled_loop_speedup_runs": loop_ratio,
        }
    env.close()
    return out
