"""Real episodes as the diagnosis uses them: commands to replay, channels to compare, stages.

Read from episode logs in the project's schema (``docs/log_schema.md``): compacted ``<name>.parquet``
files, the ``<name>/`` directory of a run that did not finish (used up to its last row, noted), and
``ur_rtde`` recording sessions (a folder with ``rtde.csv``; :mod:`drillgym.eval.diagnosis.rtde_import`). Only
the columns a real cell records are read; ``sim_*`` columns are dropped before anything looks at them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from drillgym.envs.cell_params import R_BASE_TASK, CellParams
from drillgym.envs.constants import unscale_action
from drillgym.envs.scenario import Scenario
from drillgym.eval.diagnosis.channels import LF_CHANNELS
from drillgym.eval.diagnosis.rtde_import import import_session
from drillgym.eval.diagnosis.stages import stage_labels
from drillgym.eval.diagnosis.validate import LogCheckError, check_log
from drillgym.eval.logs import EpisodeLogError, read_episode_log

SESSION_MARKER = "rtde.csv"
"""A sub-folder holding this file is an ``ur_rtde`` recording session to import."""


@dataclass
class EpisodeData:
    """One real episode, checked, in the diagnosis's channels.

    Attributes:
        name: the log's name (file stem).
        scenario: the header's scenario arguments (user units), what the cell was set up as.
        controller: the controller's name from the header (``"unknown"`` if none).
        actions: commands of every agent step, as env actions (n_steps, 4) (float32, [-1, 1]).
        t_s: sample times (s), (n,).
        phase: path phase per sample, (n,).
        depth_cmd_m: commanded depth (m, task z), (n,).
        stage: estimated stage per sample (index into ``STAGES``), (n,).
        lf: the real channels (:data:`~drillgym.eval.diagnosis.channels.LF_CHANNELS`) per sample, (n, 15); tracker
            columns NaN where the tracker was not tracking.
        repairs: what :func:`~drillgym.eval.diagnosis.validate.check_log` repaired, one line each.
        r_base_task: the planned task frame's axes in the base frame (3x3).
    """

    name: str
    scenario: dict[str, Any]
    controller: str
    actions: np.ndarray
    t_s: np.ndarray
    phase: np.ndarray
    depth_cmd_m: np.ndarray
    stage: np.ndarray
    lf: np.ndarray
    repairs: list[str] = field(default_factory=list)
    r_base_task: np.ndarray = field(default_factory=lambda: np.eye(3))
    created_utc: str | None = None
    """When the log was started (ISO 8601, from its header; None if it does not say): the series' order."""
    series_position: float = 0.0
    """This episode's place in the series of holes, 0 (first) to 1 (last) (:func:`set_series_positions`)."""

    @property
    def n(self) -> int:
        """Number of F/T samples."""
        return int(self.t_s.size)


