"""Episode metrics a real cell can compute: no true tip, so contact from the F/T force, deviation from the tracker.

The same :func:`drillgym.envs.metrics.episode_metrics`, with the engagement "stage" replaced by an F/T contact flag
(force magnitude, 50 ms mean, above :data:`CONTACT_FORCE_N`) and the true deviation unknown (NaN):
``deviation_*_mm`` and ``hole_offset_mm`` come out NaN (measure the hole on the specimen), the force metrics,
``drill_time_s`` and ``tracker_deviation_mean_mm`` are computed. :func:`cell_metrics` applies the same
definition to a simulated recorder, so sim and real episodes are compared like for like.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.metrics import EpisodeRecorder, RecordedChannels, episode_metrics, moving_average

CONTACT_FORCE_N = 0.3
"""Contact when the 50 ms mean F/T force magnitude exceeds this (N): 15x the Mini40's noise, well under
the ~1 N the drill sees within 0.05 mm of first touch."""
CONTACT_WINDOW_SAMPLES = 5
"""Samples (100 Hz) of the contact detector's mean."""
OBSERVABLE_METRICS = (
    "lateral_force_max_n",
    "lateral_force_stable_n",
    "drill_time_s",
    "thrust_max_n",
    "tracker_deviation_mean_mm",
)
"""Metrics a real cell measures."""


def contact_flags(force_n: np.ndarray, previous_force_n: np.ndarray | None = None) -> list[int]:
    """1 where the trailing 50 ms mean |F| exceeds :data:`CONTACT_FORCE_N`, else 0; one flag per row of ``force_n``.

    ``previous_force_n``: the samples just before (so an online caller gets the same flags as a batch one).
    """
    f = np.asarray(force_n, dtype=float).reshape(-1, 3)
    prev = np.zeros((0, 3)) if previous_force_n is None else np.asarray(previous_force_n, dtype=float).reshape(-1, 3)
    prev = prev[-(CONTACT_WINDOW_SAMPLES - 1) :] if CONTACT_WINDOW_SAMPLES > 1 else prev[:0]
    mag = np.linalg.norm(np.vstack([prev, f]), axis=1)
    mean = moving_average(mag, CONTACT_WINDOW_SAMPLES)[len(prev) :]
    return [int(v > CONTACT_FORCE_N) for v in mean]


def cell_metrics(rec: RecordedChannels, entry_depth_m: float, depth_m: float) -> dict[str, float]:
    """Metrics of ``rec`` as a real cell computes them (F/T contact, no true tip), sim or real alike."""
    observable = EpisodeRecorder(
        t_s=list(rec.t_s),
        phase=list(rec.phase),
        stage=contact_flags(np.asarray(rec.ft_force_n)) if len(rec.ft_force_n) else [],
        depth_cmd_m=list(rec.depth_cmd_m),
        deviation_m=[math.nan] * len(rec.t_s),
        ft_force_n=list(rec.ft_force_n),
        tracker_deviation_m=list(rec.tracker_deviation_m),
    )
    return episode_metrics(observable, entry_depth_m, depth_m, math.nan)
