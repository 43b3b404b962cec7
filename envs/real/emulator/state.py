"""The controller state an RTDE output package reports, from the emulated cell and program.

Registers are read live by the connection; everything else is here. Modes and bits follow UR's RTDE guide:
``robot_mode`` 3 POWER_OFF, 5 IDLE, 7 RUNNING; ``safety_mode`` 1 NORMAL, 3 PROTECTIVE_STOP; ``robot_status_bits``
bit 0 power on, bit 1 program running; ``safety_status_bits`` bit 0 normal mode, bit 2 protective stopped;
``safety_status`` the safety status type of UR's Client Interface (1 NORMAL, 3 PROTECTIVE_STOP), equal to
``safety_mode`` here (the emulator has no reduced mode, safeguard or emergency stop).

Targets: ``target_q`` is the joint position of the servo target (:meth:`EmulatedCell.target_q_rad`: it leads
``actual_q`` while the arm moves and equals it at rest); ``target_TCP_pose`` the newest ``servoL`` pose while a servo
stream runs, else the pose of the servo target (the interpolated point of a ``moveL``, the held pose at rest).

Motion: ``actual_qd`` / ``target_qd`` and ``actual_TCP_speed`` / ``target_TCP_speed`` are the joint and TCP
velocities over the last 10 ms physics step (rad/s; m/s, the angular part 0: the orientation is held);
``speed_scaling`` and ``target_speed_fraction`` the speed slider; ``actual_digital_output_bits`` the outputs set
over RTDE or by a script; ``tcp_offset`` the configured TCP. Not emulated (constant, listed in
:data:`drillgym.envs.real.emulator.rtde_protocol.NOT_EMULATED`): currents, torques, temperatures, voltages, accelerations, analog I/O, tool I/O.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from drillgym.envs.real.poses import matrix_to_pose

if TYPE_CHECKING:
    from drillgym.envs.real.emulator.host import EmulatorHost

ROBOT_MODE_RUNNING = 7
ROBOT_MODES = {"POWER_OFF": 3, "IDLE": 5, "RUNNING": 7}
JOINT_MODE_RUNNING = 253
SAFETY_MODE_NORMAL = 1
SAFETY_MODE_PROTECTIVE_STOP = 3
SAFETY_BIT_NORMAL = 1 << 0
SAFETY_BIT_PROTECTIVE_STOP = 1 << 2
STATUS_BIT_POWER_ON = 1 << 0
STATUS_BIT_PROGRAM_RUNNING = 1 << 1

_ZERO6 = (0.0,) * 6
_STATIC: dict[str, object] = {
    **dict.fromkeys(
        ("target_qdd", "target_current", "target_moment", "actual_current", "joint_control_output"), _ZERO6
    ),
    "actual_digital_input_bits": 0,
    "actual_digital_output_bits": 0,
    "joint_temperatures": (30.0,) * 6,
    "actual_execution_time": 0.4,
    "robot_mode": ROBOT_MODE_RUNNING,
    "joint_mode": (JOINT_MODE_RUNNING,) * 6,
    "actual_tool_accelerometer": (0.0, 0.0, -9.81),
    "speed_scaling": 1.0,
    "target_speed_fraction": 1.0,
    "actual_momentum": 0.0,
    "actual_main_voltage": 48.0,
    "actual_robot_voltage": 48.0,
    "actual_robot_current": 0.8,
    "actual_joint_voltage": (47.5,) * 6,
    "elbow_position": (0.0, 0.0, 0.0),
    "elbow_velocity": (0.0, 0.0, 0.0),
    "analog_io_types": 0,
    **dict.fromkeys(("standard_analog_input0", "standard_analog_input1"), 0.0),
    **dict.fromkeys(("standard_analog_output0", "standard_analog_output1", "io_current"), 0.0),
    "tool_mode": 0,
    "tool_analog_input_types": 0,
    **dict.fromkeys(("tool_analog_input0", "tool_analog_input1", "tool_output_current"), 0.0),
    "tool_output_voltage": 0,
    "tool_temperature": 32.0,
    "tcp_force_scalar": 0.0,
    "output_bit_registers0_to_31": 0,
    "output_bit_registers32_to_63": 0,
    "payload": 1.2,
    "payload_cog": (0.0, 0.0, 0.06),
    "payload_inertia": _ZERO6,
    "joint_position_deviation_ratio": 0.0,
}


def controller_state(emulator: EmulatorHost, t_s: float) -> dict[str, object]:
    """Values of every non-register output at emulator time ``t_s``."""
    world, program = emulator.world, emulator.program
    q = tuple(np.asarray(world.cell.q_motor_rad, dtype=float).tolist())
    tcp = tuple(np.asarray(world.tcp_pose(), dtype=float).tolist())
    qd = tuple(world.qd_rad_s.tolist())
    tcp_speed = (*world.tcp_velocity_base_m_s.tolist(), 0.0, 0.0, 0.0)
    halted = world.halted
    mode = ROBOT_MODES[program.robot_mode]
    state = dict(_STATIC)
    state.update(
        timestamp=t_s,
        actual_q=q,
        target_q=tuple(world.target_q_rad().tolist()),
        actual_TCP_pose=tcp,
        target_TCP_pose=tuple(program.last_servo_pose)
        if program.servo_active and program.last_servo_pose
        else tuple(np.asarray(world.tcp_pose(world.target_task), dtype=float).tolist()),
        actual_TCP_force=tuple(world.tcp_force_base().tolist()),
        safety_mode=SAFETY_MODE_PROTECTIVE_STOP if halted else SAFETY_MODE_NORMAL,
        safety_status_bits=SAFETY_BIT_PROTECTIVE_STOP if halted else SAFETY_BIT_NORMAL,
        safety_status=SAFETY_MODE_PROTECTIVE_STOP if halted else SAFETY_MODE_NORMAL,
        runtime_state=int(program.runtime_state),
        robot_mode=mode,
        robot_status_bits=(STATUS_BIT_POWER_ON if mode != ROBOT_MODES["POWER_OFF"] else 0)
        | (STATUS_BIT_PROGRAM_RUNNING if program.running else 0),
        actual_qd=qd,
        target_qd=qd,
        actual_TCP_speed=tcp_speed,
        target_TCP_speed=tcp_speed,
        speed_scaling=program.speed_fraction,
        target_speed_fraction=program.speed_fraction,
        actual_digital_output_bits=program.digital_out_bits,
        tcp_offset=tuple(matrix_to_pose(world.T_tcp_cfg).tolist()),
    )
    return state
