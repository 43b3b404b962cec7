"""The loaded-runs benchmark's rule for an explained stop (``drillgym.eval.perf.loaded_runs``), on console texts."""

from drillgym.eval.perf.loaded_runs import _explained

TIMING = (
    "  servo loop: 2540 cycles, 14 missed; period median 8.0 ms, p99 9.1 ms, max 121.7 ms; load average 7.3 on 2 cores"
)


def test_a_finished_hole_needs_no_explanation():
    assert _explained("hole 1: metrics ...", None)


def test_a_stale_stop_is_explained_only_with_its_fault_line_timing_and_likely_cause():
    fault = "  ENDED ON A FAULT: rtde_stale: no RTDE state for 0.12 s; stop: ok"
    cause = "  likely cause: rtde_stale after 14 missed cycles, load average 7.3 on 2 cores: the machine was likely too busy"
    assert _explained("\n".join([fault, TIMING, cause]), "rtde_stale")
    assert not _explained("\n".join([fault, TIMING]), "rtde_stale")  # no likely cause
    assert not _explained("\n".join([TIMING, cause]), "rtde_stale")  # the fault is not named
    assert not _explained("\n".join([fault, cause]), "rtde_stale")  # no servo timing


def test_another_stop_is_explained_by_its_fault_line_and_the_timing():
    fault = "  ENDED ON A FAULT: force_limit: lateral force 12.1 N over 10 N; stop: ok"
    assert _explained("\n".join([fault, TIMING]), "force_limit")
    assert not _explained(TIMING, "force_limit")
