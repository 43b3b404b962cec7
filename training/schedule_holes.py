"""The holes a schedule residual trains or is evaluated on: drawn scenarios and seeds, or a fixed list in turn.

One :class:`HoleDraws` is one worker's (or one batch slot's) source of holes, keyed by the run's seed and the
worker's rank so that no two workers and no two runs share a draw (:mod:`drillgym.envs.seeds`). The one-hole env
(:class:`drillgym.training.schedule_env.ScheduleEnv`) and the batched one
(:class:`drillgym.training.schedule_vec_env.ScheduleVecEnv`) both take their holes from it, so slot ``j`` of a
batch drills the holes worker ``j`` would.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.seeds import Purpose, draw_seed, training_stream
from drillgym.training.cell import CELL_STREAM, TrainingCell
from drillgym.training.domain_randomization import sample_scenario


@dataclass
class Hole:
    """One hole: its full scenario (the paper's with the drawn changes), episode seed and the cell's effect spec."""

    scenario: dict[str, Any]
    episode_seed: int
    cell_spec: str


class HoleDraws:
    """Holes drawn inside the training ranges (``paper_share`` of them the paper scenario), or ``episodes`` in turn.

    Args:
        paper: the paper scenario's arguments (what a draw changes).
        ranges: domain-randomisation ranges.
        paper_share: share of drawn holes that are the paper scenario.
        cell: the training cell (its ranged parameters drawn per training hole, from a stream of their own).
        episodes: fixed ``(scenario changes, seed)`` holes instead of draws.
        stream_keys: the draws' generator keys (a run's seed and the worker's rank).
        first: the fixed list's index of the first visit.
        stride: how far each visit moves along the fixed list (a batch of n slots visits ``first + k n``).
    """

    def __init__(
        self,
        paper: dict[str, Any],
        ranges: dict[str, tuple[float, float]],
        paper_share: float = 0.0,
        cell: TrainingCell | None = None,
        episodes: list[tuple[dict[str, Any], int]] | None = None,
        stream_keys: tuple[int, ...] = (),
        first: int = 0,
        stride: int = 1,
    ) -> None:
        if not 0.0 <= paper_share <= 1.0:
            raise UserError(f"paper_share={paper_share!r} must be in [0, 1]")
        self.paper = dict(paper)
        self.ranges = dict(ranges)
        self.paper_share = float(paper_share)
        self.cell = cell or TrainingCell()
        self.episodes = None if episodes is None else [(dict(sc), int(seed)) for sc, seed in episodes]
        if self.episodes is not None and not self.episodes:
            raise UserError("an empty list of episodes")
        self.stream_keys = tuple(int(k) for k in stream_keys)
        self.first, self.stride = int(first), int(stride)
        self._visits = 0
        self._rng: np.random.Generator | None = None
        self._cell_rng: np.random.Generator | None = None

    def seed(self, seed: int | None) -> None:
        """Restart the draws' generators from ``seed`` (None: only if they have not started)."""
        if seed is not None or self._rng is None:
            self._rng = training_stream(self.stream_keys, seed)
            self._cell_rng = training_stream((*self.stream_keys, CELL_STREAM), seed)

    def next(self, scenario: dict[str, Any] | None = None) -> Hole:
        """The next hole (``scenario``: changes of the paper scenario that fix it instead of a draw)."""
        self.seed(None)
        assert self._rng is not None and self._cell_rng is not None
        cell_spec = self.cell.nominal_spec()
        if self.episodes is None and self.cell.ranges:  # training holes: the cell's parameters drawn too
            cell_spec = self.cell.draw_spec(self._cell_rng)
        if self.episodes is not None:
            changes, episode_seed = self.episodes[(self.first + self._visits * self.stride) % len(self.episodes)]
            self._visits += 1
            return Hole({**self.paper, **changes}, episode_seed, cell_spec)
        if scenario is not None:
            full = {**self.paper, **scenario}
        elif self.paper_share > 0.0 and self._rng.uniform() < self.paper_share:
            full = dict(self.paper)
        else:
            full = {**self.paper, **sample_scenario(self._rng, self.ranges)}
        return Hole(full, draw_seed(self._rng, Purpose.TRAIN), cell_spec)
