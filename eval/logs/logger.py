"""``EpisodeLogger``: a Gymnasium wrapper that writes one episode to a Parquet log as it runs.

After each step it takes the F/T samples the step added to the unwrapped env's recorder
(``env.unwrapped.recorder``, per-sample channels) and the step's action, observation and latest
RTDE / tracker readings (held for the step's samples), and appends one row per sample
(:mod:`drillgym.eval.logs.schema`). The log is compacted when the episode ends or the logger is closed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from drillgym.envs.constants import scale_action
from drillgym.eval.logs.writer import FLUSH_ROWS, EpisodeLogWriter


class EpisodeLogger(gym.Wrapper):
    """Log one episode of ``env`` to ``path`` (``<name>.parquet``; ``<name>/`` while it runs).

    One logger, one episode: the log opens at the first ``reset`` (filling in ``header["seed"]`` if it
    is None) and is compacted when the episode terminates or truncates, or at ``close_log()`` /
    ``close()``. A second ``reset`` raises; wrap the env again for the next episode. ``close_log()``
    finishes the log without closing the env (to reuse it); ``abandon_log()`` keeps the parts as a
    crash would (the episode did not finish).
    """

    def __init__(
        self,
        env: gym.Env,
        path: str | Path,
        header: dict[str, Any],
        flush_rows: int = FLUSH_ROWS,
        overwrite: bool = False,
    ) -> None:
        super().__init__(env)
        self.log_path = Path(path)
        self.header = dict(header)
        self.flush_rows = flush_rows
        self.overwrite = overwrite
        self.writer: EpisodeLogWriter | None = None
        self._step = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the env and open the log."""
        if self.writer is not None:
            raise RuntimeError(f"EpisodeLogger logs one episode ({self.log_path}); wrap the env again for the next")
        obs, info = self.env.reset(seed=seed, options=options)
        if self.header.get("seed") is None:
            self.header["seed"] = seed
        self.writer = EpisodeLogWriter(self.log_path, self.header, self.flush_rows, self.overwrite)
        self._step = 0
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the env, append the new samples, compact the log if the episode ended."""
        if self.writer is None:
            raise RuntimeError("call reset() before step()")
        rec = self.env.unwrapped.recorder  # type: ignore[attr-defined]
        n0 = len(rec.t_s)
        obs, reward, terminated, truncated, info = self.env.step(action)
        if not self.writer.closed:
            self.writer.append(self._rows(rec, n0, action, obs))
            if terminated or truncated:
                self.writer.close()
        self._step += 1
        return obs, reward, terminated, truncated, info

    def _rows(self, rec: Any, n0: int, action: Any, obs: dict[str, np.ndarray]) -> dict[str, Any]:
        u: Any = self.env.unwrapped  # latest sensor readings: rtde_tcp_base, tracker_reading
        channels = {name: getattr(rec, name)[n0:] for name in SAMPLE_CHANNELS}
        return step_rows(channels, self._step, action, obs, u.rtde_tcp_base, u.tracker_reading)

    def close_log(self) -> Path | None:
        """Compact the log now (episode cut short or finished); the env stays open. Returns its path."""
        return self.writer.close() if self.writer is not None else None

    def abandon_log(self) -> Path | None:
        """Flush and leave the part directory, as a crash would. Returns the directory."""
        return self.writer.abandon() if self.writer is not None else None

    def close(self) -> None:
        """Compact the log, then close the env."""
        self.close_log()
        super().close()


SAMPLE_CHANNELS = (
    "t_s",
    "phase",
    "depth_cmd_m",
    "ft_force_n",
    "ft_torque_nm",
    "tip_task_m",
    "stage",
    "deviation_m",
)
"""The recorder's channels (:class:`drillgym.envs.metrics.EpisodeRecorder`) a log's rows take, one per F/T sample."""
FT_COLUMNS = ("ft_fx_n", "ft_fy_n", "ft_fz_n", "ft_tx_nm", "ft_ty_nm", "ft_tz_nm")
"""The log's F/T columns, in the wrench's order (force, then torque; sensor frame)."""


def step_rows(
    channels: dict[str, Any],
    step: int,
    action: Any,
    obs: dict[str, np.ndarray],
    rtde_tcp_base_m: Any,
    tracker_reading_base_m: Any,
) -> dict[str, Any]:
    """One agent step's log rows, column-wise (:mod:`drillgym.eval.logs.schema`), one per F/T sample.

    Args:
        channels: the step's samples of :data:`SAMPLE_CHANNELS` (lists or arrays, one entry per sample).
        step: the agent step's index in the episode.
        action: the action sent (clipped to [-1, 1] here, as the env does).
        obs: the observation after the step (joint angles, tracker error and validity are held for its samples).
        rtde_tcp_base_m: the latest RTDE TCP position (m, base frame), held for the step's samples.
        tracker_reading_base_m: the latest tracker reading (m, base frame; NaN in the log while not valid).
    """
    n = len(channels["t_s"])
    ft = np.hstack([np.asarray(channels["ft_force_n"]), np.asarray(channels["ft_torque_nm"])]).reshape(n, 6)
    tip = np.asarray(channels["tip_task_m"], dtype=float).reshape(n, 3)
    corr, feed_scale = scale_action(np.clip(np.asarray(action, dtype=float), -1.0, 1.0))
    valid = bool(obs["tracker_valid"][0] > 0.5)
    tracker = np.asarray(tracker_reading_base_m, dtype=float) if valid else np.full(3, np.nan)
    held = {
        **dict(zip(("cmd_dx_base_m", "cmd_dy_base_m", "cmd_dz_base_m"), corr.tolist(), strict=True)),
        "cmd_feed_scale": feed_scale,
        **{f"q{i}_rad": float(q) for i, q in enumerate(obs["q_rad"])},
        **_xyz("tcp_", "_base_m", rtde_tcp_base_m),
        **_xyz("tracker_", "_base_m", tracker),
        **_xyz("tracker_err_", "_base_m", obs["tracker_error_base_m"]),
        "tracker_valid": valid,
    }
    return {
        "t_s": channels["t_s"],
        "step": [step] * n,
        "phase": channels["phase"],
        "depth_cmd_m": channels["depth_cmd_m"],
        **{name: ft[:, i] for i, name in enumerate(FT_COLUMNS)},
        **{k: [v] * n for k, v in held.items()},
        **{f"sim_tip_{a}_task_m": tip[:, i] for i, a in enumerate("xyz")},
        "sim_stage": channels["stage"],
        "sim_deviation_m": channels["deviation_m"],
    }


def _xyz(prefix: str, suffix: str, values: Any) -> dict[str, float]:
    return {f"{prefix}{a}{suffix}": float(v) for a, v in zip("xyz", np.asarray(values, dtype=float), strict=True)}
