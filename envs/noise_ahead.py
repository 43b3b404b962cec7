"""Standard normals drawn ahead: each episode's sensor noise in a buffer, its generator put back where it belongs.

The batched env (:mod:`drillgym.envs.batched`) steps N episodes in one compiled call, so it cannot draw each
step's normals from each episode's generator as the single env does. :class:`NormalsAhead` draws them ahead, a
block at a time, into a row per episode that the compiled step reads from the episode's ``noise_at`` on
(:mod:`drillgym.envs.step_noise`). NumPy's normals are the same however a stream is cut into draws, so the
numbers read are the single env's. Two things keep them so:

* **A refill continues the stream.** The few normals the last block left unread move to the front and the rest
  of the row is drawn after them: each normal is drawn once while the episode runs.
* **At the episode's end the generator is put back** (:meth:`NormalsAhead.sync`) where the single env's
  step-by-step draws leave it: past the normals read, not past the ones drawn ahead. The generator's state
  before each block is kept (an *anchor*: that state and the row index its first normal went to); from the
  latest anchor at or before the read position, the normals up to it are drawn again. A refill moves the row by
  the normals read, so the anchor before the latest one is kept too: until the moved tail is read, the read
  position lies before the latest block.

Each normal is thus drawn once, and those of the last block or two read again at the end; drawing them all
again at every refill, as a simpler scheme would, costs twice the draws.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

_Anchor = tuple[Mapping[str, Any], int]
"""A generator state and the row index where the first normal drawn from it went (negative once moved past)."""


class NormalsAhead:
    """Rows of standard normals drawn ahead from N episodes' generators.

    Args:
        num_episodes: rows.
        size: normals per row (at least twice the most a step reads).
    """

    def __init__(self, num_episodes: int, size: int) -> None:
        self.rows = np.zeros((num_episodes, size))
        """The normals, one row per episode (the compiled step's ``noise``)."""
        self._anchors: list[list[_Anchor]] = [[] for _ in range(num_episodes)]

    @property
    def size(self) -> int:
        """Normals per row."""
        return int(self.rows.shape[1])

    def restart(self, i: int, noise_at: np.ndarray) -> None:
        """Episode ``i``'s generator is in step (seeded, or put back): its row is empty, nothing drawn ahead."""
        self._anchors[i] = []
        noise_at[i] = self.size

    def refill(self, i: int, rng: np.random.Generator, noise_at: np.ndarray) -> None:
        """Move episode ``i``'s unread normals to the front of its row and draw the rest after them from ``rng``.

        ``noise_at`` (N,) holds each row's next unread index; row ``i``'s becomes 0.
        """
        row, at = self.rows[i], int(noise_at[i])
        tail = self.size - at
        if tail:
            row[:tail] = row[at:]  # the unread normals (at most a step's), before the ones drawn now
        kept = [(state, pos - at) for state, pos in self._anchors[i][-1:]]  # needed until the tail is read
        self._anchors[i] = [*kept, (rng.bit_generator.state, tail)]
        rng.standard_normal(out=row[tail:])
        noise_at[i] = 0

    def sync(self, i: int, rng: np.random.Generator, noise_at: np.ndarray) -> None:
        """Put episode ``i``'s generator where the single env's would be: just past the normals read so far.

        Then the row counts as empty (:meth:`restart`).
        """
        at = int(noise_at[i])
        anchors = self._anchors[i]
        if anchors:
            state, pos = next(a for a in reversed(anchors) if a[1] <= at)
            rng.bit_generator.state = state
            if at > pos:
                rng.standard_normal(at - pos)
        self.restart(i, noise_at)
