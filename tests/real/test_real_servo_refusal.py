"""A refused servoL is reported with its root cause: the safety stop the next RTDE states show (no network)."""

from types import SimpleNamespace

import numpy as np

from drillgym.envs.real.robot_link import LinkError, RobotState
from drillgym.envs.real.servo import ServoLoop

PROTECTIVE_STOP_BITS = 1 << 2


def _state(bits: int) -> RobotState:
    zeros = np.zeros(6)
    return RobotState(0.0, 1.0, zeros, zeros, zeros, bits, 2)


class _Link:
    """States as a real RTDE receiver gives them: the stop bit shows up some reads after the refusal."""

    def __init__(self, bits_per_read):
        self.bits = list(bits_per_read)

    def state(self):
        if not self.bits:
            raise LinkError("gone")
        return _state(self.bits.pop(0) if len(self.bits) > 1 else self.bits[0])


def _cause(link):
    loop = SimpleNamespace(link=link, state=None)
    return ServoLoop._refusal_cause(loop, 1.5)  # type: ignore[arg-type]


def test_a_protective_stop_seen_after_the_refusal_is_the_reported_cause():
    fault = _cause(_Link([0, 0, PROTECTIVE_STOP_BITS]))
    assert fault.reason == "protective_stop" and "servoL was refused" in fault.message and fault.t_s == 1.5


def test_a_refusal_without_a_safety_stop_stays_servo_refused():
    assert _cause(_Link([0])).reason == "servo_refused"


def test_a_lost_link_while_looking_for_the_cause_reports_the_refusal():
    assert _cause(_Link([])).reason == "servo_refused"