def episode_from_log(name: str, header: dict[str, Any], frame: pd.DataFrame) -> EpisodeData:
    """Check a log (header + rows) and turn it into an :class:`EpisodeData`.

    Raises:
        LogCheckError: the log cannot be used (the message says why).
    """
    df, repairs = check_log(name, header, frame)
    try:
        scenario = Scenario.from_kwargs(**header["scenario"])
    except (TypeError, ValueError) as e:
        raise LogCheckError(f"{name}: header scenario is not valid: {e}") from e
    if frame.attrs.get("partial"):
        repairs.append("log did not finish (part directory): used up to its last row")
    step = df["step"].to_numpy()
    first = np.flatnonzero(np.concatenate([[True], np.diff(step) != 0]))
    corr = df[["cmd_dx_base_m", "cmd_dy_base_m", "cmd_dz_base_m"]].to_numpy()[first]
    feed = df["cmd_feed_scale"].to_numpy()[first]
    actions = np.stack([unscale_action(c, f) for c, f in zip(corr, feed, strict=True)])
    t_base_task = np.asarray(header.get("plan", {}).get("T_base_task", _default_t_base_task(scenario)), dtype=float)
    tracker_base = df[["tracker_x_base_m", "tracker_y_base_m", "tracker_z_base_m"]].to_numpy(dtype=float)
    tracker_task = (tracker_base - t_base_task[:3, 3]) @ t_base_task[:3, :3]
    valid = df["tracker_valid"].to_numpy(dtype=bool)
    tracker_task[~valid] = np.nan
    lf = np.column_stack(
        [
            df[["ft_fx_n", "ft_fy_n", "ft_fz_n", "ft_tx_nm", "ft_ty_nm", "ft_tz_nm"]].to_numpy(dtype=float),
            tracker_task,
            df[[f"q{i}_rad" for i in range(6)]].to_numpy(dtype=float),
        ]
    )
    assert lf.shape[1] == len(LF_CHANNELS)
    phase = df["phase"].to_numpy().astype(np.int8)
    depth = df["depth_cmd_m"].to_numpy(dtype=float)
    controller = (header.get("controller") or {}).get("name", "unknown")
    return EpisodeData(
        name=name,
        scenario=scenario.to_dict(),
        controller=str(controller),
        actions=actions.astype(np.float32),
        t_s=df["t_s"].to_numpy(dtype=float),
        phase=phase,
        depth_cmd_m=depth,
        stage=stage_labels(depth, phase, scenario.beta_deg, scenario.drill_diameter_mm),
        lf=lf,
        repairs=repairs,
        r_base_task=t_base_task[:3, :3].copy(),
        created_utc=header.get("created_utc"),
    )


def set_series_positions(episodes: list[EpisodeData]) -> list[int]:
    """Order ``episodes`` as drilled and set each one's ``series_position``; returns the indices in that order.

    The order is by the time each log was started, then by name; positions run from 0 (first) to 1 (last), 0 for a
    single episode.
    Logs started within the same second (the header's resolution) keep their names' order: the loggers name holes
    in the order they drill them (``episode_000``, ``hole_01``, ...).
    """
    order = sorted(range(len(episodes)), key=lambda i: (episodes[i].created_utc or "", episodes[i].name))
    last = max(len(episodes) - 1, 1)
    for rank, i in enumerate(order):
        episodes[i].series_position = rank / last
    return order


def _default_t_base_task(scenario: Scenario) -> np.ndarray:

    t = np.eye(4)
    t[:3, :3] = R_BASE_TASK
    t[:3, 3] = CellParams().entry_point
    return t


def find_logs(directory: str | Path) -> list[Path]:
    """Episode logs and recording sessions directly inside ``directory``, sorted by name."""
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"{d} is not a directory of episode logs")
    found = [p for p in d.glob("*.parquet") if p.is_file()]
    for sub in d.iterdir():
        if sub.is_dir() and ((sub / SESSION_MARKER).is_file() or (sub / "header.json").is_file()):
            if not (d / f"{sub.name}.parquet").exists():
                found.append(sub)
    return sorted(found, key=lambda p: p.name)


def load_episodes(directory: str | Path, strict: bool = False) -> tuple[list[EpisodeData], list[str]]:
    """Every usable episode in ``directory``; logs that fail their checks are skipped with a reason.

    Args:
        directory: folder of logs (see :func:`find_logs`).
        strict: raise on the first bad log instead of skipping it.

    Returns:
        ``(episodes, skipped)``: the episodes, and one line per skipped log naming the reason.
    """
    episodes, skipped = [], []
    for path in find_logs(directory):
        name = path.name.removesuffix(".parquet")
        try:
            if path.is_dir() and (path / SESSION_MARKER).is_file():
                header, frame = import_session(path)
            else:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    header, frame = read_episode_log(path)
            episodes.append(episode_from_log(name, header, frame))
        except (LogCheckError, EpisodeLogError, ValueError, OSError, KeyError) as e:
            if strict:
                raise
            skipped.append(f"{path.name}: {e}")
    return episodes, skipped
