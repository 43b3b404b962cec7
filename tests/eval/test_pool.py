"""The process pool helper: the same results in this process and in spawned workers."""

import math

import pytest

from drillgym.eval.pool import run_ordered, run_unordered


@pytest.mark.parametrize("workers", [1, 2])
def test_results_come_back_in_job_order_whatever_the_worker_count(workers):
    jobs = [0.0, 1.0, 4.0, 9.0, 16.0]
    assert run_ordered(math.sqrt, jobs, workers) == [0.0, 1.0, 2.0, 3.0, 4.0]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_job_becomes_its_on_error_result_and_the_others_finish(workers):
    out = dict(
        run_unordered(math.sqrt, [4.0, -1.0, 9.0], workers, on_error=lambda job, e: f"{job}: {type(e).__name__}")
    )
    assert out == {0: 2.0, 1: "-1.0: ValueError", 2: 3.0}


def test_without_on_error_a_failing_job_raises_here():
    with pytest.raises(ValueError):
        run_ordered(math.sqrt, [-1.0, 4.0], 2)


def test_the_initializer_runs_before_in_process_jobs():
    seen = []
    assert run_ordered(len, ["ab"], 1, initializer=seen.append, initargs=("init",)) == [2]
    assert seen == ["init"]


def test_zero_workers_is_an_error():
    with pytest.raises(ValueError, match="workers"):
        list(run_unordered(math.sqrt, [1.0], 0))
