"""The compiled tip balance (TipContactSolver.run) gives the same bits in blocks of any size as sample by sample."""

import copy

import numpy as np
import pytest

from drillgym.envs.cell import SimCell
from drillgym.envs.scenario import Scenario


def _targets(rng: np.random.Generator, start_z: float, n: int, lateral_m: float) -> list[tuple[float, float, float]]:
    """A feed into the bone at ~0.05 mm per sample with a wandering lateral correction (m, task frame)."""
    z = start_z + 5e-5 * np.arange(1, n + 1)
    xy = np.cumsum(rng.normal(0.0, lateral_m, size=(n, 2)), axis=0)
    return [(float(x), float(y), float(zz)) for (x, y), zz in zip(xy, z, strict=True)]


@pytest.mark.parametrize("beta_deg", [0.0, 30.0, -20.0])
@pytest.mark.parametrize("chunk", [1, 3, 5])
def test_run_in_blocks_over_a_whole_hole_is_bit_identical_to_update_per_sample(beta_deg, chunk):
    rng = np.random.default_rng(int(beta_deg) + 100 * chunk)
    cell_a = SimCell(Scenario(beta_deg=beta_deg))
    cell_a.reset(np.array([0.0, 0.0, -0.3e-3]))
    cell_b = copy.deepcopy(cell_a)
    targets = _targets(rng, -0.3e-3, 140, 2e-6)
    for i in range(0, len(targets), chunk):
        block = targets[i : i + chunk]
        for cell in (cell_a, cell_b):
            cell.begin_step(2e-6 * (1 + i % 3), 5e-5)
        rows = cell_a.run(block, 0.4)
        singles = [cell_b.update(t, 0.4) for t in block]
        for row, smp in zip(rows, singles, strict=True):
            assert row == (smp.tip, smp.rigid, smp.force, smp.torque_axis, smp.depth_local, smp.stage, smp.cutting)
            assert np.array(row[:3]).tobytes() == np.array([smp.tip, smp.rigid, smp.force]).tobytes()  # signs of 0
        assert cell_a.sample == cell_b.sample
        for cell in (cell_a, cell_b):
            cell.end_step()
    sa, sb = cell_a.solver, cell_b.solver
    assert (sa.rigid, sa.tip, sa.force, sa.torque, sa.depth_local, sa.touching, sa.bottom_z, sa._j) == (
        sb.rigid,
        sb.tip,
        sb.force,
        sb.torque,
        sb.depth_local,
        sb.touching,
        sb.bottom_z,
        sb._j,
    )
    assert sa.bottom_z > 5e-3  # the test drilled, so every branch of the balance ran
    assert np.array_equal(sa.hole.centre_xy_m, sb.hole.centre_xy_m)
    assert sa.hole.deepest_bin == sb.hole.deepest_bin > 0


def test_run_with_no_targets_leaves_the_state_alone():
    cell = SimCell(Scenario())
    before = copy.deepcopy(cell.solver.__dict__)
    cell.begin_step(2e-6, 5e-5)
    assert cell.run([], 0.4) == []
    assert cell.solver.tip == before["tip"] and cell.solver.rigid == before["rigid"]
