"""Compile the controllers' numba kernels ahead of use, into numba's on-disk cache.

:func:`drillgym.controllers.batch.matvec`, the stacked offline models' interpolation
(:mod:`drillgym.controllers.stacked_models`), li2023's step (:mod:`drillgym.controllers.li2023_step`) and the slow
entry's feed offset and the closed loop of the li2023 family (:mod:`drillgym.controllers.closed_loop_kernel`) are compiled on first call and cached beside its source (or in
``NUMBA_CACHE_DIR``); ``make install`` runs this module once, after :mod:`drillgym.envs.compiled`, so that a
controller streaming to a robot does not stall on its first action.

    python -m drillgym.controllers.compiled
"""

from __future__ import annotations

import time

import numpy as np

from drillgym.controllers.batch import matvec
from drillgym.controllers.closed_loop import run_closed_loop
from drillgym.controllers.feed_schedule import add_entry_feed
from drillgym.controllers.li2023_step import actions_into
from drillgym.controllers.models import OfflineForceModel
from drillgym.controllers.registry import make_controller
from drillgym.controllers.stacked_models import StackedOfflineModels
from drillgym.envs.batched import BatchedDrillEnv


def compile_kernels() -> float:
    """Call every kernel with the argument layouts the controllers pass (compiling or loading it); the seconds it took."""
    t0 = time.perf_counter()
    x = np.zeros((2, 3))
    matvec(np.eye(3), x)  # a matrix shared by the batch
    matvec(np.zeros((2, 3, 3)), x)  # one per episode
    matvec(np.eye(3), np.zeros((2, 6))[:, :3])  # a strided view
    model = OfflineForceModel(np.linspace(0.0, 1.0, 4), np.zeros((4, 2)))  # stacked offline models, two episodes
    stacked = StackedOfflineModels([model, model])
    stacked.lateral_into(np.zeros(2), np.zeros((2, 3)))
    eye = np.eye(3)[None]  # li2023's step: matrices shared (1, 3, 3) and per episode (2, 3, 3)
    for m in (eye, np.repeat(eye, 2, axis=0)):
        actions_into(
            np.zeros(2), True, stacked.depth_m, stacked.lateral_task_n, stacked.sizes, stacked.model_of, m, m, m,
            np.zeros((2, 3)), np.ones(1), False, False, 1e-3, np.zeros((2, 3)), np.zeros((2, 4), dtype=np.float32),
        )  # fmt: skip
    actions = np.zeros((2, 4), dtype=np.float32)  # the slow entry's feed offset, on an observation's column
    depth = np.zeros((2, 33), dtype=np.float32)[:, 25]
    add_entry_feed(actions, depth, np.zeros(1), np.zeros(1))
    add_entry_feed(actions, depth, np.zeros(2), np.zeros(2))
    batch = BatchedDrillEnv(1, autoreset=False, max_episode_steps=2)  # the closed loop: two steps of li2023_tuned
    try:
        batch.reset(seed=0)
        controller = make_controller("li2023_tuned")
        controller.set_plan(batch.envs[0].plan)
        run_closed_loop(batch, controller, lambda i, rewards: None)
    finally:
        batch.close()
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"drillgym: controller kernels ready ({compile_kernels():.1f} s)")
