"""The batched env's threaded compiled step gives the one-thread step's numbers, bit for bit."""

import numba
import numpy as np
import pytest

from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.effects.cells import CELLS
from drillgym.envs.errors import UserError


def _run(threads: int, effects: str = "", steps: int = 330) -> tuple[list, BatchedDrillEnv]:
    """Steps of six episodes of two scenarios on random actions, autoreset included; every step's outputs."""
    env = BatchedDrillEnv(6, threads=threads, effects=effects)
    env.reset(seed=11, options={"scenario": [{}, {"beta_deg": -10.0, "feed_mm_s": 0.9}] * 3})
    rng = np.random.default_rng(5)
    out = []
    for _ in range(steps):
        obs, reward, terminated, truncated, infos = env.step(rng.uniform(-0.5, 0.5, (6, 4)).astype(np.float32))
        out.append(({k: v.copy() for k, v in obs.items()}, reward, terminated, truncated, infos["deviation_m"]))
    return out, env


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="one CPU: numba has one thread")
@pytest.mark.parametrize(
    "effects", ["", CELLS["li2023-lab"], "latency:extra_latency_s=0.03+thermal_softening:softening=0.2"]
)
def test_two_threads_step_every_episode_as_one_thread_does(effects):
    one, env1 = _run(1, effects)
    two, env2 = _run(2, effects)
    assert any(step[2].any() for step in one), "no episode ended: autoreset untested"
    for k, (a, b) in enumerate(zip(one, two, strict=True)):
        for key in a[0]:
            np.testing.assert_array_equal(a[0][key], b[0][key], err_msg=f"step {k}: {key}")
        for x, y in zip(a[1:], b[1:], strict=True):
            np.testing.assert_array_equal(x, y, err_msg=f"step {k}")
    np.testing.assert_array_equal(env1.record, env2.record)
    assert env1.state.tobytes() == env2.state.tobytes()


@pytest.mark.parametrize("threads", [0, -1, 1.5, numba.config.NUMBA_NUM_THREADS + 1])
def test_thread_counts_outside_numbas_are_refused(threads):
    with pytest.raises(UserError, match="threads="):
        BatchedDrillEnv(2, threads=threads)
