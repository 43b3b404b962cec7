"""Normals drawn ahead (envs/noise_ahead.py): the stream read is the generator's, and sync puts it back exactly."""

import numpy as np
import pytest

from drillgym.envs.noise_ahead import NormalsAhead


def _read(ahead: NormalsAhead, rng: np.random.Generator, noise_at: np.ndarray, count: int, step_most: int) -> list:
    """Read ``count`` normals as the compiled step does: refill when fewer than ``step_most`` are left."""
    if noise_at[0] > ahead.size - step_most:
        ahead.refill(0, rng, noise_at)
    at = int(noise_at[0])
    noise_at[0] = at + count
    return ahead.rows[0, at : at + count].tolist()


@pytest.mark.parametrize("seed", range(6))
def test_normals_read_are_the_generators_stream_and_sync_leaves_it_past_them(seed):
    plan = np.random.default_rng(seed)
    ahead = NormalsAhead(1, 99)
    noise_at = np.zeros(1, dtype=np.int64)
    rng = np.random.default_rng(1000 + seed)
    ahead.restart(0, noise_at)
    reference = np.random.default_rng(1000 + seed)
    for episode in range(4):
        got: list[float] = []
        for _ in range(int(plan.integers(1, 40))):
            got += _read(ahead, rng, noise_at, int(plan.choice([0, 3, 30, 33])), 33)
        ahead.sync(0, rng, noise_at)
        assert got == reference.standard_normal(len(got)).tolist()
        assert rng.bit_generator.state == reference.bit_generator.state, episode
        assert noise_at[0] == ahead.size  # empty again: the next episode draws afresh


def test_sync_just_after_a_refill_reaches_back_before_the_latest_block():
    """A refill moves the unread tail to the front; if the episode ends before the tail is read, the generator goes
    back to the state before the previous block."""
    ahead = NormalsAhead(1, 10)
    noise_at = np.zeros(1, dtype=np.int64)
    rng, reference = np.random.default_rng(7), np.random.default_rng(7)
    ahead.restart(0, noise_at)
    got = _read(ahead, rng, noise_at, 8, 4)  # one block of 10, 2 left unread
    got += _read(ahead, rng, noise_at, 1, 4)  # refill: the 2 move to the front, 1 of them is read
    assert noise_at[0] == 1
    ahead.sync(0, rng, noise_at)
    assert got == reference.standard_normal(9).tolist()
    assert rng.bit_generator.state == reference.bit_generator.state
