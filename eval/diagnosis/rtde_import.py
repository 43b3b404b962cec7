"""Import a real-cell recording session: ``ur_rtde`` file recording + F/T + tracker + commands CSVs.

A session folder holds (``docs/diagnosis.md`` has the full spec):

* ``rtde.csv``: ``RTDEReceiveInterface.startFileRecording(path, variables)`` output. Its first line names
  the recorded variables; a vector variable is expanded as ``name_0 … name_{n-1}`` (``actual_q_0`` …
  ``actual_q_5``); every value is written in fixed notation with 6 decimals; a row is written every
  receive period (125 Hz on a CB3) and may repeat the same robot state. Needed: ``timestamp`` (s since
  the controller started), ``actual_q_0..5`` (rad), ``actual_TCP_pose_0..2`` (m, base); others are ignored.
* ``ft.csv``: ``t_s`` and ``fx``, ``fy``, ``fz`` with a unit suffix ``_n`` (or ``_mn``, ``_lbf``) and
  ``tx``, ``ty``, ``tz`` with ``_nm`` (or ``_nmm``, ``_lbfin``): every F/T sample (100 Hz), sensor frame.
* ``tracker.csv``: ``t_s``, ``x``, ``y``, ``z`` with ``_m`` (or ``_mm``), optional ``valid`` (0/1); base frame.
* ``commands.csv``: one row per agent step, when it was sent: ``t_s``, ``phase``, ``depth_cmd_m``,
  ``cmd_dx_base_m``, ``cmd_dy_base_m``, ``cmd_dz_base_m``, ``cmd_feed_scale``.
* ``header.json``: ``scenario`` (as in an episode log), optional ``controller``, ``plan``, and ``clock``:
  ``rtde_timestamp_at_t0_s`` (required: the RTDE timestamp at the episode's t = 0) and ``host_t0_s``
  (the other files' ``t_s`` at t = 0; default 0).

Rows are the F/T samples; each agent step's command, joint angles, TCP and tracker are the values at
the end of the step held for its rows, as the episode-log schema says. Repairs (listed in the header's
``run.repairs``): repeated RTDE rows are dropped. Everything else that does not fit raises
:class:`~drillgym.eval.diagnosis.validate.LogCheckError` naming the file and the problem.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from drillgym.envs import REAL_ENV_ID
from drillgym.envs.constants import CONTROL_DT_S, FT_RATE_HZ, RTDE_RATE_HZ, TRACKER_RATE_HZ
from drillgym.eval.diagnosis.validate import LogCheckError
from drillgym.eval.logs.schema import LOG_SCHEMA_VERSION

RTDE_Q = tuple(f"actual_q_{i}" for i in range(6))
RTDE_TCP = tuple(f"actual_TCP_pose_{i}" for i in range(3))
FORCE_UNITS = {"n": 1.0, "mn": 1e-3, "lbf": 4.4482216152605}
TORQUE_UNITS = {"nm": 1.0, "nmm": 1e-3, "lbfin": 0.1129848290276167}
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
COMMAND_COLUMNS = ("t_s", "phase", "depth_cmd_m", "cmd_dx_base_m", "cmd_dy_base_m", "cmd_dz_base_m", "cmd_feed_scale")
RTDE_MAX_GAP_S = 3.0 / RTDE_RATE_HZ
"""Longest tolerated interval between RTDE states (s); longer is a gap."""


def _read_csv(path: Path) -> pd.DataFrame:
    """The CSV table at ``path``; a missing, unreadable or malformed file raises ``LogCheckError`` naming it."""
    try:
        return pd.read_csv(path)
    except (OSError, ValueError) as e:
        raise LogCheckError(f"{path}: not a readable CSV ({e})") from e


def read_rtde_csv(path: Path) -> pd.DataFrame:
    """An ``ur_rtde`` recording as a table (its header line names the columns)."""
    frame = _read_csv(path)
    frame.columns = [c.strip() for c in frame.columns]
    missing = [c for c in ("timestamp", *RTDE_Q, *RTDE_TCP) if c not in frame.columns]
    if missing:
        raise LogCheckError(
            f"{path}: missing ur_rtde variable(s) {missing}; record at least "
            "['timestamp', 'actual_q', 'actual_TCP_pose'] with startFileRecording"
        )
    return frame


def _unit_columns(frame: pd.DataFrame, path: Path, axes: tuple[str, ...], units: dict[str, float]) -> np.ndarray:
    out = []
    for axis in axes:
        found = [(u, f) for u, f in units.items() if f"{axis}_{u}" in frame.columns]
        if len(found) != 1:
            options = ", ".join(f"{axis}_{u}" for u in units)
            raise LogCheckError(f"{path}: need exactly one column for {axis} with its unit ({options})")
        unit, factor = found[0]
        out.append(frame[f"{axis}_{unit}"].to_numpy(dtype=float) * factor)
    return np.column_stack(out)


def _hold(t_src: np.ndarray, values: np.ndarray, t_at: np.ndarray) -> np.ndarray:
    """The latest source value at or before each time (the first one before the stream starts)."""
    k = np.searchsorted(t_src, t_at + 1e-7, side="right") - 1
    return values[np.clip(k, 0, len(t_src) - 1)]


def import_session(session: str | Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """Read a session folder; return ``(header, rows)`` in the episode-log schema (``source: "real"``).

    Raises:
        FileNotFoundError: ``session`` does not exist; NotADirectoryError: it is a file, not a session folder.
    """
    d = Path(session)
    if not d.exists():
        raise FileNotFoundError(f"session folder {d} does not exist")
    if not d.is_dir():
        raise NotADirectoryError(
            f"{d} is a file; a session is a folder (rtde.csv, ft.csv, tracker.csv, commands.csv, header.json)"
        )
    meta, host_t0 = _read_meta(d)
    repairs: list[str] = []
    t_rtde, q, tcp = _read_rtde(d, float(meta["clock"]["rtde_timestamp_at_t0_s"]), repairs)
    t, force, torque = _read_ft(d, host_t0)
    cmd, t_cmd = _read_commands(d, host_t0)
    rows = t > t_cmd[0] + 1e-9
    t, force, torque = t[rows], force[rows], torque[rows]
    step = np.searchsorted(t_cmd, t - 1e-9, side="left") - 1
    step_end = np.append(t_cmd[1:], t_cmd[-1] + CONTROL_DT_S)[step]
    _check_rtde_coverage(d, t_rtde, step_end)

    out: dict[str, Any] = {"t_s": t, "step": step.astype(np.int32)}
    out["phase"] = cmd["phase"].to_numpy()[step].astype(np.int8)
    out["depth_cmd_m"] = np.interp(t, t_cmd, cmd["depth_cmd_m"].to_numpy(dtype=float))
    for k, name in enumerate(("ft_fx_n", "ft_fy_n", "ft_fz_n")):
        out[name] = force[:, k]
    for k, name in enumerate(("ft_tx_nm", "ft_ty_nm", "ft_tz_nm")):
        out[name] = torque[:, k]
    for name in COMMAND_COLUMNS[3:]:
        out[name] = cmd[name].to_numpy(dtype=float)[step]
    q_end, tcp_end = _hold(t_rtde, q, step_end), _hold(t_rtde, tcp, step_end)
    for i in range(6):
        out[f"q{i}_rad"] = q_end[:, i]
    for k, a in enumerate("xyz"):
        out[f"tcp_{a}_base_m"] = tcp_end[:, k]
    out.update(_tracker_columns(d, meta, host_t0, step_end, out["depth_cmd_m"]))
    header = {
        "schema_version": LOG_SCHEMA_VERSION,
        "source": "real",
        "env_id": meta.get("env_id", REAL_ENV_ID),
        "seed": None,
        "scenario": meta["scenario"],
        "controller": meta.get("controller"),
        "plan": meta.get("plan", {}),
        "rates_hz": {"ft": FT_RATE_HZ, "control": 1.0 / CONTROL_DT_S, "rtde": RTDE_RATE_HZ, "tracker": TRACKER_RATE_HZ},
        "versions": meta.get("versions", {}),
        "created_utc": meta.get("created_utc", dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")),
        "run": {**meta.get("run", {}), "imported_from": str(d), "repairs": repairs},
    }
    frame = pd.DataFrame(out)
    frame.attrs.update(partial=False, path=str(d))
    return header, frame


def _read_meta(d: Path) -> tuple[dict[str, Any], float]:
    try:
        meta = json.loads((d / "header.json").read_text())
    except (OSError, ValueError) as e:
        raise LogCheckError(f"{d / 'header.json'}: missing or unreadable ({e})") from e
    if "scenario" not in meta:
        raise LogCheckError(f"{d / 'header.json'}: no 'scenario'")
    clock = meta.setdefault("clock", {})
    if "rtde_timestamp_at_t0_s" not in clock:
        raise LogCheckError(
            f"{d / 'header.json'}: clock.rtde_timestamp_at_t0_s is required (the RTDE timestamp counts from the "
            "controller's start; without it the robot's states cannot be put on the episode's clock)"
        )
    return meta, float(clock.get("host_t0_s", 0.0))


def _read_rtde(d: Path, t0: float, repairs: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rtde = read_rtde_csv(d / "rtde.csv")
    t_rtde = rtde["timestamp"].to_numpy(dtype=float) - t0
    if np.any(np.diff(t_rtde) < 0):
        raise LogCheckError(f"{d / 'rtde.csv'}: timestamps go backwards")
    keep = np.concatenate([[True], np.diff(t_rtde) > 0])
    if not keep.all():
        repairs.append(f"rtde.csv: {int((~keep).sum())} repeated robot state(s) dropped")
    q = rtde.loc[keep, list(RTDE_Q)].to_numpy(dtype=float)
    tcp = rtde.loc[keep, list(RTDE_TCP)].to_numpy(dtype=float)
    return t_rtde[keep], q, tcp


def _read_ft(d: Path, host_t0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ft = _read_csv(d / "ft.csv")
    if "t_s" not in ft.columns:
        raise LogCheckError(f"{d / 'ft.csv'}: no t_s column")
    t = ft["t_s"].to_numpy(dtype=float) - host_t0
    force = _unit_columns(ft, d / "ft.csv", ("fx", "fy", "fz"), FORCE_UNITS)
    torque = _unit_columns(ft, d / "ft.csv", ("tx", "ty", "tz"), TORQUE_UNITS)
    return t, force, torque


def _read_commands(d: Path, host_t0: float) -> tuple[pd.DataFrame, np.ndarray]:
    cmd = _read_csv(d / "commands.csv")
    missing = [c for c in COMMAND_COLUMNS if c not in cmd.columns]
    if missing:
        raise LogCheckError(f"{d / 'commands.csv'}: missing column(s) {missing}")
    t_cmd = cmd["t_s"].to_numpy(dtype=float) - host_t0
    if np.any(np.diff(t_cmd) <= 0):
        raise LogCheckError(f"{d / 'commands.csv'}: t_s must increase")
    return cmd, t_cmd


def _tracker_columns(
    d: Path, meta: dict[str, Any], host_t0: float, step_end: np.ndarray, depth_cmd_m: np.ndarray
) -> dict[str, np.ndarray]:
    """Tracker columns; ``tracker_err`` is the marker minus its first reading moved along the planned axis."""
    tracker, valid = _tracker(d, host_t0, step_end, step_end.size)
    start = tracker[np.argmax(valid)] if valid.any() else np.zeros(3)
    r = np.asarray(meta.get("plan", {}).get("T_base_task", np.eye(4)), dtype=float)[:3, :3]
    planned = start + (depth_cmd_m - depth_cmd_m[0])[:, None] * r[:, 2][None, :]
    out: dict[str, np.ndarray] = {}
    for k, a in enumerate("xyz"):
        out[f"tracker_{a}_base_m"] = np.where(valid, tracker[:, k], np.nan)
        out[f"tracker_err_{a}_base_m"] = np.where(valid, tracker[:, k] - planned[:, k], 0.0)
    out["tracker_valid"] = valid
    return out


def _check_rtde_coverage(d: Path, t_rtde: np.ndarray, step_end: np.ndarray) -> None:
    if t_rtde.size == 0:
        raise LogCheckError(f"{d / 'rtde.csv'}: no robot states")
    if t_rtde[0] > step_end.min() + 1e-6 or t_rtde[-1] < step_end.max() - RTDE_MAX_GAP_S:
        raise LogCheckError(
            f"{d / 'rtde.csv'}: robot states cover {t_rtde[0]:.3f}–{t_rtde[-1]:.3f} s of the episode clock, the "
            f"episode needs {step_end.min():.3f}–{step_end.max():.3f} s (check clock.rtde_timestamp_at_t0_s)"
        )
    gaps = np.flatnonzero(np.diff(t_rtde) > RTDE_MAX_GAP_S)
    if gaps.size:
        i = int(gaps[0])
        raise LogCheckError(
            f"{d / 'rtde.csv'}: gap of {t_rtde[i + 1] - t_rtde[i]:.3f} s in the robot states after t={t_rtde[i]:.3f} s "
            f"(at most {RTDE_MAX_GAP_S:.3f} s is tolerated)"
        )


def _tracker(d: Path, host_t0: float, step_end: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    path = d / "tracker.csv"
    if not path.is_file():
        return np.zeros((n, 3)), np.zeros(n, dtype=bool)
    tr = _read_csv(path)
    if "t_s" not in tr.columns:
        raise LogCheckError(f"{path}: no t_s column")
    t = tr["t_s"].to_numpy(dtype=float) - host_t0
    xyz = _unit_columns(tr, path, ("x", "y", "z"), LENGTH_UNITS)
    valid = tr["valid"].to_numpy(dtype=bool) if "valid" in tr.columns else np.isfinite(xyz).all(axis=1)
    held = _hold(t, xyz, step_end)
    ok = _hold(t, valid.astype(float), step_end) > 0.5
    ok &= step_end >= t[0] - 1e-9
    return held, ok
