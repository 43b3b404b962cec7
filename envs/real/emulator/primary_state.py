"""What a CB3 sends on its client interfaces: robot state on 30001 / 30002 (10 Hz), the real-time packet on 30003.

Layouts follow UR's "Client Interface" documentation for CB3 software 3.x (the ``Client_Interface_V3.x`` Excel
sheet, tabs "Primary and secondary" and "RealTime"; the same tables as docs.universal-robots.com's
``primary-secondary-guide`` and ``realtime-guide``), read against the parsers that rely on them: UR's C++ client
library (``ur_client_library/src/primary/robot_state/*.cpp``: the sub-package fields and the sizes its strict mode
checks) and python-urx 0.11 (``urx/ursecmon.py``: a robot mode sub-package of 46 bytes means software >= 3.2;
``urx/urrtmon.py``). Everything is big-endian. Only the values are the emulator's.

**Robot state message** (``int32 size, uint8 type = 16``, then sub-packages ``int32 size, uint8 type, fields``), in
the order a controller sends them (UR's client library test data, a URSim package):

===  ======================  =====  ==================================================================================
type sub-package             bytes  fields (units: rad, rad/s, m, m/s, N, A, V, °C, s unless said)
===  ======================  =====  ==================================================================================
0    robot mode data         46     timestamp (uint64, µs since start), 7 bools (real robot connected, enabled, power
                                    on, emergency stopped, protective stopped, program running, program paused),
                                    robot mode, control mode (uint8), target speed fraction, speed scaling, speed
                                    fraction limit (double)
1    joint data              251    per joint: q actual, q target, qd actual (double), I, V, T motor, T micro (float),
                                    joint mode (uint8)
4    cartesian info          101    TCP pose (x, y, z, rx, ry, rz: base frame, rotation vector), TCP offset (flange)
5    kinematics info         225    checksums (6 uint32), DH θ, a, d, α (6 doubles each), calibration status (uint32;
                                    the documentation says uchar, the controller sends four bytes)
9    calibration data        53     6 doubles (F/T calibration, UR software only)
3    masterboard data        75     digital in / out bits (int32), analog ranges, inputs, domains, outputs, board
                                    temperature, 48 V, robot current, I/O current, safety mode, reduced mode, Euromap67
                                    installed (0: none of its fields follow), UR-only uint32, operational mode
                                    selector, three-position enabling device, UR-only uint8
2    tool data               37     analog ranges (char), analog inputs (double), 48 V (float), output voltage
                                    (uint8), current, temperature (float), tool mode (uint8)
6    configuration data      445    joint min/max (per joint), max speed/acceleration (per joint), default joint and
                                    tool speed and acceleration, equivalent radius, DH a, d, α, θ, masterboard version,
                                    controller box type, robot type (1: UR5), robot subtype (int32)
7    force mode data         61     wrench (6 doubles), robot dexterity
8    additional info         8      teach (freedrive) button pressed, enabled, I/O-enabled freedrive (bools)
===  ======================  =====  ==================================================================================

**Version message** (``int32 size, uint8 type = 20, uint64 timestamp, int8 source, uint8 robot message type = 3``,
then ``int8 name length, name, uint8 major, uint8 minor, int32 bugfix, int32 build, build date``): sent once when a
client connects to 30001 or 30002.

**Real-time packet** (30003, every 8 ms controller cycle): 1108 bytes, ``int32 size`` then 138 doubles: time; q, qd,
qdd, I, M target; q, qd, I actual, I control; tool vector (TCP pose) actual, TCP speed actual, TCP force; tool vector
target, TCP speed target; digital input bits; motor temperatures; controller timer, test value, robot mode; joint
modes; safety mode; 6 UR-only; tool accelerometer (3); 6 UR-only; speed scaling, linear momentum norm, 2 UR-only,
V main, V robot, I robot; joint voltages (6); digital output bits; program state; elbow position (3), elbow velocity
(3) -- the CB3 layout from software 3.5 on (3.2-3.4 ended after the program state, at 1060 bytes).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence

ROBOT_STATE = 16
ROBOT_MESSAGE = 20
VERSION_MESSAGE = 3
MESSAGE_SOURCE = -2
"""``source`` of a version message, as URSim's in UR's client library test data."""
CONTROLLER_VERSION = (3, 15, 7, 106331)
"""PolyScope 3.15.7 (the dashboard's and RTDE's answer): major, minor, bugfix, build."""
BUILD_DATE = "07-09-2022, 00:00:00"
PROJECT_NAME = b"URControl"
RUNTIME_PLAYING, RUNTIME_PAUSED = 2, 4
ROBOT_MODE_POWER_OFF = 3
SAFETY_MODE_PROTECTIVE_STOP = 3
CONTROL_MODE_POSITION = 0
UR5_ROBOT_TYPE = 1
"""``robotType`` of a UR5 (UR's client library, ``urcl::RobotType``)."""

UR5_DH_A_M = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
UR5_DH_D_M = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
UR5_DH_ALPHA_RAD = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
UR5_DH_THETA_RAD = (0.0,) * 6
"""UR's nominal UR5 Denavit-Hartenberg parameters (m, rad); an uncalibrated arm (θ offsets 0)."""
JOINT_LIMIT_RAD = 2 * math.pi
JOINT_MAX_SPEED_RAD_S = math.pi
JOINT_MAX_ACCELERATION_RAD_S2 = 40.0
DEFAULTS = (1.05, 1.4, 0.25, 1.2, 0.61)
"""PolyScope's default joint speed (rad/s) and acceleration (rad/s²), tool speed (m/s) and acceleration (m/s²), and
equivalent radius (m)."""

_HEAD = struct.Struct(">iB")
_ROBOT_MODE = struct.Struct(">iBQ???????BBddd")
_JOINT = struct.Struct(">dddffffB")
_CARTESIAN = struct.Struct(">iB12d")
_KINEMATICS = struct.Struct(">iB6I24dI")
_CALIBRATION = struct.Struct(">iB6d")
_MASTERBOARD = struct.Struct(">iBiiBBddbbddffffBBBIBBB")
_TOOL = struct.Struct(">iBbbddfBffB")
_CONFIGURATION = struct.Struct(">iB12d12d5d24d4i")
_FORCE_MODE = struct.Struct(">iB7d")
_ADDITIONAL = struct.Struct(">iB???")
_REALTIME = struct.Struct(">i138d")
REALTIME_PACKET_BYTES = _REALTIME.size
"""1108: the CB3 real-time packet from software 3.5 on."""


def _v(state: Mapping[str, object], name: str) -> Sequence[float]:
    """A vector of the state as it is (``struct`` packs ints and floats as doubles alike)."""
    return state[name]  # type: ignore[return-value]


def _f(state: Mapping[str, object], name: str) -> float:
    return state[name]  # type: ignore[return-value]


def _i(state: Mapping[str, object], name: str) -> int:
    return int(state[name])  # type: ignore[call-overload]


def version_message(t_s: float) -> bytes:
    """The version message a CB3 sends a new 30001 / 30002 client (PolyScope :data:`CONTROLLER_VERSION`)."""
    major, minor, bugfix, build = CONTROLLER_VERSION
    body = (
        struct.pack(">QbBb", int(t_s * 1e6), MESSAGE_SOURCE, VERSION_MESSAGE, len(PROJECT_NAME))
        + PROJECT_NAME
        + struct.pack(">BBii", major, minor, bugfix, build)
        + BUILD_DATE.encode()
    )
    return _HEAD.pack(_HEAD.size + len(body), ROBOT_MESSAGE) + body


def robot_state_message(state: Mapping[str, object]) -> bytes:
    """One robot state message (type 16) from a controller state (the RTDE output names and units).

    ``state`` holds what :func:`drillgym.envs.real.emulator.state.controller_state` returns: ``timestamp`` (s),
    joint values (rad, rad/s), TCP pose and speed (m, rad, base frame), ``tcp_offset`` (flange frame), modes and
    I/O. Program running / paused come from ``runtime_state``, power from ``robot_mode``, the protective stop from
    ``safety_mode``.
    """
    subs = [
        _robot_mode(state),
        _joints(state),
        _CARTESIAN.pack(_CARTESIAN.size, 4, *_v(state, "actual_TCP_pose"), *_v(state, "tcp_offset")),
        _KINEMATICS.pack(
            _KINEMATICS.size, 5, *([0] * 6), *UR5_DH_THETA_RAD, *UR5_DH_A_M, *UR5_DH_D_M, *UR5_DH_ALPHA_RAD, 0
        ),
        _CALIBRATION.pack(_CALIBRATION.size, 9, *([0.0] * 6)),
        _masterboard(state),
        _tool(state),
        _configuration(),
        _FORCE_MODE.pack(_FORCE_MODE.size, 7, *([0.0] * 6), 0.0),
        _ADDITIONAL.pack(_ADDITIONAL.size, 8, False, False, False),
    ]
    body = b"".join(subs)
    return _HEAD.pack(_HEAD.size + len(body), ROBOT_STATE) + body


def _robot_mode(state: Mapping[str, object]) -> bytes:
    runtime = _i(state, "runtime_state")
    mode = _i(state, "robot_mode")
    return _ROBOT_MODE.pack(
        _ROBOT_MODE.size,
        0,
        int(_f(state, "timestamp") * 1e6),
        True,  # real robot connected
        True,  # real robot enabled (not simulated)
        mode != ROBOT_MODE_POWER_OFF,
        False,  # emergency stopped
        _i(state, "safety_mode") == SAFETY_MODE_PROTECTIVE_STOP,
        runtime == RUNTIME_PLAYING,
        runtime == RUNTIME_PAUSED,
        mode,
        CONTROL_MODE_POSITION,
        _f(state, "target_speed_fraction"),
        _f(state, "speed_scaling"),
        1.0,  # target speed fraction limit
    )


def _joints(state: Mapping[str, object]) -> bytes:
    q, q_target, qd = _v(state, "actual_q"), _v(state, "target_q"), _v(state, "actual_qd")
    current, voltage = _v(state, "actual_current"), _v(state, "actual_joint_voltage")
    temperature = _v(state, "joint_temperatures")
    modes: Sequence[int] = state["joint_mode"]  # type: ignore[assignment]
    parts = [
        _JOINT.pack(q[j], q_target[j], qd[j], current[j], voltage[j], temperature[j], 0.0, int(modes[j]))
        for j in range(6)
    ]
    body = b"".join(parts)
    return _HEAD.pack(_HEAD.size + len(body), 1) + body


def _masterboard(state: Mapping[str, object]) -> bytes:
    return _MASTERBOARD.pack(
        _MASTERBOARD.size,
        3,
        _i(state, "actual_digital_input_bits") & 0x7FFFFFFF,
        _i(state, "actual_digital_output_bits") & 0x7FFFFFFF,
        0,  # analog input ranges
        0,
        _f(state, "standard_analog_input0"),
        _f(state, "standard_analog_input1"),
        0,  # analog output domains (current)
        0,
        _f(state, "standard_analog_output0"),
        _f(state, "standard_analog_output1"),
        35.0,  # masterboard temperature
        _f(state, "actual_robot_voltage"),
        _f(state, "actual_robot_current"),
        _f(state, "io_current"),
        _i(state, "safety_mode"),
        False,  # in reduced mode
        0,  # Euromap67 interface not installed
        0,  # UR software only
        0,  # operational mode selector input
        False,  # three-position enabling device input
        0,  # UR software only
    )


def _tool(state: Mapping[str, object]) -> bytes:
    return _TOOL.pack(
        _TOOL.size,
        2,
        0,
        0,
        _f(state, "tool_analog_input0"),
        _f(state, "tool_analog_input1"),
        _f(state, "actual_main_voltage"),
        _i(state, "tool_output_voltage") & 0xFF,
        _f(state, "tool_output_current"),
        _f(state, "tool_temperature"),
        _i(state, "tool_mode") & 0xFF,
    )


def _configuration() -> bytes:
    limits = [v for _ in range(6) for v in (-JOINT_LIMIT_RAD, JOINT_LIMIT_RAD)]
    motion = [v for _ in range(6) for v in (JOINT_MAX_SPEED_RAD_S, JOINT_MAX_ACCELERATION_RAD_S2)]
    dh = (*UR5_DH_A_M, *UR5_DH_D_M, *UR5_DH_ALPHA_RAD, *UR5_DH_THETA_RAD)
    return _CONFIGURATION.pack(_CONFIGURATION.size, 6, *limits, *motion, *DEFAULTS, *dh, 3, 4, UR5_ROBOT_TYPE, 1)


def realtime_packet(state: Mapping[str, object]) -> bytes:
    """The 1108-byte real-time packet of one controller cycle (values as in :func:`robot_state_message`)."""
    zero6 = (0.0,) * 6
    values = (
        _f(state, "timestamp"),
        *_v(state, "target_q"),
        *_v(state, "target_qd"),
        *_v(state, "target_qdd"),
        *_v(state, "target_current"),
        *_v(state, "target_moment"),
        *_v(state, "actual_q"),
        *_v(state, "actual_qd"),
        *_v(state, "actual_current"),
        *_v(state, "joint_control_output"),
        *_v(state, "actual_TCP_pose"),
        *_v(state, "actual_TCP_speed"),
        *_v(state, "actual_TCP_force"),
        *_v(state, "target_TCP_pose"),
        *_v(state, "target_TCP_speed"),
        float(_i(state, "actual_digital_input_bits")),
        *_v(state, "joint_temperatures"),
        _f(state, "actual_execution_time"),
        0.0,  # test value (UR software only)
        float(_i(state, "robot_mode")),
        *_v(state, "joint_mode"),
        float(_i(state, "safety_mode")),
        *zero6,
        *_v(state, "actual_tool_accelerometer"),
        *zero6,
        _f(state, "speed_scaling"),
        _f(state, "actual_momentum"),
        0.0,
        0.0,
        _f(state, "actual_main_voltage"),
        _f(state, "actual_robot_voltage"),
        _f(state, "actual_robot_current"),
        *_v(state, "actual_joint_voltage"),
        float(_i(state, "actual_digital_output_bits")),
        float(_i(state, "runtime_state")),
        *_v(state, "elbow_position"),
        *_v(state, "elbow_velocity"),
    )
    return _REALTIME.pack(_REALTIME.size, *values)
