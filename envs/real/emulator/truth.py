"""Privileged truth of the emulated cell (true tip, engagement, hole): for tests, never for the client.

Metrics follow :func:`drillgym.envs.metrics.episode_metrics` on what the emulator knows: the drilling interval runs
from first contact (stage > 0) to the deepest tip position (the end of the feed).
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.envs.drilling.contact import ContactSample


class TruthRecorder:
    """True tip channels of one specimen, one entry per physics update (100 Hz)."""

    def __init__(self) -> None:
        self.t_s: list[float] = []
        self.stage: list[int] = []
        self.tip_task_m: list[tuple[float, float, float]] = []
        self.force_task_n: list[tuple[float, float, float]] = []

    def clear(self) -> None:
        """Drop everything (new specimen)."""
        for channel in (self.t_s, self.stage, self.tip_task_m, self.force_task_n):
            channel.clear()

    def record(self, t_s: float, sample: ContactSample) -> None:
        """Append one physics update."""
        self.t_s.append(t_s)
        self.stage.append(sample.stage)
        self.tip_task_m.append(sample.tip)
        self.force_task_n.append(sample.force)

    def metrics(self, hole_centre_xy_m: np.ndarray | None) -> dict[str, float]:
        """True deviation (mm) over the drilling interval, entry-hole offset (mm), true peak forces (N)."""
        out = {
            "deviation_mean_mm": math.nan,
            "deviation_max_mm": math.nan,
            "hole_offset_mm": math.nan if hole_centre_xy_m is None else float(np.hypot(*hole_centre_xy_m) * 1e3),
            "lateral_force_true_max_n": math.nan,
            "thrust_true_max_n": math.nan,
            "contact_s": 0.0,
        }
        stage = np.asarray(self.stage)
        contact = np.flatnonzero(stage > 0)
        if contact.size == 0:
            return out
        tip = np.asarray(self.tip_task_m)
        deepest = int(np.flatnonzero(tip[:, 2] >= tip[:, 2].max() - 1e-12)[-1])
        drill = slice(int(contact[0]), max(deepest + 1, int(contact[0]) + 1))
        dev = np.hypot(tip[drill, 0], tip[drill, 1])
        force = np.asarray(self.force_task_n)[drill]
        out.update(
            deviation_mean_mm=float(dev.mean() * 1e3),
            deviation_max_mm=float(dev.max() * 1e3),
            lateral_force_true_max_n=float(np.hypot(force[:, 0], force[:, 1]).max()),
            thrust_true_max_n=float(np.abs(force[:, 2]).max()),
            contact_s=float(self.t_s[drill.stop - 1] - self.t_s[drill.start]),
        )
        return out
