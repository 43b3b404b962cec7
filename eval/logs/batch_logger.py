"""``BatchLogger``: the Parquet logs of a batched run's episodes, one per episode, written as they run.

The batched counterpart of :class:`drillgym.eval.logs.EpisodeLogger`: after each step of
:func:`drillgym.controllers.rollout.run_episodes` it appends every running episode's rows (the same rows,
:func:`drillgym.eval.logs.logger.step_rows`, from the batched env's records) to that episode's log, and compacts
a log when its episode ends. The logs are those the single env's logger writes for the same episodes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs import SIM_ENV_ID
from drillgym.eval.logs.header import build_header
from drillgym.eval.logs.logger import step_rows
from drillgym.eval.logs.writer import FLUSH_ROWS, EpisodeLogWriter


class BatchLogger:
    """One log per episode of a batch (``paths[i]``: episode ``i``'s ``<name>.parquet``, or None for no log).

    Args:
        batch: the batched env, just reset (each episode's header is read from its single env).
        paths: per episode, its log path or None.
        seeds: per episode, its reset seed.
        controller: the controller's ``describe()``.
        extra: the header's ``run`` entry (suite, scenario, controller spec, effects).
    """

    def __init__(
        self,
        batch: Any,
        paths: list[Path | None],
        seeds: list[int],
        controller: dict[str, Any],
        extra: dict[str, Any],
        flush_rows: int = FLUSH_ROWS,
    ) -> None:
        self.batch = batch
        self.writers: list[EpisodeLogWriter | None] = [
            None
            if path is None
            else EpisodeLogWriter(
                path,
                build_header(env, controller, seed, extra=extra, env_id=SIM_ENV_ID),
                flush_rows,
                overwrite=True,
            )
            for env, path, seed in zip(batch.envs, paths, seeds, strict=True)
        ]

    def log_step(
        self, step: int, actions: np.ndarray, obs: dict[str, np.ndarray], running: list[int], ended: np.ndarray
    ) -> None:
        """Append step ``step`` of the ``running`` episodes; compact the logs of those that ``ended``."""
        state = self.batch.state
        for i in running:
            writer = self.writers[i]
            if writer is None or writer.closed:
                continue
            one = {k: v[i] for k, v in obs.items()}
            rows = step_rows(
                self.batch.last_step_channels(i),
                step,
                actions[i],
                one,
                state["rtde_tcp_base_m"][i],
                state["tracker_reading_base_m"][i],
            )
            writer.append(rows)
            if ended[i]:
                writer.close()

    def close(self) -> None:
        """Compact every log still open (episodes cut short)."""
        for writer in self.writers:
            if writer is not None and not writer.closed:
                writer.close()

    def abandon(self) -> None:
        """Flush and leave every open log's part directory, as a crash would."""
        for writer in self.writers:
            if writer is not None and not writer.closed:
                writer.abandon()
