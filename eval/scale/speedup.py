"""Measure ``drillgym bench --ray`` against the in-process run on one grid: ``python -m drillgym.eval.scale.speedup``.

Runs the grid ``--repeat`` times each way, alternating, in this process: the episode phase in-process
(``--workers 1``) and on a local Ray instance (start-up, worker warm-up and episode phase timed apart),
and prints the median times, the speed-up of the episode phase and the load average. Logs are written
as ``drillgym bench`` writes them, into a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from drillgym.eval.bench.episode import EpisodeJob
from drillgym.eval.bench.jobs import controller_label, run_jobs, split_controller_specs
from drillgym.eval.bench.suites import suite_scenarios


def _jobs(suite: str, specs: list[str], seeds: int, out: Path) -> list[EpisodeJob]:
    jobs = []
    for sc in suite_scenarios(suite):
        for spec in specs:
            for seed in range(seeds):
                name = f"logs/{suite}__{sc.name}__{controller_label(spec)}__seed{seed}.parquet"
                jobs.append(
                    EpisodeJob(suite, sc.name, sc.kwargs, spec, seed, out / name, name, sc.episode_effects(seed))
                )
    return jobs


def measure(suite: str, controllers: str, seeds: int, repeat: int, num_cpus: int | None) -> dict[str, Any]:
    """Median times (s) of both ways over ``repeat`` alternating runs, and the speed-up of the episode phase."""
    from drillgym.eval.scale.bench_ray import run_jobs_ray

    specs = split_controller_specs(controllers)
    local_s: list[float] = []
    ray_runs: list[dict[str, float]] = []
    loads: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            loads.append(os.getloadavg()[0])
            out = Path(tmp) / f"local{i}"
            jobs = _jobs(suite, specs, seeds, out)
            (out / "logs").mkdir(parents=True)
            t0 = time.perf_counter()
            run_jobs(jobs, 1, desc="local")
            local_s.append(time.perf_counter() - t0)
            out = Path(tmp) / f"ray{i}"
            run = run_jobs_ray(_jobs(suite, specs, seeds, out), out, num_cpus=num_cpus, desc="ray")
            ray_runs.append(
                {"startup_s": run.session.startup_s, "warmup_s": run.warmup_s, "episodes_s": run.episodes_s}
            )
            loads.append(os.getloadavg()[0])
    ray_med = {k: statistics.median(r[k] for r in ray_runs) for k in ray_runs[0]}
    local_med = statistics.median(local_s)
    return {
        "episodes": len(_jobs(suite, specs, seeds, Path())),
        "cpus": num_cpus or os.cpu_count(),
        "local_episodes_s": local_s,
        "ray": ray_runs,
        "median_local_episodes_s": local_med,
        "median_ray": ray_med,
        "speedup_episode_phase": local_med / ray_med["episodes_s"],
        "speedup_with_warmup": local_med / (ray_med["episodes_s"] + ray_med["warmup_s"]),
        "load_avg_1min": loads,
    }


def main() -> None:
    """CLI."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--suite", default="paper")
    p.add_argument("--controllers", default="none,li2023,li2023:kp=1.0,zhang2005")
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray (default: the machine's)")
    a = p.parse_args()
    print(json.dumps(measure(a.suite, a.controllers, a.seeds, a.repeat, a.num_cpus), indent=2))


if __name__ == "__main__":
    main()
