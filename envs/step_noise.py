"""The standard normals a compiled step reads (:mod:`drillgym.envs.step_kernel`), drawn as the Python step draws them.

Both steppers take a step's sensor noise from the episode's generator (the env's ``np_random``) in the same order:
the F/T's 5x6 normals if it is noisy, then the tracker's 3 if it is noisy and its sample is new. The compiled step
reads them from a buffer (``noise``) that :func:`draw_noise` fills; the batched env fills a longer one ahead.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.envs.constants import PHYSICS_DT_S, SUBSTEPS_PER_STEP, TRACKER_RATE_HZ

NOISE_SIZE = 6 * SUBSTEPS_PER_STEP + 3
"""Standard normals a step may read: the F/T's (5x6), then the tracker's (3)."""


def tracker_sample_is_new(t_s: Any, stamp_s: Any) -> Any:
    """Whether the step starting at ``t_s`` ends with a new tracker sample (the last one was at ``stamp_s``).

    Floats or arrays of them (one per episode); the end time is the kernel's sum, term by term.
    """
    for _ in range(SUBSTEPS_PER_STEP):
        t_s = t_s + PHYSICS_DT_S
    return np.floor(t_s * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ != stamp_s  # sensors.latest_sample_time_s


def draw_noise(
    rng: np.random.Generator, noise: np.ndarray, ft_noisy: bool, tracker_noisy: bool, tracker_new: bool
) -> None:
    """The step's standard normals into ``noise`` from the episode's generator, in the Python step's order.

    The F/T's (5x6) if it is noisy, then the tracker's (3) if it is noisy and its sample is new, one after the
    other from ``noise[0]`` on, as the compiled step reads them from ``noise_at`` = 0.
    """
    at = 6 * SUBSTEPS_PER_STEP if ft_noisy else 0
    end = at + 3 if tracker_noisy and tracker_new else at
    if end:  # one draw: NumPy's normals are the same however the stream is cut into draws
        rng.standard_normal(out=noise[:end])


def noisy_sensors(p: np.void) -> tuple[bool, bool]:
    """Whether an episode's F/T and its tracker are noisy (its step reads normals for them: :func:`draw_noise`)."""
    return bool(p["ft_std"][0] > 0), bool(p["tracker_noise_m"] > 0)


def is_noisy(p: np.void) -> bool:
    """Whether an episode's step reads any normals."""
    return any(noisy_sensors(p))
