"""``BatchLogger``: the Parquet logs of a batched run's episodes, one per episode, written as they run.

The batched counterpart of :class:`drillgym.eval.logs.EpisodeLogger`: after each step of
:func:`drillgym.controllers.rollout.run_episodes` it keeps what the step held for each running episode (the
command, the joint angles, the RTDE TCP and the tracker) in arrays, and once ``flush_rows`` samples are waiting and
``flush_s`` seconds have passed since that log's last part, it writes them as a part of its log, their F/T samples
read from the batched env's record; a log is compacted when its episode ends. The rows are those
:func:`drillgym.eval.logs.logger.step_rows` gives the single env's logger for the same episode, value for value
(``tests/eval/test_bench_batched.py``). An exception writes every open log's rows (:meth:`BatchLogger.abandon`); a
process killed outright loses at most the rows of its last ``flush_s`` seconds (a simulated episode takes ≈ 10 ms:
writing its parts every 100 rows cost more than its steps).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.controllers.step_log import HELD
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.constants import SUBSTEPS_PER_STEP, scaled_rows
from drillgym.envs.sample_record import record_channels
from drillgym.eval.logs.header import build_header
from drillgym.eval.logs.logger import FT_COLUMNS
from drillgym.eval.logs.writer import FLUSH_ROWS, EpisodeLogWriter

FLUSH_S = 1.0
"""Wall seconds between two parts of a batched run's log, at least (:class:`BatchLogger`)."""


class BatchLogger:
    """One log per episode of a batch (``paths[i]``: episode ``i``'s ``<name>.parquet``, or None for no log).

    Args:
        batch: the batched env (:class:`drillgym.envs.batched.BatchedDrillEnv`), just reset; each episode's
            header is read from its single env.
        paths: per episode, its log path or None.
        seeds: per episode, its reset seed.
        controller: the controller's ``describe()``.
        extra: the header's ``run`` entry (suite, scenario, controller spec, effects), or one per episode.
        flush_rows: samples per part at least (as :class:`~drillgym.eval.logs.writer.EpisodeLogWriter`'s).
        flush_s: wall seconds between two parts of a log at least (0: a part every ``flush_rows`` samples).
    """

    def __init__(
        self,
        batch: Any,
        paths: list[Path | None],
        seeds: list[int],
        controller: dict[str, Any],
        extra: dict[str, Any] | list[dict[str, Any]],
        flush_rows: int = FLUSH_ROWS,
        flush_s: float = FLUSH_S,
    ) -> None:
        self.batch = batch
        self.flush_s = flush_s
        extras = [extra] * len(paths) if isinstance(extra, dict) else extra
        self.writers: list[EpisodeLogWriter | None] = [
            None
            if path is None
            else EpisodeLogWriter(
                path, build_header(env, controller, seed, extra=ex, env_id=SIM_ENV_ID), flush_rows, overwrite=True
            )
            for env, path, seed, ex in zip(batch.envs, paths, seeds, extras, strict=True)
        ]
        n, steps = batch.num_envs, batch.record.shape[1] // SUBSTEPS_PER_STEP
        self.held = np.zeros((n, steps, len(HELD)))
        self.valid = np.zeros((n, steps), dtype=bool)
        self.logged = np.zeros(n, dtype=np.int64)
        """Steps of each episode kept so far."""
        self.written = np.zeros(n, dtype=np.int64)
        """Steps of each episode already in its log's parts."""
        self.steps_per_part = max(1, -(-flush_rows // SUBSTEPS_PER_STEP))
        self.parted_s = np.full(n, time.monotonic())
        """When each log's last part was written (or the logger made), ``time.monotonic`` seconds."""

    def log_step(
        self, step: int, actions: np.ndarray, obs: dict[str, np.ndarray], running: list[int], ended: np.ndarray
    ) -> None:
        """Keep step ``step`` of the ``running`` episodes; write a part where one is due, compact those that ``ended``."""
        if not running:
            return
        state = self.batch.state
        rows = np.asarray(running)
        valid = obs["tracker_valid"][rows, 0] > 0.5
        held = self.held[rows, step]
        held[:, 0:4] = scaled_rows(np.clip(np.asarray(actions[rows], dtype=float), -1.0, 1.0))
        held[:, 4:10] = obs["q_rad"][rows]
        held[:, 10:13] = state["rtde_tcp_base_m"][rows]
        held[:, 13:16] = np.where(valid[:, None], state["tracker_reading_base_m"][rows], np.nan)
        held[:, 16:19] = obs["tracker_error_base_m"][rows]
        self.held[rows, step] = held
        self.valid[rows, step] = valid
        self.logged[rows] = step + 1
        self.write_due(running, ended)

    def write_due(self, running: list[int], ended: np.ndarray) -> None:
        """Write the parts now due of the ``running`` episodes' logs (up to the steps kept); close those that ``ended``.

        A part is due once ``flush_rows`` samples wait and ``flush_s`` seconds have passed since the log's last
        part, or when its episode ended.
        """
        now = time.monotonic()
        for i in running:
            writer = self.writers[i]
            if writer is None or writer.closed:
                continue
            done = int(self.logged[i])
            due = done - self.written[i] >= self.steps_per_part and now - self.parted_s[i] >= self.flush_s
            if ended[i] or due:
                self._write(i, done)
                self.parted_s[i] = now
            if ended[i]:
                writer.close()

    def _write(self, i: int, done: int) -> None:
        """Append episode ``i``'s steps since its last part, up to step ``done`` (excluded), to its log."""
        writer = self.writers[i]
        assert writer is not None
        s0, n = int(self.written[i]), SUBSTEPS_PER_STEP
        ch = record_channels(self.batch.record[i, n * s0 : n * done])
        held = np.repeat(self.held[i, s0:done], n, axis=0)
        ft = np.hstack([ch["ft_force_n"], ch["ft_torque_nm"]])
        columns: dict[str, Any] = {
            "t_s": ch["t_s"],
            "step": np.repeat(np.arange(s0, done), n),
            "phase": ch["phase"],
            "depth_cmd_m": ch["depth_cmd_m"],
            **{name: ft[:, k] for k, name in enumerate(FT_COLUMNS)},
            **{name: held[:, k] for k, name in enumerate(HELD)},
            "tracker_valid": np.repeat(self.valid[i, s0:done], n),
            **{f"sim_tip_{a}_task_m": ch["tip_task_m"][:, k] for k, a in enumerate("xyz")},
            "sim_stage": ch["stage"],
            "sim_deviation_m": ch["deviation_m"],
        }
        writer.append(columns)
        writer.flush()
        self.written[i] = done

    def close(self) -> None:
        """Write and compact every log still open (episodes cut short)."""
        for i, writer in enumerate(self.writers):
            if writer is not None and not writer.closed:
                self._write(i, int(self.logged[i]))
                writer.close()

    def abandon(self) -> None:
        """Write what each open log has kept and leave its part directory, as a crash would."""
        for i, writer in enumerate(self.writers):
            if writer is not None and not writer.closed:
                self._write(i, int(self.logged[i]))
                writer.abandon()
