"""Seed namespaces: the judge's episodes and every other purpose's are different integers by construction."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drillgym.envs.seeds import (
    INDEX_LIMIT,
    Purpose,
    draw_seed,
    episode_seed,
    purpose_of,
    stream,
    training_stream,
)

indices = st.integers(min_value=0, max_value=INDEX_LIMIT - 1)
purposes = st.sampled_from(list(Purpose))


def test_judge_seeds_are_the_plain_benchmark_seeds():
    assert [episode_seed(Purpose.JUDGE, i) for i in range(5)] == [0, 1, 2, 3, 4]
    assert [episode_seed(Purpose.JUDGE, 7 + i) for i in range(2)] == [7, 8]


@settings(max_examples=500, deadline=None)
@given(purposes, indices, purposes, indices)
def test_two_purposes_never_share_a_seed_whatever_the_indices(p, i, q, j):
    a, b = episode_seed(p, i), episode_seed(q, j)
    assert purpose_of(a) == p and purpose_of(b) == q
    if p != q:
        assert a != b
    else:
        assert (a == b) == (i == j)


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=2**40), st.integers(min_value=0, max_value=64), purposes)
def test_child_seeds_stay_in_their_purposes_namespace(run_seed, rank, p):
    assert purpose_of(draw_seed(stream(p, run_seed, rank), p)) == p


def test_runs_s_and_s_plus_one_share_no_worker_stream():
    """SB3 seeds worker r of run s with s + r, so runs 0 and 1 shared a worker; keyed streams share none."""
    seeds = {
        (s, r): [draw_seed(stream(Purpose.TRAIN, s, r), Purpose.TRAIN) for _ in range(3)]
        for s in range(5)
        for r in range(4)
    }
    firsts = [v[0] for v in seeds.values()]
    assert len(set(firsts)) == len(firsts)
    assert training_stream((0, 1), None).integers(1 << 30) != training_stream((1, 0), None).integers(1 << 30)


def test_out_of_range_indices_and_seeds_outside_every_namespace_are_refused():
    with pytest.raises(ValueError, match=r"must be in \[0, 2\^48\)"):
        episode_seed(Purpose.TUNE, -1)
    with pytest.raises(ValueError, match=r"must be in \[0, 2\^48\)"):
        episode_seed(Purpose.TUNE, INDEX_LIMIT)
    with pytest.raises(ValueError, match="no purpose's namespace"):
        purpose_of(len(Purpose) << 48)


def test_a_namespaced_seed_seeds_a_gymnasium_generator_of_its_own():
    """Gymnasium builds ``np_random`` from ``SeedSequence(seed)``: a big seed is a different stream, not wrapped."""
    from gymnasium.utils import seeding

    draws = {s: seeding.np_random(s)[0].standard_normal() for s in (3, episode_seed(Purpose.TUNE, 3))}
    assert len(set(draws.values())) == 2
    assert np.isfinite(list(draws.values())).all()
