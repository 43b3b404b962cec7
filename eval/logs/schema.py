"""Columns of an episode log: one row per F/T sample (100 Hz), units and frames in the names.

The table below is the schema; ``docs/log_schema.md`` explains it. A real-cell log has the same columns
except the ``sim_`` ones (privileged simulator state), which it leaves out. Frames: ``base`` (UR base),
``task`` (planned entry point, z along the planned drill axis), ``sensor`` (the F/T sensor).
"""

from __future__ import annotations

from dataclasses import dataclass

import pyarrow as pa

LOG_SCHEMA_VERSION = 1
"""Bumped whenever a column is added, removed or changes meaning."""
HEADER_METADATA_KEY = b"drillgym.header"
"""Schema-metadata key of the JSON header in a compacted ``<name>.parquet``."""
SIM_PREFIX = "sim_"
"""Prefix of the privileged, simulation-only columns."""


@dataclass(frozen=True)
class Column:
    """One column: name (with unit and frame), Arrow type, and what it holds."""

    name: str
    type: pa.DataType
    description: str


def _xyz(prefix: str, suffix: str, what: str, axes: str = "xyz") -> list[Column]:
    return [Column(f"{prefix}{a}{suffix}", pa.float64(), f"{what}, {a}") for a in axes]


COLUMNS: tuple[Column, ...] = (
    Column("t_s", pa.float64(), "time of the F/T sample since reset (s)"),
    Column("step", pa.int32(), "agent step the sample belongs to (0-based; 5 samples per step)"),
    Column("phase", pa.int8(), "path phase while the sample was taken: 0 approach, 1 feed, 2 retract, 3 done"),
    Column("depth_cmd_m", pa.float64(), "commanded tip depth past the planned entry point (m, task z)"),
    Column("ft_fx_n", pa.float64(), "F/T force x (N, sensor frame), tared, on the tool"),
    Column("ft_fy_n", pa.float64(), "F/T force y (N, sensor frame)"),
    Column("ft_fz_n", pa.float64(), "F/T force z (N, sensor frame)"),
    Column("ft_tx_nm", pa.float64(), "F/T torque x (N·m, sensor frame, about the sensor origin)"),
    Column("ft_ty_nm", pa.float64(), "F/T torque y (N·m, sensor frame)"),
    Column("ft_tz_nm", pa.float64(), "F/T torque z (N·m, sensor frame)"),
    *_xyz("cmd_d", "_base_m", "commanded drill-tip correction (m, base frame)"),
    Column("cmd_feed_scale", pa.float64(), "commanded feed override (× nominal feed)"),
    *[Column(f"q{i}_rad", pa.float64(), f"RTDE joint angle {i} (rad, motor side)") for i in range(6)],
    *_xyz("tcp_", "_base_m", "RTDE TCP (drill tip of the rigid arm) position (m, base frame)"),
    *_xyz("tracker_", "_base_m", "optical-tracker marker position (m, base frame); NaN without a tracker"),
    *_xyz("tracker_err_", "_base_m", "tracker marker minus its planned position (m, base frame), as observed"),
    Column("tracker_valid", pa.bool_(), "a tracker is fitted and tracking"),
    *_xyz("sim_tip_", "_task_m", "true drill-tip position (m, task frame); sim only"),
    Column("sim_stage", pa.int8(), "Li's engagement stage: 0 no contact, 1-3 entering, 4 fully engaged; sim only"),
    Column("sim_deviation_m", pa.float64(), "true tip distance from the planned axis (m); sim only"),
)
"""Every column, in file order."""

COLUMN_NAMES: tuple[str, ...] = tuple(c.name for c in COLUMNS)
SIM_COLUMNS: tuple[str, ...] = tuple(n for n in COLUMN_NAMES if n.startswith(SIM_PREFIX))
"""Privileged columns a real-cell log does not have."""
ARROW_SCHEMA = pa.schema([pa.field(c.name, c.type, nullable=False) for c in COLUMNS])
"""Arrow schema of the part files and of the compacted file (plus the header metadata)."""
