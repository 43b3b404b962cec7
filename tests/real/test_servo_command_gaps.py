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


def run_loop(monkeypatch: pytest.MonkeyPatch, call_s: dict[int, float]) -> ServoLoop:
    clock = FakeClock()
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
        clock.now_s,
    )
    link.loop = loop
    loop._run()
    return loop


def test_a_long_first_servo_call_is_no_gap_in_the_stream(monkeypatch):
    """The first call waits 300 ms (three times the 100 ms bar): the stream then runs its cycles, none missed."""
    loop = run_loop(monkeypatch, {0: 0.3})
    assert loop.fault is None
    assert loop.stats.cycles == CYCLES and loop.stats.missed_cycles == 0
    assert loop.stats.servo_call_max_s == pytest.approx(0.3)
    assert loop.stats.max_gap_s == pytest.approx(PERIOD_S)


def test_a_servo_call_that_blocks_mid_stream_is_a_watchdog_stop(monkeypatch):
    """Call 10 takes 150 ms: its command leaves 158 ms after the one before (over the 100 ms bar), so the loop
    stops on ``watchdog_cycle`` right after it, having counted the 18 periods the gap spans less one."""
    loop = run_loop(monkeypatch, {10: 0.15})
    assert loop.fault is not None and loop.fault.reason == "watchdog_cycle"
    assert loop.fault.message == "158 ms between two servo commands"
    assert loop.stats.cycles == 10  # the blocked command was sent, and nothing after it
    assert loop.stats.missed_cycles == round(0.158 / PERIOD_S) - 1
    assert loop.stats.stop_result == "servoStop True"


def test_a_call_just_under_the_bar_keeps_the_stream_going(monkeypatch):
    """Call 10 takes 90 ms: 98 ms between two commands, under the 100 ms bar; the 11 skipped periods are counted."""
    loop = run_loop(monkeypatch, {10: 0.09})
    assert loop.fault is None and loop.stats.cycles == CYCLES
    assert loop.stats.missed_cycles == round(0.098 / PERIOD_S) - 1
    assert loop.stats.max_gap_s == pytest.approx(0.098)
