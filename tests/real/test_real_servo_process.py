"""The servo loop's own process: what it shares with the agent's process, and how it ends."""

import multiprocessing
import time

import numpy as np
import pytest
from real_cell import CI_LIMITS, ONE_CELL_AT_A_TIME, make_real_env, run_steps

from drillgym.controllers import make_controller
from drillgym.envs.real.netft import FTRecord
from drillgym.envs.real.servo_bench import missed_periods, sleep_floor
from drillgym.envs.real.servo_shared import SharedCommandSlot, SharedFTRing
from drillgym.eval.perf.rtde import echo_latencies_s

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)


def _record(t):
    return FTRecord(t, int(t * 10), 0, np.arange(6) + t)


def test_the_shared_ring_returns_whole_records_in_order_across_a_wrap():
    ring = SharedFTRing(capacity=100)
    assert ring.latest() is None and ring.since(0.0) == []
    for k in range(250):
        ring.append(_record(float(k)))
    assert ring.count == 250 and ring.latest().t_recv_s == 249.0
    got = ring.since(200.0)
    assert [r.t_recv_s for r in got] == [float(k) for k in range(200, 250)]
    np.testing.assert_array_equal(got[0].wrench, np.arange(6) + 200.0)
    assert got[0].rdt_sequence == 2000 and got[0].status == 0
    assert [r.t_recv_s for r in ring.since(0.0)] == [float(k) for k in range(151, 250)]  # the oldest were overwritten


def _write_command(slot):
    slot.write(np.array([1e-4, -2e-4, 3e-4]), 1.5, 42.0)


def test_a_command_written_in_another_process_is_read_whole():
    ctx = multiprocessing.get_context("spawn")
    slot = SharedCommandSlot(ctx)
    p = ctx.Process(target=_write_command, args=(slot,))
    p.start()
    p.join(30.0)
    corr, scale, t = slot.read()
    np.testing.assert_array_equal(corr, [1e-4, -2e-4, 3e-4])
    assert scale == 1.5 and t == 42.0


def test_echo_latency_is_matched_to_the_first_state_showing_the_command():
    send_t, send_z = [0.0, 0.008, 0.016], [1.0, 2.0, 1.0]  # the third command repeats the first's code
    seen = [(0.004, 1.0), (0.013, 2.0), (0.030, 1.0)]
    assert echo_latencies_s(send_t, send_z, seen) == pytest.approx([0.004, 0.005, 0.014])


def test_a_late_cycle_counts_the_periods_it_skipped():
    period = 0.008
    send_t = [0.0, 0.008, 0.016, 0.040, 0.048, 0.0595]  # 24 ms: 2 skipped; 11.5 ms: under 1.5 periods, none
    assert missed_periods(send_t, period) == 2
    assert missed_periods([0.0], period) == 0


def test_the_floor_loop_wakes_once_per_period_for_the_time_asked():
    out = sleep_floor(0.2, 0.008)
    assert out["cycles"] == 25 and len(out["send_t"]) == 25
    assert np.all(np.diff(out["send_t"]) > 0.004)  # it sleeps: never two wake-ups in one period


@pytest.mark.realtime
def test_the_episode_runs_in_a_real_time_servo_process(start_emulator):
    emu = start_emulator()
    env = make_real_env(emu, safety_limits=CI_LIMITS, servo_process=True)
    try:
        process = env.unwrapped.devices.process
        assert process is not None and process.proc.is_alive()
        assert process.scheduling.startswith(("SCHED_FIFO", "SCHED_OTHER"))  # what the OS allowed, said
        _, info, _ = run_steps(env, make_controller("li2023"), max_steps=20)
        assert info["failure"] is None and info["servo_cycles"] > 100
    finally:
        env.close()
    assert not process.proc.is_alive() and process.proc.exitcode == 0


@pytest.mark.realtime
def test_the_servo_process_stops_the_robot_when_the_agents_process_goes_away(start_emulator):
    emu = start_emulator()
    env = make_real_env(emu, safety_limits=CI_LIMITS, servo_process=True)
    try:
        run_steps(env, make_controller("none"), max_steps=10)
        process = env.unwrapped.devices.process
        assert emu.status()["servo_active"]
        process.conn.close()  # what the child sees when the agent's process dies: the pipe closes
        process.proc.join(10.0)
        assert process.proc.exitcode == 0
        st = emu.status()
        assert st["command_counts"].get("16") == 1 and not st["servo_active"]  # one servoStop, then nothing
    finally:
        process.closed = True
        env.close()


@pytest.mark.realtime
def test_the_loop_runs_in_its_own_process_by_default_and_as_a_thread_on_request(start_emulator):
    emu = start_emulator()
    env = make_real_env(emu, safety_limits=CI_LIMITS)
    try:
        assert env.unwrapped.devices.process is not None
    finally:
        env.close()
    env = make_real_env(emu, safety_limits=CI_LIMITS, servo_process=False)
    try:
        assert env.unwrapped.devices.process is None
        t0 = time.monotonic()
        _, info, _ = run_steps(env, make_controller("li2023"), max_steps=20)
        assert info["failure"] is None and info["servo_cycles"] > 100 and time.monotonic() - t0 < 30.0
    finally:
        env.close()
