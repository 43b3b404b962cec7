"""Checks of an episode log before the diagnosis trusts it: a clear error or a documented repair.

Never a silent wrong answer. What is checked (``docs/diagnosis.md`` has the table):

* every real-cell column is present (``sim_*`` columns are dropped unread);
* time: strictly increasing at the F/T rate; a gap (lost samples) raises, naming where;
* units: forces within the F/T range (not mN), joint angles within ±2π (not degrees), positions within
  2 m of the base (not mm); a violation raises, naming the column and the likely unit;
* commands constant within an agent step;
* NaN: runs of at most :data:`MAX_REPAIR_SAMPLES` samples in a sensor channel are repaired by linear
  interpolation (listed in the episode's ``repairs``); longer runs raise; tracker NaN is allowed only
  where ``tracker_valid`` is false (those samples are left out of the tracker's gap).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from drillgym.envs.constants import FT_RATE_HZ, SUBSTEPS_PER_STEP
from drillgym.envs.errors import UserError
from drillgym.eval.logs.schema import COLUMN_NAMES, SIM_PREFIX

REAL_COLUMNS = tuple(n for n in COLUMN_NAMES if not n.startswith(SIM_PREFIX))
"""Columns every log must have (a real cell's)."""
SENSOR_COLUMNS = (
    "ft_fx_n",
    "ft_fy_n",
    "ft_fz_n",
    "ft_tx_nm",
    "ft_ty_nm",
    "ft_tz_nm",
    *(f"q{i}_rad" for i in range(6)),
    "tcp_x_base_m",
    "tcp_y_base_m",
    "tcp_z_base_m",
)
COMMAND_COLUMNS = ("cmd_dx_base_m", "cmd_dy_base_m", "cmd_dz_base_m", "cmd_feed_scale")
TRACKER_COLUMNS = ("tracker_x_base_m", "tracker_y_base_m", "tracker_z_base_m")
MAX_REPAIR_SAMPLES = 3
"""Longest run of NaN samples in one sensor channel that is repaired by interpolation (30 ms at 100 Hz)."""
FT_RANGE_N = 500.0
"""No F/T force beyond this (N): the Mini40's range is 40–120 N; 500 means mN or a broken sensor."""
MAX_POSITION_M = 2.0
"""No position farther than this from the base (m): a UR5 reaches 0.85 m; more means mm."""
TIME_TOLERANCE = 0.25
"""Allowed deviation of a sample interval from 1/FT_RATE_HZ, as a fraction of it."""
HEADER_KEYS = ("scenario", "source")


class LogCheckError(UserError):
    """A log the diagnosis cannot use as it is; the message names the file, the column and why."""


def check_log(name: str, header: dict[str, Any], frame: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Validate (and where documented, repair) one log.

    Returns:
        ``(frame, repairs)``: the real-cell columns only, and one line per repair made.

    Raises:
        LogCheckError: naming the problem.
    """
    for key in HEADER_KEYS:
        if key not in header:
            raise LogCheckError(f"{name}: header has no {key!r}; not a drillgym episode log")
    missing = [c for c in REAL_COLUMNS if c not in frame.columns]
    if missing:
        raise LogCheckError(f"{name}: missing column(s) {missing}")
    df = frame.loc[:, list(REAL_COLUMNS)].copy()
    if len(df) < 4 * SUBSTEPS_PER_STEP:
        raise LogCheckError(f"{name}: only {len(df)} samples; an episode needs at least {4 * SUBSTEPS_PER_STEP}")
    _check_time(name, df["t_s"].to_numpy(dtype=float))
    repairs: list[str] = []
    for col in (*SENSOR_COLUMNS, *COMMAND_COLUMNS, "depth_cmd_m"):
        df[col] = _repair_nan(name, col, df[col].to_numpy(dtype=float), repairs)
    valid = df["tracker_valid"].to_numpy(dtype=bool)
    for col in TRACKER_COLUMNS:
        x = df[col].to_numpy(dtype=float)
        bad = valid & ~np.isfinite(x)
        if bad.any():
            x = _repair_nan(name, col, np.where(valid, x, 0.0), repairs)
            df[col] = np.where(valid, x, np.nan)
    _check_units(name, df)
    _check_commands(name, df)
    return df, repairs


def _check_time(name: str, t: np.ndarray) -> None:
    if not np.all(np.isfinite(t)):
        raise LogCheckError(f"{name}: t_s has NaN or inf")
    dt = np.diff(t)
    nominal = 1.0 / FT_RATE_HZ
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0])
        raise LogCheckError(f"{name}: t_s is not increasing at row {i + 1} ({t[i]:.4f} -> {t[i + 1]:.4f} s)")
    typical = float(np.median(dt))
    if abs(typical - nominal) > TIME_TOLERANCE * nominal:
        raise LogCheckError(
            f"{name}: typical sample interval {typical:.4g} (t_s units); expected {nominal:.3f} s (F/T at "
            f"{FT_RATE_HZ:g} Hz; t_s in ms?)"
        )
    bad = np.flatnonzero(np.abs(dt - nominal) > TIME_TOLERANCE * nominal)
    if bad.size:
        i = int(bad[0])
        if dt[i] > nominal:
            raise LogCheckError(
                f"{name}: time gap of {dt[i]:.3f} s after t={t[i]:.3f} s ({round(dt[i] / nominal) - 1} sample(s) "
                f"lost; {bad.size} irregular interval(s)); the diagnosis needs every F/T sample at {FT_RATE_HZ:g} Hz"
            )
        raise LogCheckError(
            f"{name}: sample interval {dt[i]:.4f} s at t={t[i]:.3f} s; expected {nominal:.3f} s (F/T at {FT_RATE_HZ:g} Hz; "
            "t_s in ms?)"
        )


def _repair_nan(name: str, col: str, x: np.ndarray, repairs: list[str]) -> np.ndarray:
    bad = ~np.isfinite(x)
    if not bad.any():
        return x
    if bad.all():
        raise LogCheckError(f"{name}: column {col} is all NaN")
    edges = np.diff(np.concatenate([[0], bad.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int((stops - starts).max())
    if longest > MAX_REPAIR_SAMPLES:
        i = int(starts[np.argmax(stops - starts)])
        raise LogCheckError(
            f"{name}: column {col} has {longest} consecutive NaN samples from row {i}; at most "
            f"{MAX_REPAIR_SAMPLES} are repaired by interpolation"
        )
    idx = np.arange(x.size)
    out = x.copy()
    out[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    repairs.append(f"{col}: {int(bad.sum())} NaN sample(s) in {starts.size} run(s) of <= {longest} interpolated")
    return out


def _check_units(name: str, df: pd.DataFrame) -> None:
    forces = df[["ft_fx_n", "ft_fy_n", "ft_fz_n"]].to_numpy()
    if np.abs(forces).max() > FT_RANGE_N:
        raise LogCheckError(
            f"{name}: |F| up to {np.abs(forces).max():.4g} beyond the F/T range ({FT_RANGE_N:g} N); forces in mN?"
        )
    q = df[[f"q{i}_rad" for i in range(6)]].to_numpy()
    if np.abs(q).max() > 2 * np.pi + 1e-6:
        raise LogCheckError(f"{name}: joint angles up to {np.abs(q).max():.4g}; more than 2π rad: degrees?")
    for cols in (("tcp_x_base_m", "tcp_y_base_m", "tcp_z_base_m"), TRACKER_COLUMNS):
        p = df[list(cols)].to_numpy()
        far = np.nanmax(np.abs(p)) if np.isfinite(p).any() else 0.0
        if far > MAX_POSITION_M:
            raise LogCheckError(f"{name}: {cols[0][:-9]} position up to {far:.4g} from the base; more than 2 m: mm?")
    scale = df["cmd_feed_scale"].to_numpy()
    if np.any(scale <= 0):
        raise LogCheckError(f"{name}: cmd_feed_scale must be positive (a scale of the nominal feed)")


def _check_commands(name: str, df: pd.DataFrame) -> None:
    step = df["step"].to_numpy()
    if np.any(np.diff(step) < 0) or np.any(np.diff(step) > 1):
        raise LogCheckError(f"{name}: the step column must count up by 0 or 1 per sample")
    cmd = df[list(COMMAND_COLUMNS)].to_numpy()
    first = np.concatenate([[True], np.diff(step) != 0])
    held = cmd[np.flatnonzero(first)][np.cumsum(first) - 1]  # each step's first command, on its rows
    changed = np.any(np.abs(cmd - held) > 1e-12, axis=1)
    if changed.any():
        row = int(np.flatnonzero(changed)[0])
        raise LogCheckError(f"{name}: the command changes inside agent step {int(step[row])} (row {row})")
