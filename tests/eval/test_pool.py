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


def _running(pid: int) -> bool:
    """Whether ``pid`` is a live process (a zombie waiting to be reaped counts as gone)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return not any(line.startswith("State:") and "Z" in line.split()[1] for line in f)
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not __import__("os").path.isdir("/proc"), reason="reads /proc")
def test_workers_exit_when_the_parent_is_killed_instead_of_running_on():
    import os
    import signal
    import subprocess
    import sys
    import time

    script = (
        "import multiprocessing, threading, time\n"
        "from drillgym.eval.pool import run_unordered\n"
        "threading.Thread(target=lambda: list(run_unordered(time.sleep, [60.0, 60.0], 2)), daemon=True).start()\n"
        "while len(multiprocessing.active_children()) < 2: time.sleep(0.05)\n"
        "print(*[p.pid for p in multiprocessing.active_children()], flush=True)\n"
        "time.sleep(60)\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    workers: list[int] = []
    try:
        workers = [int(p) for p in parent.stdout.readline().split()]
        assert len(workers) == 2 and all(_running(p) for p in workers)
        time.sleep(1.0)  # the workers are in their 60 s jobs
        parent.send_signal(signal.SIGTERM)  # no shutdown of the pool: the parent just dies
        parent.wait(10)
        deadline = time.monotonic() + 10.0
        while any(_running(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_running(p) for p in workers)
    finally:
        parent.kill()
        for p in workers:
            if _running(p):
                os.kill(p, signal.SIGKILL)


def _pid(_: object) -> int:
    import os

    return os.getpid()


def test_a_worker_pool_keeps_its_workers_from_one_round_of_jobs_to_the_next():
    from drillgym.eval.pool import WorkerPool

    with WorkerPool(2) as pool:
        first = {pid for _, pid in pool.map_unordered(_pid, list(range(6)))}
        second = {pid for _, pid in pool.map_unordered(_pid, list(range(6)))}
    import os

    assert os.getpid() not in first
    assert second <= first and 1 <= len(first) <= 2


def test_a_worker_pool_runs_a_lone_job_in_process_until_its_workers_have_started():
    import os

    from drillgym.eval.pool import WorkerPool

    with WorkerPool(2) as pool:
        assert dict(pool.map_unordered(_pid, [0])) == {0: os.getpid()}
        assert os.getpid() not in {pid for _, pid in pool.map_unordered(_pid, [0, 1])}
        assert dict(pool.map_unordered(_pid, [0]))[0] != os.getpid()  # started: even one job goes to a worker


def _die(_: object) -> int:
    import os

    os._exit(3)


def test_a_worker_pool_starts_fresh_workers_after_one_died():
    from drillgym.eval.pool import WorkerPool

    with WorkerPool(2) as pool:
        out = dict(pool.map_unordered(_die, [0, 1], on_error=lambda job, e: type(e).__name__))
        assert out == {0: "BrokenProcessPool", 1: "BrokenProcessPool"}
        assert sorted(r for _, r in pool.map_unordered(math.sqrt, [4.0, 9.0])) == [2.0, 3.0]


def _meet(job: tuple[int, str, bool]) -> int:
    """In the process that started the pool: wait for a worker to have run a job; in a worker: say so (and die)."""
    import os
    import pathlib
    import time

    parent, flag, die = job
    if os.getpid() != parent:
        pathlib.Path(flag).touch()
        if die:
            os._exit(3)
        return os.getpid()
    deadline = time.monotonic() + 60.0
    while not pathlib.Path(flag).exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    return os.getpid()


def test_a_pool_counting_this_process_runs_jobs_here_and_in_its_worker(tmp_path):
    import os

    from drillgym.eval.pool import WorkerPool

    jobs = [(os.getpid(), str(tmp_path / "met"), False)] * 4
    with WorkerPool(2, here=True) as pool:
        out = dict(pool.map_unordered(_meet, jobs))
        assert sorted(out) == [0, 1, 2, 3]
        assert len(set(out.values())) == 2 and os.getpid() in out.values()  # one worker spawned, this process
        assert sorted(r for _, r in pool.map_unordered(math.sqrt, [4.0, 9.0, 16.0])) == [2.0, 3.0, 4.0]


def test_a_pool_counting_this_process_runs_the_rest_here_when_its_worker_dies(tmp_path):
    import os

    from drillgym.eval.pool import WorkerPool

    jobs = [(os.getpid(), str(tmp_path / "met"), True)] * 5
    with WorkerPool(2, here=True) as pool:
        out = dict(pool.map_unordered(_meet, jobs, on_error=lambda job, e: type(e).__name__))
        assert sorted(out) == [0, 1, 2, 3, 4]
        assert sorted(out.values(), key=str) == [os.getpid()] * 4 + ["BrokenProcessPool"]
        assert sorted(r for _, r in pool.map_unordered(math.sqrt, [4.0, 9.0])) == [2.0, 3.0]  # fresh workers


def test_a_pool_counting_this_process_raises_a_failing_job_here_without_on_error():
    from drillgym.eval.pool import WorkerPool

    with WorkerPool(2, here=True) as pool, pytest.raises(ValueError):
        list(pool.map_unordered(math.sqrt, [4.0, -1.0, 9.0, -4.0]))


def _sigint_ignored(_: object) -> bool:
    import signal

    return signal.getsignal(signal.SIGINT) is signal.SIG_IGN


def test_workers_ignore_ctrl_c_which_the_process_that_started_them_handles():
    import signal

    from drillgym.eval.pool import WorkerPool

    before = signal.getsignal(signal.SIGINT)
    with WorkerPool(2) as pool:
        assert all(ignored for _, ignored in pool.map_unordered(_sigint_ignored, [0, 1, 2, 3]))
    assert signal.getsignal(signal.SIGINT) is before


def _wait_or_fail(job: tuple[str, str]) -> None:
    """The long job (``"run"``): say it started, sleep, mark that it unwound; the other waits for it, then fails."""
    import pathlib
    import time

    kind, folder = job
    started, unwound = pathlib.Path(folder, "started"), pathlib.Path(folder, "unwound")
    if kind == "run":
        started.touch()
        try:
            time.sleep(60.0)
        finally:
            unwound.touch()
        return
    deadline = time.monotonic() + 60.0
    while not started.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    raise ValueError("the other job is running")


def test_an_error_here_stops_the_running_jobs_at_once_and_unwinds_them(tmp_path):
    import time

    from drillgym.eval.pool import WorkerPool

    t0 = time.monotonic()
    with pytest.raises(ValueError, match="the other job is running"), WorkerPool(2) as pool:
        list(pool.map_unordered(_wait_or_fail, [("run", str(tmp_path)), ("fail", str(tmp_path))]))
    assert time.monotonic() - t0 < 30.0  # not the long job's 60 s
    assert (tmp_path / "unwound").exists()  # its finally block ran
