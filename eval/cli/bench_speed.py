"""``drillgym bench-speed``: the simulated cell's speed as same-run ratios and its memory (:mod:`drillgym.eval.perf.speed`)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from drillgym.envs.errors import UserError
from drillgym.eval.perf.speed import batched_throughput, controller_cycle_times, measure, rollout_throughput


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--runs", type=int, default=7, help="timed runs (medians reported; default 7)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON (every figure)")
    parser.add_argument(
        "--batch-sizes",
        default="1,16,64",
        help="batched env sizes whose episodes per second are measured (comma-separated; '' skips; default 1,16,64)",
    )
    parser.add_argument(
        "--batch-seconds", type=float, default=3.0, help="seconds per throughput measure (3 rounds; default 3)"
    )
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="also time each batch size with its compiled step on this many threads (BatchedDrillEnv(threads=...); "
        "default 1: one thread only)",
    )
    parser.add_argument(
        "--rollout-controllers",
        default="li2023,zhang2005",
        help="controllers whose episodes per second are measured on the single env and on the batched engine, as "
        "drillgym bench runs them (comma-separated; '' skips; default li2023,zhang2005)",
    )
    parser.add_argument(
        "--rollout-seeds",
        type=int,
        default=20,
        help="episodes per controller and engine in each of 3 rounds (default 20)",
    )
    parser.add_argument(
        "--schedule-holes",
        type=int,
        default=20,
        help="schedule-residual training holes per step whose rate is measured on one-hole envs and on the batched "
        "engine (3 interleaved steps; 0 skips; default 20)",
    )
    parser.add_argument(
        "--diagnosis-episodes",
        type=int,
        default=0,
        help="also time drillgym diagnose on this many episodes of a withheld-effect reality (3 runs, median; "
        "e.g. 12; default 0: skipped)",
    )
    parser.add_argument(
        "--diagnosis-workers", type=int, default=2, help="worker processes of the timed diagnosis (default 2)"
    )


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym bench-speed``."""
    if args.threads < 1:
        raise UserError(f"--threads {args.threads} must be >= 1")
    if args.rollout_seeds < 1 or args.schedule_holes < 0:
        raise UserError("--rollout-seeds must be >= 1 and --schedule-holes >= 0")
    if args.diagnosis_episodes and (args.diagnosis_episodes < 6 or args.diagnosis_workers < 1):
        raise UserError("--diagnosis-episodes must be 0 (skipped) or >= 6, --diagnosis-workers >= 1")
    result = measure(args.runs)
    result["controllers"] = controller_cycle_times()
    sizes = tuple(int(n) for n in args.batch_sizes.split(",") if n.strip())
    if sizes:
        result["batched"] = batched_throughput(sizes, args.batch_seconds, threads=args.threads)
    specs = tuple(s.strip() for s in args.rollout_controllers.split(",") if s.strip())
    if specs:
        result["rollouts"] = rollout_throughput(specs, args.rollout_seeds)
    if args.schedule_holes:
        from drillgym.eval.perf.schedule_speed import schedule_throughput  # training's imports, only when asked

        result["schedule"] = schedule_throughput(args.schedule_holes)
    if args.diagnosis_episodes:
        from drillgym.eval.perf.diagnosis_speed import diagnosis_time  # the diagnosis's imports, only when asked

        result["diagnosis"] = diagnosis_time(args.diagnosis_episodes, args.diagnosis_workers)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    _print(result, specs)
    return 0


def _print(result: dict[str, Any], specs: tuple[str, ...]) -> None:
    """The figures as text."""
    load = result["loadavg_before"]
    print(
        f"paper scenario, zero action, {result['runs']} runs (medians), one core; "
        f"load average {load[0]:.2f} on {result['cpu_count']} CPUs"
    )
    print(
        f"  env step / bare PyBullet step  {result['env_step_per_bare_pybullet_step_median']:6.1f}  "
        f"(min {result['env_step_per_bare_pybullet_step_min']:.1f}, max {result['env_step_per_bare_pybullet_step_max']:.1f}; "
        f"{result['env_step_us_median']:.1f} µs vs {result['bare_pybullet_step_us_median']:.2f} µs, "
        "UR5 in DIRECT torque mode, 1 ms)"
    )
    print(
        f"  real-time factor   {result['real_time_factor_median']:8.1f}  "
        f"(min {result['real_time_factor_min']:.1f}, max {result['real_time_factor_max']:.1f})"
    )
    print(
        f"  episode            {result['episode_sim_s']:.2f} s simulated in {result['episode_wall_s_median'] * 1e3:.1f} ms "
        f"({result['agent_steps_per_episode']} agent steps)"
    )
    print(
        f"  env construction   {result['construct_s'] * 1e3:.0f} ms (gym.make + first reset); "
        f"first episode {result['warmup_episode_s'] * 1e3:.0f} ms"
    )
    print(
        f"  peak memory        {result['peak_rss_mib']:.0f} MiB RSS; "
        f"{result['episode_python_peak_mib']:.2f} MiB Python peak within an episode"
    )
    if "batched" in result:
        b = result["batched"]
        print(
            f"episodes per second on one core, N/T rows on T threads (median of {b['runs']} interleaved rounds; "
            f"{b['steps_per_episode']:.0f} steps per episode, resets included)"
        )
        print(f"  single env         {b['single_env_episodes_per_s_median']:7.1f}")
        for n, r in b["batched"].items():
            print(
                f"  batched, N = {n:6s}{r['episodes_per_s_median']:7.1f}   "
                f"{r['speedup_over_single_median']:.1f}x the single env "
                f"(compiled step {r['kernel_us_per_episode_step_median']:.1f} us per episode-step; "
                f"{r['kernel_only_speedup_ceiling_median']:.1f}x if the rest were free)"
            )
    if "rollouts" in result:
        r = result["rollouts"]
        print(
            f"controller episodes per second on one core ({r['seeds']} seeds, median of {r['runs']} interleaved rounds; "
            "the same results either way)"
        )
        for spec in specs:
            t = r[spec]
            print(
                f"  {spec:12s} single env {t['single_env_episodes_per_s_median']:6.1f}   "
                f"batched {t['batched_episodes_per_s_median']:6.1f}   {t['speedup_median']:.1f}x   "
                f"(Python loop {t['python_loop_episodes_per_s_median']:6.1f}: the compiled loop "
                f"{t['compiled_loop_speedup_median']:.2f}x)"
            )
    if "schedule" in result:
        s = result["schedule"]
        print(
            f"schedule-residual training holes per second on one core ({s['holes']} holes a step, median of "
            f"{s['runs']} interleaved steps; the same rewards either way)"
        )
        print(
            f"  one-hole envs {s['one_hole_envs_holes_per_s_median']:6.1f}   batched "
            f"{s['batched_holes_per_s_median']:6.1f}   {s['speedup_median']:.1f}x"
        )
    if "diagnosis" in result:
        d = result["diagnosis"]
        runs = ", ".join(f"{t:.1f}" for t in d["runs_s"])
        print(
            f"diagnosis of {d['episodes']} episodes on {d['workers']} workers: {d['median_s']:.1f} s median "
            f"(runs {runs} s; named {'+'.join(d['named']) or 'nothing'})"
        )
    print("controller cycle time (one predict per 50 ms agent step; Li's budget: 50 ms)")
    for spec, t in result["controllers"].items():
        print(f"  {spec:10s} p50 {t['p50_us']:7.1f} µs   p99 {t['p99_us']:7.1f} µs   max {t['max_us']:7.1f} µs")
