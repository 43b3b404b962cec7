"""Episode metrics from recorded channels: one definition for simulated and real episodes.

Pure numpy on arrays a log also holds, so ``eval/`` computes the same numbers from a Parquet log of a
real run as the env reports in ``info["metrics"]``. Units in the names; forces from the F/T sensor
(as Li measured them), filtered with Li's 20-sample (0.2 s at 100 Hz) moving average.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

FORCE_FILTER_SAMPLES = 20
"""Moving-average length of the force filter (samples at 100 Hz): Li 2023 §3.4."""
STABLE_MARGIN_M = 0.5e-3
"""The stable stage starts this far past full engagement (commanded depth, m)."""

METRIC_NAMES = (
    "deviation_mean_mm",
    "deviation_max_mm",
    "lateral_force_max_n",
    "lateral_force_stable_n",
    "hole_offset_mm",
    "drill_time_s",
    "thrust_max_n",
    "tracker_deviation_mean_mm",
)


def moving_average(x: np.ndarray, n: int) -> np.ndarray:
    """Trailing moving average over ``n`` samples along axis 0 (shorter at the start)."""
    c = np.cumsum(np.asarray(x, dtype=float), axis=0)
    out = c.copy()
    out[n:] = c[n:] - c[:-n]
    counts = np.minimum(np.arange(1, len(x) + 1), n).reshape((-1,) + (1,) * (np.ndim(x) - 1))
    return out / counts


@dataclass
class EpisodeRecorder:
    """Per-F/T-sample channels of one episode, appended as the episode runs."""

    t_s: list[float] = field(default_factory=list)
    phase: list[int] = field(default_factory=list)
    stage: list[int] = field(default_factory=list)
    depth_cmd_m: list[float] = field(default_factory=list)
    deviation_m: list[float] = field(default_factory=list)
    ft_force_n: list[np.ndarray] = field(default_factory=list)
    tracker_deviation_m: list[float] = field(default_factory=list)
    # For episode logs only (not used by the metrics):
    ft_torque_nm: list[np.ndarray] = field(default_factory=list)
    """F/T torque readings (Tx, Ty, Tz) (N·m, sensor frame), one per sample."""
    tip_task_m: list[tuple[float, float, float]] = field(default_factory=list)
    """True drill-tip position (m, task frame), one per sample; privileged (sim only)."""

    def clear(self) -> None:
        """Drop everything recorded."""
        for v in self.__dict__.values():
            v.clear()


class RecordedChannels(Protocol):
    """What :func:`episode_metrics` reads: per-sample channels as sequences or arrays.

    An :class:`EpisodeRecorder` (the real cell's), a simulated episode's
    :class:`~drillgym.envs.sample_record.SampleRecord`, or any object with these channels.
    """

    @property
    def t_s(self) -> Any: ...  # noqa: D102
    @property
    def phase(self) -> Any: ...  # noqa: D102
    @property
    def stage(self) -> Any: ...  # noqa: D102
    @property
    def depth_cmd_m(self) -> Any: ...  # noqa: D102
    @property
    def deviation_m(self) -> Any: ...  # noqa: D102
    @property
    def ft_force_n(self) -> Any: ...  # noqa: D102
    @property
    def tracker_deviation_m(self) -> Any: ...  # noqa: D102


def episode_metrics(
    rec: RecordedChannels,
    entry_depth_m: float,
    depth_m: float,
    hole_offset_m: float,
    feed_phase: int = 1,
) -> dict[str, float]:
    """Li-style metrics of one episode.

    Args:
        rec: the recorded channels.
        entry_depth_m: commanded depth at which the drill is fully engaged, R (cot κ + tan|β|).
        depth_m: target depth (m); the stable stage ends there.
        hole_offset_m: entry-hole centre vs planned (m), measured on the specimen.
        feed_phase: the phase code of drilling.

    The drilling interval runs from first contact (stage > 0) to the end of the feed; the stable stage
    is the feed with the commanded depth past full engagement plus 0.5 mm.
    """
    stage = np.asarray(rec.stage)
    phase = np.asarray(rec.phase)
    t = np.asarray(rec.t_s)
    contact = np.flatnonzero(stage > 0)
    out = dict.fromkeys(METRIC_NAMES, float("nan"))
    out["hole_offset_mm"] = hole_offset_m * 1e3
    if contact.size == 0:
        return out
    feeding = np.flatnonzero(phase == feed_phase)
    end = int(feeding[-1]) + 1 if feeding.size else len(t)
    drill = slice(int(contact[0]), max(end, int(contact[0]) + 1))
    dev = np.asarray(rec.deviation_m)[drill]
    force = moving_average(np.asarray(rec.ft_force_n), FORCE_FILTER_SAMPLES)
    lateral = np.hypot(force[:, 0], force[:, 1])
    depth_cmd = np.asarray(rec.depth_cmd_m)
    stable = (phase == feed_phase) & (depth_cmd >= entry_depth_m + STABLE_MARGIN_M) & (depth_cmd < depth_m)
    out["deviation_mean_mm"] = float(dev.mean() * 1e3)
    out["deviation_max_mm"] = float(dev.max() * 1e3)
    out["lateral_force_max_n"] = float(lateral[drill].max())
    out["lateral_force_stable_n"] = float(lateral[stable].mean()) if stable.any() else float("nan")
    out["drill_time_s"] = float(t[drill.stop - 1] - t[drill.start])
    out["thrust_max_n"] = float(np.abs(force[drill, 2]).max())
    if len(rec.tracker_deviation_m):
        out["tracker_deviation_mean_mm"] = float(np.asarray(rec.tracker_deviation_m)[drill].mean() * 1e3)
    return out
