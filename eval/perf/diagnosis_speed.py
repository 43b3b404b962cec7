"""How long a diagnosis takes: a withheld-effect reality's episodes written once, then diagnosed several times.

``drillgym bench-speed --diagnosis-episodes 12`` reports it (:mod:`drillgym.eval.cli.bench_speed`). The reality is
Stribeck joint friction (a form the candidate library lacks, which the diagnosis names ``joint_friction``), its
episodes written by ``drillgym make-reality``'s generator with seed 0; each run diagnoses them afresh, with the
default candidates and no figures, in this process and ``workers`` spawned ones (their start included, as a user's
``drillgym diagnose --workers N`` pays it). The median of the runs' wall times is reported.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from drillgym.envs.errors import UserError
from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, run_diagnosis
from drillgym.eval.diagnosis.episodes import load_episodes
from drillgym.eval.diagnosis.reality.generate import make_reality

REALITY = "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4"
"""The reality diagnosed: a withheld effect that the diagnosis names (as ``joint_friction``)."""


def diagnosis_time(episodes: int = 12, workers: int = 2, runs: int = 3) -> dict[str, Any]:
    """Wall seconds of diagnosing ``episodes`` reality episodes with ``workers`` workers, ``runs`` times.

    Returns:
        ``{"episodes", "workers", "runs_s": [...], "median_s", "named": [...], "reality"}``.
    """
    if episodes < 6 or workers < 1 or runs < 1:
        raise UserError(f"need episodes >= 6, workers >= 1 and runs >= 1; got {episodes}, {workers}, {runs}")
    with tempfile.TemporaryDirectory(prefix="drillgym-diagnosis-speed-") as tmp:
        make_reality(REALITY, episodes, 0, Path(tmp) / "real")
        data, _ = load_episodes(Path(tmp) / "real")
        options = DiagnoseOptions(workers=workers, progress=False)
        times, named = [], []
        for _ in range(runs):
            t0 = time.perf_counter()
            result = run_diagnosis(data, options).result
            times.append(time.perf_counter() - t0)
            named = list(result["named"])
    return {
        "episodes": episodes,
        "workers": workers,
        "runs_s": times,
        "median_s": statistics.median(times),
        "named": named,
        "reality": REALITY,
    }
