"""One simulated episode's recorded F/T samples: the rows the compiled step writes, read as named channels.

The compiled step (:mod:`drillgym.envs.step_kernel`) appends each step's five sample rows
(:data:`OUT_COLUMNS` columns, declared here) to a record and counts them; the batched env keeps one
record per episode, the single env this one. The Python step fills the same rows (:meth:`SampleRecord.extend`),
so both steppers record alike and nothing is copied from one layout into another. The channels
(:data:`CHANNELS`) are those of :class:`drillgym.envs.metrics.EpisodeRecorder` (the real cell's), as arrays:
:func:`drillgym.envs.metrics.episode_metrics` reads either.

A channel is a view of rows that are never written again once their step has ended; a new episode records into a
new buffer, so channels read from an earlier episode keep its values.
"""

from __future__ import annotations

import numpy as np

OUT_T_S, OUT_PHASE, OUT_STAGE, OUT_DEPTH_CMD, OUT_DEVIATION = 0, 1, 2, 3, 4
"""The sample row's columns: the sample's time (s), path phase, stage, commanded depth (m), true tip deviation (m)."""
OUT_TIP = 5
"""True tip position (3, m, task frame)."""
OUT_FORCE = 8
"""F/T force reading (3, N, sensor frame); the torque reading (3, N·m) follows."""
OUT_TORQUE = 11
OUT_TRACKER_DEVIATION = 14
"""Lateral tracker error (m)."""
OUT_CUTTING = 15
"""1 if the drill cut at the sample."""
OUT_COLUMNS = 16


CHANNELS = (
    "t_s",
    "phase",
    "stage",
    "depth_cmd_m",
    "deviation_m",
    "tip_task_m",
    "ft_force_n",
    "ft_torque_nm",
    "tracker_deviation_m",
)
"""The recorded channels, one value (or xyz row) per F/T sample; units and frames in :func:`record_channels`."""

INITIAL_ROWS = 2048
"""Rows a new episode's buffer holds before it grows (the paper hole records ~1,500)."""


def record_channels(rows: np.ndarray) -> dict[str, np.ndarray]:
    """The channels (:data:`CHANNELS`) of sample rows in the compiled step's ``out`` layout (views, codes as ints).

    ``t_s`` (s), ``phase`` and ``stage`` (codes), ``depth_cmd_m`` (commanded depth, m), ``deviation_m`` (true tip
    off the planned axis, m), ``tip_task_m`` (true tip, m, task frame), ``ft_force_n`` and ``ft_torque_nm`` (F/T
    readings, sensor frame), ``tracker_deviation_m`` (lateral tracker error, m).
    """
    return {
        "t_s": rows[:, OUT_T_S],
        "phase": rows[:, OUT_PHASE].astype(np.int64),
        "stage": rows[:, OUT_STAGE].astype(np.int64),
        "depth_cmd_m": rows[:, OUT_DEPTH_CMD],
        "deviation_m": rows[:, OUT_DEVIATION],
        "tip_task_m": rows[:, OUT_TIP : OUT_TIP + 3],
        "ft_force_n": rows[:, OUT_FORCE : OUT_FORCE + 3],
        "ft_torque_nm": rows[:, OUT_TORQUE : OUT_TORQUE + 3],
        "tracker_deviation_m": rows[:, OUT_TRACKER_DEVIATION],
    }


class SampleRecord:
    """The sample rows of one episode (``buffer[0, :count[0]]``), in the layout the compiled step writes.

    ``buffer`` (1, capacity, ``OUT_COLUMNS``) and ``count`` (1,) are the compiled step's ``out`` and ``recorded``
    arguments for an episode batch of one: call :meth:`reserve` with the rows a call may append first.
    """

    def __init__(self) -> None:
        self.buffer = np.empty((1, INITIAL_ROWS, OUT_COLUMNS))
        self.count = np.zeros(1, dtype=np.int64)

    def clear(self) -> None:
        """Start a new episode in a new buffer (rows read from the last one keep their values)."""
        self.buffer = np.empty((1, INITIAL_ROWS, OUT_COLUMNS))
        self.count = np.zeros(1, dtype=np.int64)

    def __len__(self) -> int:
        """Samples recorded."""
        return int(self.count[0])

    @property
    def rows(self) -> np.ndarray:
        """The recorded rows (n, ``OUT_COLUMNS``), a view."""
        return self.buffer[0, : self.count[0]]

    def reserve(self, rows: int) -> None:
        """Make room for ``rows`` more rows (the buffer at least doubles when it grows)."""
        n = int(self.count[0])
        capacity = self.buffer.shape[1]
        if n + rows > capacity:
            grown = np.empty((1, max(2 * capacity, n + rows), OUT_COLUMNS))
            grown[0, :n] = self.buffer[0, :n]
            self.buffer = grown

    def extend(self, rows: int) -> np.ndarray:
        """Count ``rows`` more rows as recorded; the view of them to fill (their values are undefined until then)."""
        self.reserve(rows)
        n = int(self.count[0])
        self.count[0] = n + rows
        return self.buffer[0, n : n + rows]

    def channels(self) -> dict[str, np.ndarray]:
        """Every channel (:func:`record_channels`) of the rows recorded so far."""
        return record_channels(self.rows)

    @property
    def t_s(self) -> np.ndarray:
        """Sample times (s)."""
        return self.buffer[0, : self.count[0], OUT_T_S]

    @property
    def phase(self) -> np.ndarray:
        """Path phase codes (:class:`drillgym.envs.task.Phase`)."""
        return self.buffer[0, : self.count[0], OUT_PHASE].astype(np.int64)

    @property
    def stage(self) -> np.ndarray:
        """Drilling stage codes (0: no contact)."""
        return self.buffer[0, : self.count[0], OUT_STAGE].astype(np.int64)

    @property
    def depth_cmd_m(self) -> np.ndarray:
        """Commanded depth past the entry point (m)."""
        return self.buffer[0, : self.count[0], OUT_DEPTH_CMD]

    @property
    def deviation_m(self) -> np.ndarray:
        """True tip distance from the planned axis (m)."""
        return self.buffer[0, : self.count[0], OUT_DEVIATION]

    @property
    def tip_task_m(self) -> np.ndarray:
        """True drill-tip position (n, 3; m, task frame); privileged (sim only)."""
        return self.buffer[0, : self.count[0], OUT_TIP : OUT_TIP + 3]

    @property
    def ft_force_n(self) -> np.ndarray:
        """F/T force readings (n, 3; N, sensor frame)."""
        return self.buffer[0, : self.count[0], OUT_FORCE : OUT_FORCE + 3]

    @property
    def ft_torque_nm(self) -> np.ndarray:
        """F/T torque readings (n, 3; N·m, sensor frame)."""
        return self.buffer[0, : self.count[0], OUT_TORQUE : OUT_TORQUE + 3]

    @property
    def tracker_deviation_m(self) -> np.ndarray:
        """Lateral tracker error (m; the latest tracker sample's at each F/T sample)."""
        return self.buffer[0, : self.count[0], OUT_TRACKER_DEVIATION]
