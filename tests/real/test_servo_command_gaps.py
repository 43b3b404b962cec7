"""The servo loop's watchdog measures the time between two servo commands as they leave, on a fake clock.

``ur_rtde``'s ``servoL`` first waits for the control program's "ready" and then sends. The first call of a hole
waits for the program to take the watchdog set at reset (on an emulator beside busy processes: ~100 ms); the
robot stands still before it, so that wait is no gap in the stream. A call that blocks mid-stream is one. The
loop runs here on a fake clock (``time`` in :mod:`drillgym.envs.real.servo` replaced), so every gap is exact and
nothing depends on this machine's load.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from drillgym.envs.constants import APPROACH_SPEED_M_S
from drillgym.envs.real import servo as servo_module
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.robot_link import RobotState
from drillgym.envs.real.safety import PROGRAM_PLAYING
from drillgym.envs.real.servo import CellGeometry, ServoLoop
from drillgym.envs.task import APPROACH_START_M, DrillPath

PERIOD_S = 0.008
"""The stream's period on the fake clock (s): 125 Hz."""
CYCLES = 40
"""Cycles the fake link takes before it asks the loop to stop (0.32 s of stream: still on the approach)."""


class FakeClock:
    """``time.monotonic`` / ``perf_counter`` that advance only when the fake link says so (s)."""

    def __init__(self) -> None:
        self.now_s = 100.0

    def monotonic(self) -> float:
        return self.now_s

    perf_counter = monotonic


class FakeLink:
    """A robot that follows every target at once; ``servoL`` call ``k`` (0-based) takes ``call_s.get(k, 0)`` s."""

    dry_run = False
    host = "fake"

    def __init__(self, clock: FakeClock, call_s: dict[int, float]) -> None:
        self.clock, self.call_s = clock, call_s
        self.pose = np.array([0.0, 0.0, -APPROACH_START_M, 0.0, 0.0, 0.0])
        self.calls = 0
        self.loop: ServoLoop | None = None

    def connected(self) -> bool:
        return True

    def state(self) -> RobotState:
        zeros = np.zeros(6)
        return RobotState(
            self.clock.now_s, self.clock.now_s, zeros, self.pose.copy(), self.pose.copy(), 0, PROGRAM_PLAYING
        )

    def init_period(self) -> float:
        return self.clock.now_s

    def wait_period(self, t_cycle: float) -> None:
        self.clock.now_s = max(self.clock.now_s, t_cycle + PERIOD_S)

    def servo_l(self, pose: np.ndarray) -> bool:
        self.clock.now_s += self.call_s.get(self.calls, 0.0)
        self.pose = np.asarray(pose, dtype=float)
        self.calls += 1
        if self.calls >= CYCLES and self.loop is not None:
            self.loop._stop_requested.set()
        return True

    def servo_stop(self) -> bool:
        return True


