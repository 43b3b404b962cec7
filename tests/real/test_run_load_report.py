"""``drillgym run``'s servo-timing line and its likely cause of a stale-stream or watchdog stop (issue 43, item 5).

The decision rule (:func:`drillgym.eval.real.load_report.likely_cause`) on stub numbers, on both sides of each of its
bars: the kind of stop, at least one missed cycle, a 1-min load average at the core count. One realtime run on the
emulator checks that the console says what the rule makes of the numbers the run recorded.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.eval.real.load_report import (
    LOAD_FAULTS,
    ServoTiming,
    describe_timing,
    likely_cause,
    period_stats_s,
    servo_timing,
    this_process_scheduling,
)

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)


def timing(missed: int = 14, load: float = 7.3, cores: int = 2, realtime: bool = True) -> ServoTiming:
    """Stub timing of one hole: 8 ms periods, one 120 ms gap, a 35 ms longest servoL call, the servo process at
    SCHED_FIFO by default."""
    scheduling = "SCHED_FIFO priority 20 (servo process)" if realtime else "SCHED_OTHER nice -10 (servo process)"
    return ServoTiming(1200, missed, 0.008, 0.0091, 0.120, scheduling, realtime, load, cores, 0.035)


def test_the_period_statistics_are_taken_over_the_gaps_between_consecutive_commands():
    """Gaps 8, 8, 54, 8 ms: the median 8 ms, the maximum 54 ms, the 99th percentile by linear interpolation between
    the two largest sorted gaps, 8 + 0.97 · 46 = 52.62 ms (index 0.99 · 3 = 2.97). 1e-12 s: float rounding only."""
    median, p99, worst = period_stats_s([0.0, 0.008, 0.016, 0.070, 0.078])
    assert median == pytest.approx(0.008, abs=1e-12)
    assert p99 == pytest.approx(0.05262, abs=1e-12)
    assert worst == pytest.approx(0.054, abs=1e-12)


@pytest.mark.parametrize("sends", [[], [0.5]])
def test_fewer_than_two_commands_have_no_period(sends):
    assert all(math.isnan(v) for v in period_stats_s(sends))


def test_the_timing_line_gives_cycles_missed_periods_longest_call_scheduling_and_load():
    line = describe_timing(timing())
    assert line == (
        "servo loop: 1200 cycles, 14 missed; period median 8.0 ms, p99 9.1 ms, max 120.0 ms; "
        "longest servoL call 35.0 ms; SCHED_FIFO priority 20 (servo process); load average 7.3 on 2 cores"
    )


def test_the_timing_line_says_n_a_for_a_loop_that_never_ran_two_cycles():
    stub = ServoTiming(1, 0, math.nan, math.nan, math.nan, "SCHED_FIFO priority 20 (servo process)", True, 0.2, 2)
    assert "period median n/a, p99 n/a, max n/a; longest servoL call n/a;" in describe_timing(stub)


@pytest.mark.parametrize("failure", LOAD_FAULTS)
def test_a_stale_or_watchdog_stop_after_missed_cycles_on_a_saturated_machine_names_the_load(failure):
    cause = likely_cause(failure, timing(missed=14, load=7.3, cores=2))
    assert cause is not None
    assert cause.startswith(f"{failure} after 14 missed cycles, load average 7.3 on 2 cores: the machine was likely")
    assert "too busy" in cause and "cap_sys_nice" not in cause  # the loop was real-time: no priority advice


def test_a_load_average_equal_to_the_core_count_is_busy_and_just_below_is_not():
    """The bar is one runnable task per core (BUSY_LOAD_PER_CORE = 1): 2.0 on 2 cores is on it, 1.99 below it."""
    assert "too busy" in (likely_cause("rtde_stale", timing(load=2.0, cores=2)) or "")
    below = likely_cause("rtde_stale", timing(load=1.99, cores=2)) or ""
    assert "too busy" not in below and "not saturated" in below and "steal time" in below


def test_one_missed_cycle_is_enough_and_none_is_not():
    one = likely_cause("ft_stale", timing(missed=1)) or ""
    assert one.startswith("ft_stale after 1 missed cycle, load average") and "too busy" in one
    none = likely_cause("ft_stale", timing(missed=0)) or ""
    assert none.startswith("ft_stale with no missed servo cycle (load average 7.3 on 2 cores)")
    assert "not this machine's load" in none and "Net F/T" in none and "too busy" not in none


def test_no_missed_cycle_before_an_rtde_stop_points_at_the_robot_link():
    cause = likely_cause("rtde_stale", timing(missed=0, load=0.3)) or ""
    assert "kept its period" in cause and "network link to the robot" in cause


@pytest.mark.parametrize("failure", [None, "force_limit", "protective_stop", "tracking", "link_lost", "agent_timeout"])
def test_other_ends_get_no_likely_cause_however_busy_the_machine(failure):
    assert likely_cause(failure, timing(missed=500, load=40.0, cores=2)) is None


def test_a_loop_without_real_time_priority_is_told_how_to_get_it():
    cause = likely_cause("watchdog_cycle", timing(realtime=False)) or ""
    assert "too busy" in cause and "not real-time (SCHED_OTHER nice -10 (servo process))" in cause
    assert "cap_sys_nice" in cause


def test_the_timing_is_read_from_the_env_s_servo_loop_and_its_process():
    """A stub of the real env after a hole: the servo's send times and counts, the servo process's scheduling."""
    stats = SimpleNamespace(cycles=4, missed_cycles=6, servo_call_max_s=0.031)
    servo = SimpleNamespace(history_t=[0.0, 0.008, 0.016, 0.072], stats=stats)
    process = SimpleNamespace(scheduling="SCHED_FIFO priority 20", realtime=True)
    env = SimpleNamespace(unwrapped=SimpleNamespace(servo=servo, devices=SimpleNamespace(process=process)))
    got = servo_timing(env)
    assert got is not None and (got.cycles, got.missed_cycles, got.servo_call_max_s) == (4, 6, 0.031)
    assert got.period_max_s == pytest.approx(0.056, abs=1e-12)  # float rounding only
    assert got.scheduling == "SCHED_FIFO priority 20 (servo process)" and got.realtime
    assert got.cores >= 1 and got.load_1min >= 0.0


def test_a_servo_thread_reports_this_process_s_scheduling_and_no_servo_no_timing():
    servo = SimpleNamespace(
        history_t=[0.0, 0.008], stats=SimpleNamespace(cycles=2, missed_cycles=0, servo_call_max_s=0.002)
    )
    env = SimpleNamespace(unwrapped=SimpleNamespace(servo=servo, devices=SimpleNamespace(process=None)))
    got = servo_timing(env)
    assert got is not None and got.scheduling.endswith("(thread of this process, --servo-thread)")
    assert got.scheduling.startswith(this_process_scheduling()[0])
    assert servo_timing(SimpleNamespace(unwrapped=SimpleNamespace(servo=None))) is None


def test_this_process_scheduling_names_the_policy_and_its_niceness_or_priority():
    what, realtime = this_process_scheduling()
    assert what.startswith("SCHED_")
    assert (" priority " in what) if realtime else (" nice " in what)


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_run_explains_a_stale_stop_on_the_console_by_the_rule_on_its_recorded_numbers(start_emulator, tmp_path, capsys):
    """The emulator's F/T stream stops 1 s after the first servoL: the hole ends on a stream stop (ft_stale, or
    another of the stream stops first on a busy machine); the console's timing line and likely cause are the rule's
    on the numbers ``metrics.json`` recorded (the load average is read once, at the end of the hole)."""
    from drillgym.eval.cli import main

    emu = start_emulator(scenario={"feed_mm_s": 3.0, "depth_mm": 3.0}, extra_args=["--fault", "stale_ft@1.0"])
    argv = ["run", "--robot", emu.host, "--scenario", "feed_mm_s=3,depth_mm=3", "--yes", "--max-gap-ms", "500"]
    assert main([*argv, "--out", str(tmp_path)]) == 3
    out = capsys.readouterr().out
    result = json.loads((tmp_path / "metrics.json").read_text())[0]
    assert result["failure"] in LOAD_FAULTS, result["error"]
    recorded = {k: (math.nan if v is None else v) for k, v in result["servo_timing"].items()}
    stub = ServoTiming(**recorded)
    assert f"  {describe_timing(stub)}\n" in out
    assert f"  likely cause: {likely_cause(result['failure'], stub)}\n" in out
    assert stub.missed_cycles == result["missed_cycles"] and np.isfinite(stub.period_median_s)
