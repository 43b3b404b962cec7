"""Batchable controllers: N episodes stepped at once command what each would alone, bit for bit."""

import numpy as np
import pytest
from cell_plan import plan_at_entry, q_at_entry

from drillgym.controllers import make_controller
from drillgym.controllers.batch import matvec
from drillgym.controllers.none import NoCompensation
from drillgym.envs.errors import UserError
from drillgym.envs.observation import OBS_BOUNDS


def _observations(rng: np.random.Generator, n: int, steps: int) -> list[dict[str, np.ndarray]]:
    """Random but plausible observations of ``n`` episodes (forces of a few N, depths across the entry)."""
    out = []
    for k in range(steps):
        obs = {key: np.zeros((n, size), np.float32) for key, (size, _) in OBS_BOUNDS.items()}
        obs["ft_wrench_mean"][:] = rng.normal(0.0, 2.0, (n, 6))
        obs["tcp_error_base_m"][:] = rng.normal(0.0, 1e-4, (n, 3))
        obs["q_rad"][:] = q_at_entry() + rng.normal(0.0, 1e-3, (n, 6))
        obs["path_depth_m"][:, 0] = k * 5e-5 + rng.uniform(0.0, 1e-4, n)  # 0 to 2 mm: past the CMRR's start
        obs["phase"][:, 1] = 1.0
        obs["feed_scale"][:] = 1.0
        out.append(obs)
    return out


@pytest.mark.parametrize(
    "spec",
    [
        "li2023",
        "li2023_tuned",
        "li2023:axes=x,kd=0.2,y_gain=1.4",
        "li2023:offline=false",
        "zhang2005",
        "zhang2005:thrust_ref_n=1,filter_samples=20",
        "li2023_cmrr:thrust_ref_n=1",
    ],
)
def test_a_batch_of_episodes_commands_what_each_episode_alone_commands_bit_for_bit(spec):
    n, steps = 5, 40  # 40 steps: three compensation points (every 12 steps)
    observations = _observations(np.random.default_rng(3), n, steps)
    batch = make_controller(spec)
    batch.set_plan(plan_at_entry(), n)
    together = np.stack([batch.act_batch(obs) for obs in observations])  # (steps, n, 4)
    for i in range(n):
        alone = make_controller(spec)
        alone.set_plan(plan_at_entry())
        actions = np.stack([alone.act({k: v[i] for k, v in obs.items()}) for obs in observations])
        assert actions.dtype == np.float32
        np.testing.assert_array_equal(actions, together[:, i])
    assert np.ptp(together[:, :, :3]) > 0.01  # the corrections move: the comparison is not of zeros
    if "thrust_ref_n" in spec:
        assert np.ptp(together[:, :, 3]) > 0.01  # so does the CMRR's feed


def test_a_controller_that_steps_one_episode_refuses_a_batch():
    class OneAtATime(NoCompensation):
        batchable = False

    with pytest.raises(UserError, match="one episode at a time"):
        OneAtATime().set_plan(plan_at_entry(), 4)


def test_matvec_is_the_matrix_product_row_by_row():
    rng = np.random.default_rng(0)
    m, per_row, x = rng.normal(size=(3, 3)), rng.normal(size=(4, 3, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(matvec(m, x), x @ m.T, rtol=1e-14)
    np.testing.assert_allclose(matvec(per_row, x), np.einsum("nij,nj->ni", per_row, x), rtol=1e-14)


def test_matvec_gives_the_elementwise_sum_in_its_order_bit_for_bit():
    """``(m0 x0 + m1 x1) + m2 x2`` as numpy evaluates it elementwise: no fused multiply-add, no reordering."""
    rng = np.random.default_rng(1)
    for k in range(200):
        n = int(rng.integers(1, 9))
        x = rng.normal(size=(n, 3)) * 10.0 ** float(rng.integers(-6, 3))
        m = rng.normal(size=(3, 3)) if k % 2 else rng.normal(size=(n, 3, 3))
        rows = m if m.ndim == 3 else np.broadcast_to(m, (n, 3, 3))
        expected = rows[:, :, 0] * x[:, None, 0] + rows[:, :, 1] * x[:, None, 1] + rows[:, :, 2] * x[:, None, 2]
        assert np.array_equal(matvec(m, x), expected)


def test_zhang2005_cross_product_is_numpys_bit_for_bit():
    from drillgym.controllers.zhang2005 import _cross

    rng = np.random.default_rng(3)
    for _ in range(2000):
        a = rng.normal(size=3) * 10.0 ** rng.integers(-8, 8, 3) * (rng.random(3) > 0.3)
        b = rng.normal(size=3) * 10.0 ** rng.integers(-8, 8, 3) * (rng.random(3) > 0.3)
        assert _cross(a, b).tobytes() == np.cross(a, b).tobytes()  # signed zeros too