class FakeFT:
    """A fresh, zero wrench at every read."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock

    def latest(self) -> SimpleNamespace:
        return SimpleNamespace(t_recv_s=self.clock.now_s, wrench=np.zeros(6))


def run_loop(
    monkeypatch: pytest.MonkeyPatch, call_s: dict[int, float], start_late_s: float = 0.0
) -> tuple[ServoLoop, FakeLink, float]:
    """Run the loop on the fake clock, its first cycle ``start_late_s`` after the episode's ``t0``; returns the
    loop, the link and ``t0``."""
    clock = FakeClock()
    t0 = clock.now_s
    clock.now_s += start_late_s
    monkeypatch.setattr(servo_module, "time", SimpleNamespace(monotonic=clock.monotonic, perf_counter=clock.monotonic))
    link = FakeLink(clock, call_s)
    geometry = CellGeometry(np.zeros(3), np.eye(3), 0.005)
    loop = ServoLoop(
        link,  # type: ignore[arg-type]
        FakeFT(clock),  # type: ignore[arg-type]
        np.zeros(6),
        geometry,
        DrillPath(0.005, 0.001),
        SafetyLimits(),
        ServoParams(),
        50.0,
        t0,
    )
    link.loop = loop
    loop._run()
    return loop, link, t0


def test_a_long_first_servo_call_is_no_gap_in_the_stream(monkeypatch):
    """The first call waits 300 ms (three times the 100 ms bar): the stream then runs its cycles, none missed."""
    loop, _, _ = run_loop(monkeypatch, {0: 0.3})
    assert loop.fault is None
    assert loop.stats.cycles == CYCLES and loop.stats.missed_cycles == 0
    assert loop.stats.servo_call_max_s == pytest.approx(0.3)
    assert loop.stats.max_gap_s == pytest.approx(PERIOD_S)


def test_a_servo_call_that_blocks_mid_stream_is_a_watchdog_stop(monkeypatch):
    """Call 10 takes 150 ms: its command leaves 158 ms after the one before (over the 100 ms bar), so the loop
    stops on ``watchdog_cycle`` right after it, having counted the 18 periods the gap spans less one."""
    loop, _, _ = run_loop(monkeypatch, {10: 0.15})
    assert loop.fault is not None and loop.fault.reason == "watchdog_cycle"
    assert loop.fault.message == "158 ms between two servo commands"
    assert loop.stats.cycles == 10  # the blocked command was sent, and nothing after it
    assert loop.stats.missed_cycles == round(0.158 / PERIOD_S) - 1
    assert loop.stats.stop_result == "servoStop True"


def test_a_call_just_under_the_bar_keeps_the_stream_going(monkeypatch):
    """Call 10 takes 90 ms: 98 ms between two commands, under the 100 ms bar; the 11 skipped periods are counted."""
    loop, _, _ = run_loop(monkeypatch, {10: 0.09})
    assert loop.fault is None and loop.stats.cycles == CYCLES
    assert loop.stats.missed_cycles == round(0.098 / PERIOD_S) - 1
    assert loop.stats.max_gap_s == pytest.approx(0.098)


def _approach_depth_m(elapsed_s: float) -> float:
    """The nominal path's depth (m, task frame) ``elapsed_s`` into the approach (docs/physics.md: 2 mm/s)."""
    return -APPROACH_START_M + APPROACH_SPEED_M_S * elapsed_s


@pytest.mark.parametrize("start_late_s", [0.0, 0.124])
def test_the_path_runs_on_the_episode_clock_when_the_stream_starts_late(monkeypatch, start_late_s):
    """The stream's first cycle comes 124 ms after the episode's t0 (a loaded servo process's start): the path is
    where the episode clock says at every cycle, as in the sim, where step k's path is k control periods in. A path
    counted from the first cycle lagged the agent's steps by that delay and moved li2023's contact by 2.5 steps."""
    loop, link, t0 = run_loop(monkeypatch, {}, start_late_s)
    assert loop.fault is None and loop.stats.cycles == CYCLES
    expected = [_approach_depth_m(t) for t in loop.history_t]
    np.testing.assert_allclose(loop.history_s, expected, rtol=0, atol=1e-12)
    assert loop.history_t[0] == pytest.approx(start_late_s)
    assert link.pose[2] == pytest.approx(_approach_depth_m(link.clock.now_s - t0 - PERIOD_S), abs=1e-12)


def test_after_a_late_cycle_the_target_catches_up_with_the_path_at_the_speed_limit(monkeypatch):
    """Call 10 takes 90 ms: the path moves on with the clock (0.18 mm at 2 mm/s), the target follows it at no more
    than ``max_tcp_speed_m_s`` over 3 servo periods per cycle, and is back on the path by the next cycle."""
    poses: list[np.ndarray] = []
    original = FakeLink.servo_l

    def recording(self: FakeLink, pose: np.ndarray) -> bool:
        poses.append(np.asarray(pose[:3], dtype=float))
        return original(self, pose)

    monkeypatch.setattr(FakeLink, "servo_l", recording)
    loop, _, _ = run_loop(monkeypatch, {10: 0.09})
    steps = np.linalg.norm(np.diff(np.array(poses), axis=0), axis=1)
    assert steps.max() <= SafetyLimits().max_tcp_speed_m_s * 3 * PERIOD_S + 1e-12
    assert steps[10] == pytest.approx(APPROACH_SPEED_M_S * 0.09, rel=1e-9)  # the catch-up, in one cycle
    np.testing.assert_allclose(loop.history_s, [_approach_depth_m(t) for t in loop.history_t], atol=1e-12)
