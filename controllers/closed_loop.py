"""A batch of ``li2023``-family episodes run in compiled code, controller and cell together.

:func:`drillgym.controllers.rollout.run_batch` hands its episodes here when one stacked ``li2023`` controller
(optionally under a slow entry: ``li2023``, ``li2023_tuned``, a plan schedule over them) drives every slot, with no
per-step hook and one thread: :class:`ClosedLoop` runs the steps in
:func:`drillgym.controllers.closed_loop_kernel.run_steps` and handles in Python only what needs it (compensation
points, normals refills, ended episodes, errors). The episodes' results, records and states are those of the Python
loop, bit for bit (``tests/controllers/test_closed_loop.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.closed_loop_kernel import (
    STOP_BAD_ACTION,
    STOP_DONE,
    STOP_ENDED,
    STOP_FULL,
    STOP_POINT,
    STOP_REFILL,
    STOP_SINGULAR,
    run_steps,
)
from drillgym.controllers.feed_schedule import SlowEntry
from drillgym.controllers.li2023 import Li2023Controller, _rows
from drillgym.controllers.step_log import HELD, StepLog
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.constants import CONTROL_DT_S, MAX_EPISODE_STEPS, SUBSTEPS_PER_STEP
from drillgym.envs.observation import OBS_SIZE, unpack_observation
from drillgym.envs.reward import checked_action
from drillgym.envs.step_noise import NOISE_SIZE, is_noisy
from drillgym.envs.views import observation_rows

_TWO = np.array([2.0])
_NO_ENTRY = np.zeros(1)
_NO_LOG = (
    np.zeros(1, dtype=bool),
    np.zeros((1, 1, len(HELD))),
    np.zeros((1, 1), dtype=bool),
    np.zeros(1, dtype=np.int64),
)


def closed_loop_parts(policy: Any) -> tuple[Li2023Controller, SlowEntry | None] | None:
    """The ``li2023`` controller (and the slow entry over it) that :class:`ClosedLoop` runs for ``policy``, or None.

    Exactly these classes (a subclass may change what a step does): ``Li2023Controller``, or a ``SlowEntry`` over
    one, possibly behind a wrapper that only chose it (a plan schedule: :meth:`Controller.stack_part`).
    """
    if not isinstance(policy, Controller):
        return None
    part = policy.stack_part()
    if type(part) is Li2023Controller:
        return part, None
    if type(part) is SlowEntry and type(part.base) is Li2023Controller:
        return part.base, part
    return None


EpisodeEnd = Callable[[int, np.ndarray], None]
"""Called when slot ``i`` has ended, with its rewards (one per step): the caller makes its result."""


class ClosedLoop:
    """Runs one episode in every slot of ``batch`` (reset, ``autoreset=False``), one ``li2023`` controller driving all.

    Args:
        batch: the batched env, just reset; one thread.
        li: the ``li2023`` controller set to the batch's episodes (one row each).
        entry: the slow entry over it, or None.
        log: the episodes' logs, kept step by step (the kernel fills their arrays), or None.
    """

    def __init__(
        self, batch: BatchedDrillEnv, li: Li2023Controller, entry: SlowEntry | None, log: StepLog | None = None
    ) -> None:
        if batch.threads != 1 or batch.autoreset:
            raise ValueError("the closed loop runs a batch with autoreset=False on one thread")
        self.batch, self.li, self.entry, self.log = batch, li, entry, log
        n = batch.num_envs
        self.obs64 = np.empty((n, OBS_SIZE))
        self.obs32 = np.empty((n, OBS_SIZE), dtype=np.float32)
        self.actions = np.zeros((n, 4), dtype=np.float32)
        cfg = li.config
        flags = (cfg.online, cfg.offline, li._y_any, li._y_all, entry is not None)
        self._switches = np.array([int(bool(f)) for f in flags], dtype=np.int64)
        self._reals = np.array([cfg.max_correction_m, cfg.point_period_s])
        self._per_point = np.array([li.steps_per_point], dtype=np.int64)

    def _controller_arrays(self) -> tuple[Any, ...]:
        """The controller's arrays in :func:`~drillgym.controllers.closed_loop_kernel.run_steps`' order.

        Read anew only when a compensation point has grown the point queue into new arrays.
        """
        li, m = self.li, self.li._model_rows
        entry_m, entry_offset = self.entry._entry if self.entry is not None else (_NO_ENTRY, _NO_ENTRY)
        return (
            li.force_window, li.tcp_window, li.point_times_s, li.point_corrections, li.point_ring, m.depth_m,
            m.lateral_task_n, m.sizes, m.model_of, np.ascontiguousarray(_rows(li.lateral)),
            np.ascontiguousarray(_rows(li.R)), np.ascontiguousarray(_rows(li.C_tool)), li.y_gain, entry_m,
            entry_offset, self._switches, self._reals, self._per_point,
        )  # fmt: skip

    def _take_point(self, counters: np.ndarray, ctl: tuple[Any, ...]) -> tuple[Any, ...]:
        """li2023's compensation point at the loop's step, in Python (its Jacobian and BLAS product).

        Returns the controller's arrays for the loop: anew only if the point queue grew into new arrays.
        """
        li = self.li
        li.step = int(counters[0])
        li._compensation_point(unpack_observation(self.obs32), li.step * CONTROL_DT_S)
        counters[1] = 1
        return ctl if li.point_times_s is ctl[2] else self._controller_arrays()

    def run(self, on_end: EpisodeEnd) -> None:
        """Step until every slot has ended, calling ``on_end`` for each as it ends."""
        batch, li = self.batch, self.li
        n = batch.num_envs
        observation_rows(batch.state, batch.params, batch.recorded > 0, bool(batch.scenario.tracker), self.obs64)
        self.obs32[:] = self.obs64
        noisy = np.array([is_noisy(p) for p in batch.params])
        counters = np.array([li.step, 0, 0, 0], dtype=np.int64)
        reward_rows = np.zeros((batch.record.shape[1] // SUBSTEPS_PER_STEP + 2, n))
        ended, no_end = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        limit_steps = batch.max_episode_steps < MAX_EPISODE_STEPS
        ctl = self._controller_arrays()
        log = self.log
        log_arrays = _NO_LOG if log is None else (np.ones(1, dtype=bool), log.held, log.valid, log.logged)
        while True:
            code = run_steps(
                tuple(batch.arrays), batch.command, batch.normals.rows, batch.normals.size - NOISE_SIZE, noisy,
                batch.record, batch.recorded, batch.active, batch._weights, batch.prev_action, batch.peak_lateral_n,
                batch.max_episode_steps, limit_steps, bool(batch.scenario.tracker), self.obs64, self.obs32, ctl,
                counters, reward_rows, ended, self.actions, _TWO, log_arrays,
            )  # fmt: skip
            if code == STOP_DONE:
                break
            if log is not None and code in (STOP_POINT, STOP_ENDED):  # every 12 steps at most, and at each end
                log.write_due(batch.active.nonzero()[0].tolist(), ended if code == STOP_ENDED else no_end)
            if code == STOP_POINT:
                ctl = self._take_point(counters, ctl)
            elif code == STOP_REFILL:
                batch._draw_ahead(batch.active.copy())
            elif code == STOP_FULL:
                reward_rows = np.concatenate([reward_rows, np.zeros_like(reward_rows)])
            elif code == STOP_ENDED:
                done = ended.nonzero()[0].tolist()
                for i in done:  # each generator where the single env's step-by-step draws leave it
                    batch.normals.sync(i, batch.envs[i].np_random, batch.state["noise_at"])
                batch.active[ended] = False
                for i in done:
                    on_end(i, reward_rows[: counters[2], i].copy())
            elif code == STOP_SINGULAR:
                st = batch.state
                i = int(np.argmax(st["singular"]))
                raise np.linalg.LinAlgError(f"episode {i}: singular TCP Jacobian at q = {st['q_motor_rad'][i]}")
            elif code == STOP_BAD_ACTION:
                checked_action(self.actions, "state unchanged", n)
                raise RuntimeError("the closed loop stopped on an action the check accepts")  # pragma: no cover
            else:  # pragma: no cover
                raise RuntimeError(f"closed loop: unknown stop {code}")
        li.step = int(counters[0])


def run_closed_loop(batch: BatchedDrillEnv, policy: Any, on_end: EpisodeEnd, log: StepLog | None = None) -> bool:
    """Run ``batch``'s episodes with ``policy`` (set to them) in the closed loop if it can; whether it did."""
    parts = closed_loop_parts(policy)
    if parts is None or batch.threads != 1 or batch.autoreset:  # an autoreset batch never ends: the Python loop's
        return False
    ClosedLoop(batch, *parts, log=log).run(on_end)
    return True
