"""Compile the cell's numba kernels ahead of use, into numba's on-disk cache.

The kernels (:mod:`drillgym.envs.robot.ur5_kernel`, :mod:`drillgym.envs.drilling.contact_kernel`,
:mod:`drillgym.envs.step_kernel`) are
compiled on first call (about 10 s) and cached beside their sources (or in ``NUMBA_CACHE_DIR``); every
later process loads them in milliseconds. ``make install`` runs this module once, so that no command,
test or worker pays the compile (a process that streams to a robot must not stall 10 s on its first step).

    python -m drillgym.envs.compiled
"""

from __future__ import annotations

import time

import numpy as np

from drillgym.envs import step_kernel as sk
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.cell import SimCell
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.scenario import Scenario


def compile_kernels() -> float:
    """Run one short simulated step of every kernel (compiling or loading it); the seconds it took."""
    t0 = time.perf_counter()

    cell = SimCell(Scenario())
    cell.reset(np.array([0.0, 0.0, -0.05e-3]))
    cell.begin_step(2e-6, 5e-6)
    cell.run([(0.0, 0.0, -0.04e-3), (0.0, 0.0, -0.03e-3)])
    cell.end_step()
    cell.marker_base_m()

    env = UR5BoneDrillEnv()
    env.reset(seed=0)
    env.step(np.zeros(4, dtype=np.float32))
    env.close()
    env = UR5BoneDrillEnv(ft_noise_n=0.0, tracker_noise_mm=0.0)  # an open-loop replay (the diagnosis)
    env.reset(seed=0)
    env.advance_open_loop(np.zeros((1, 4)))
    env.close()

    batch = BatchedDrillEnv(2)
    batch.reset(seed=0)
    batch.step(np.zeros((2, 4), dtype=np.float32))
    # the threaded step too, whatever the CPUs (BatchedDrillEnv(threads=...) calls it)
    sk.advance_batch_threaded(
        *batch.arrays, batch.command, batch.normals.rows, batch.record, batch.recorded, batch.active
    )
    batch.close()
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"drillgym: numba kernels ready ({compile_kernels():.1f} s)")
