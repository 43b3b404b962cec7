"""What a batched run keeps of each step for its episode logs: the protocol the rollout loops write to.

A log of a batched run (:class:`drillgym.eval.logs.batch_logger.BatchLogger`) keeps, for every step of every running
episode, what the step held for its five F/T samples (:data:`HELD`: the command, the joint angles, the RTDE TCP
and the tracker) in arrays; the F/T samples themselves are in the batched env's record. The Python loop hands it
each step (:meth:`StepLog.log_step`); the compiled loop (:mod:`drillgym.controllers.closed_loop`) writes the same
numbers into its arrays itself and asks it to write what is due each time it returns to Python
(:meth:`StepLog.write_due`).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

HELD = (
    "cmd_dx_base_m",
    "cmd_dy_base_m",
    "cmd_dz_base_m",
    "cmd_feed_scale",
    *(f"q{i}_rad" for i in range(6)),
    *(f"tcp_{a}_base_m" for a in "xyz"),
    *(f"tracker_{a}_base_m" for a in "xyz"),
    *(f"tracker_err_{a}_base_m" for a in "xyz"),
)
"""The columns a step holds for its samples, in :attr:`StepLog.held` order (``tracker_valid`` apart): the command
(correction m, base frame; feed scale), the observed joint angles (rad), the RTDE TCP (m, base), the tracker's
reading where it is valid (else NaN; m, base) and the observed tracker error (m, base)."""


class StepLog(Protocol):
    """A batched run's episode logs, kept step by step (see the module docstring)."""

    held: np.ndarray
    """(N, S, len(HELD)): what step ``s`` of episode ``i`` held."""
    valid: np.ndarray
    """(N, S) bool: whether the tracker's reading was valid at that step."""
    logged: np.ndarray
    """(N,) int64: steps of each episode kept so far."""

    def log_step(self, step: int, actions: np.ndarray, obs: dict[str, Any], running: list[int], ended: Any) -> None:
        """Keep step ``step`` of the ``running`` episodes (their actions, the observation after it); :meth:`write_due`."""

    def write_due(self, running: list[int], ended: np.ndarray) -> None:
        """Write the parts now due of the ``running`` episodes' logs; close those that ``ended``."""
