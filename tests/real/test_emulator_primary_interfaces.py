"""The client interfaces 30001 / 30002 / 30003 send state as a CB3 does; each test names the source it follows.

Sources: UR's "Client Interface" documentation for CB3 software 3.x (primary/secondary: a version message on connect,
then a robot state message, type 16, of sub-packages at 10 Hz; real-time: a 1108-byte packet every 8 ms cycle from
software 3.5 on), UR's C++ client library (``ur_client_library/src/primary/robot_state/*.cpp``: the fields it parses
and, in strict mode, the sub-package sizes it requires) and python-urx 0.11 (``urx/ursecmon.py``, ``urx/urrtmon.py``)
used unmodified (``.venv/bin/pip install urx``).
"""

import socket
import struct
import time

import numpy as np
import pytest
import rtde_control
import rtde_receive
from real_cell import wait_until

from drillgym.envs.real.emulator import primary_state as ps
from drillgym.envs.real.emulator.config import PRIMARY_PORT, SCRIPT_PORT, SECONDARY_PORT
from drillgym.envs.real.emulator.state_streams import STATE_PERIOD_S

CYCLE_S = 0.008
LIB_SUB_PACKAGES = {
    0: struct.Struct(">iBQ???????BBddd"),
    5: struct.Struct(">iB6I24dI"),
    6: struct.Struct(">iB12d12d5d24d4i"),
    3: struct.Struct(">iBIIBBddbbddffffBBBIBBB"),
}
"""Sub-packages UR's client library parses field by field (robot mode, kinematics, configuration, masterboard without
Euromap67), in the order of its ``parseWith``; strict mode requires each to be consumed exactly."""
DOCUMENTED_SIZES = {0: 46, 1: 251, 4: 101, 5: 225, 9: 53, 3: 75, 2: 37, 6: 445, 7: 61, 8: 8}
"""Sub-package sizes of the Client Interface (CB3 3.x; a 46-byte robot mode sub-package is what urx takes for 3.2+)."""


def _recv_exact(sock, n):
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        assert chunk, "connection closed"
        data += chunk
    return data


def _read_message(sock):
    head = _recv_exact(sock, 5)
    size, kind = struct.unpack(">iB", head)
    return kind, head + _recv_exact(sock, size - 5)


def _sub_packages(message):
    subs, pos = [], 5
    while pos < len(message):
        size, kind = struct.unpack_from(">iB", message, pos)
        subs.append((kind, message[pos : pos + size]))
        pos += size
    assert pos == len(message)
    return subs


def _connect(host, port):
    s = socket.create_connection((host, port), timeout=2.0)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def test_state_packets_have_the_documented_sizes():
    """Client Interface CB3 3.x: sub-package sizes as listed (no emulator needed); the whole message stays under the
    2000 bytes python-urx's packet finder accepts; the real-time packet is 1108 bytes with its size in front."""
    state = _resting_state()
    message = ps.robot_state_message(state)
    sizes = {kind: len(body) for kind, body in _sub_packages(message)}
    assert sizes == DOCUMENTED_SIZES
    assert struct.unpack_from(">iB", message) == (len(message), ps.ROBOT_STATE) and len(message) <= 2000
    packet = ps.realtime_packet(state)
    assert len(packet) == 1108 and struct.unpack_from(">i", packet)[0] == 1108


def _resting_state():
    from drillgym.envs.real.emulator import state as st

    q = (0.1, -1.5, 2.0, -2.0, -1.57, 0.1)
    return {
        **st._STATIC,
        "timestamp": 1.5,
        "actual_q": q,
        "target_q": q,
        "actual_qd": (0.0,) * 6,
        "target_qd": (0.0,) * 6,
        "actual_TCP_pose": (-0.45, -0.11, 0.11, 2.2, 2.2, 0.0),
        "target_TCP_pose": (-0.45, -0.11, 0.11, 2.2, 2.2, 0.0),
        "actual_TCP_speed": (0.0,) * 6,
        "target_TCP_speed": (0.0,) * 6,
        "actual_TCP_force": (0.0,) * 6,
        "safety_mode": 1,
        "safety_status_bits": 1,
        "runtime_state": 1,
        "robot_mode": 7,
        "tcp_offset": (0.0, 0.0, 0.1479, 0.0, 0.0, 0.0),
    }


@pytest.mark.realtime
@pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning")  # urx 0.11's threads use Condition.notifyAll
def test_urx_state_reader_sees_joints_pose_and_modes(start_emulator):
    """python-urx 0.11 unmodified: ``URRobot`` waits at most 0.5 s for a state packet on 30002 (``ursecmon.wait``) and
    reads joint data, cartesian info and robot mode from it, and the real-time packet on 30003 (``urrtmon``: q actual at
    values 31-36, q target at 1-6). They must agree with RTDE's values for the same resting arm, to float precision
    (1e-9: the same numbers packed as doubles). ``urx.Robot.getl`` needs math3d < 4 (it calls ``PoseVector.tolist``),
    so the pose is read through ``URRobot.getl``, which urx's ``Robot`` wraps."""
    urx_urrobot = pytest.importorskip("urx.urrobot")
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_q", "actual_TCP_pose", "robot_mode"])
    robot = urx_urrobot.URRobot(emu.host, use_rt=True)
    try:
        np.testing.assert_allclose(robot.getj(), r.getActualQ(), atol=1e-9)
        np.testing.assert_allclose(robot.getl(), r.getActualTCPPose(), atol=1e-9)
        assert robot.is_running() and not robot.is_program_running()  # robot mode RUNNING (7), no program yet
        mode = robot.secmon.get_all_data()["RobotModeData"]
        assert mode["size"] == 46 and mode["robotMode"] == 7 and mode["isPowerOnRobot"]
        assert robot.secmon.get_cartesian_info()["tcpOffsetZ"] == pytest.approx(0.1479, abs=1e-9)
        np.testing.assert_allclose(robot.rtmon.q_actual(wait=True), r.getActualQ(), atol=1e-9)
        np.testing.assert_allclose(robot.rtmon.q_target(), r.getActualQ(), atol=1e-9)  # at rest: target = actual
    finally:
        robot.close()
        r.disconnect()


@pytest.mark.realtime
@pytest.mark.parametrize("port", [PRIMARY_PORT, SECONDARY_PORT])
def test_primary_and_secondary_send_the_version_then_robot_state_at_10_hz(start_emulator, port):
    """Client Interface: a client of 30001 / 30002 gets the version message (type 20, robot message type 3: URControl
    3.15, the emulated PolyScope) and then robot state messages at 10 Hz. The messages ride on the 8 ms controller
    cycle, so consecutive robot-mode timestamps (µs) are 96 or 104 ms apart and ten of them span 1 s within one cycle;
    reading promptly, none is skipped."""
    emu = start_emulator()
    with _connect(emu.host, port) as s:
        kind, message = _read_message(s)
        assert kind == ps.ROBOT_MESSAGE and message[14] == ps.VERSION_MESSAGE  # after size, type, timestamp, source
        name_len = message[15]
        assert message[16 : 16 + name_len] == b"URControl"
        assert tuple(message[16 + name_len : 18 + name_len]) == (3, 15)
        stamps = []
        while len(stamps) < 11:
            kind, message = _read_message(s)
            assert kind == ps.ROBOT_STATE
            subs = dict(_sub_packages(message))
            stamps.append(struct.unpack_from(">Q", subs[0], 5)[0] * 1e-6)
    steps = np.diff(stamps)
    assert np.all((steps > STATE_PERIOD_S - CYCLE_S - 1e-6) & (steps < STATE_PERIOD_S + CYCLE_S + 1e-6)), steps
    assert stamps[-1] - stamps[0] == pytest.approx(10 * STATE_PERIOD_S, abs=CYCLE_S + 1e-6)


@pytest.mark.realtime
def test_robot_state_parses_in_ur_client_library_strict_mode(start_emulator):
    """UR's C++ client library (``PrimaryParser`` with ``setStrictMode(true)``): every sub-package it parses field by
    field is consumed exactly, and its values are the emulator's: robot mode RUNNING with power on, the UR5 DH
    parameters in kinematics info and configuration data, robot type 1 (UR5), masterboard safety mode NORMAL. A
    protective stop (the control port's fault) shows in the next messages as ``isProtectiveStopped`` and safety
    mode 3 (within 1 s: ten messages)."""
    emu = start_emulator()
    with _connect(emu.host, PRIMARY_PORT) as s:
        _read_message(s)  # version
        _, message = _read_message(s)
        subs = dict(_sub_packages(message))
        fields = {kind: LIB_SUB_PACKAGES[kind].unpack(subs[kind]) for kind in LIB_SUB_PACKAGES}
        mode = fields[0]
        assert mode[3:6] == (True, True, True) and mode[10] == 7  # connected, enabled, power on; RUNNING
        kin = fields[5]
        np.testing.assert_allclose(kin[14:20], ps.UR5_DH_A_M)  # after size, type, 6 checksums, 6 theta
        config = fields[6]
        assert config[-2] == ps.UR5_ROBOT_TYPE
        np.testing.assert_allclose(config[2 + 29 : 2 + 35], ps.UR5_DH_A_M)  # 24 limits + 5 defaults, then DH a
        assert fields[3][16] == 1  # masterboard safety mode NORMAL
        emu.fault("protective_stop")

        def stopped():
            _, msg = _read_message(s)
            sub = dict(_sub_packages(msg))
            return LIB_SUB_PACKAGES[0].unpack(sub[0])[7] and LIB_SUB_PACKAGES[3].unpack(sub[3])[16] == 3

        assert wait_until(stopped, timeout_s=1.5, poll_s=0.0)


@pytest.mark.realtime
def test_realtime_interface_sends_the_1108_byte_packet_every_cycle(start_emulator):
    """Client Interface, RealTime (CB3 3.5+): 1108 bytes with the size first, one packet per 8 ms controller cycle;
    the packet's time field is the controller's, so consecutive packets read promptly are 8 ms apart (median: a late
    loop turn may make one step larger, never smaller) and their values are RTDE's (robot mode 7, safety mode 1,
    q actual to float precision, 1e-9: the same doubles)."""
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_q"])
    try:
        with _connect(emu.host, SCRIPT_PORT) as s:
            packets = [_recv_exact(s, 1108) for _ in range(60)]
        values = [struct.unpack(">i138d", p) for p in packets]
        assert all(v[0] == 1108 for v in values)
        steps = np.diff([v[1] for v in values])
        assert np.median(steps) == pytest.approx(CYCLE_S, abs=1e-9) and steps.min() > CYCLE_S - 1e-9
        last = values[-1][1:]
        assert last[94] == 7 and last[101] == 1  # robot mode, safety mode
        np.testing.assert_allclose(last[31:37], r.getActualQ(), atol=1e-9)
    finally:
        r.disconnect()


@pytest.mark.realtime
def test_target_joint_values_lead_the_actual_ones_while_the_arm_moves(start_emulator):
    """Client Interface: ``q target`` is the target joint position, ``q actual`` the measured one; they differ while
    the arm follows a motion and agree at rest. A 4 mm ``moveL`` at 10 mm/s (ur_rtde, asynchronous) trails its target
    by about speed x servo time constant (10 mm/s x 20 ms = 0.2 mm, ~4e-4 rad at the joints): the largest joint
    difference seen on 30003 while moving (q target at values 1-6, q actual at 31-36) must exceed 5e-5 rad (an eighth
    of that). At rest, 0.5 s (25 servo time constants) after the move arrived, the two agree within 1e-7 rad, on
    30003 and in the joint data of 30002's robot state."""
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_TCP_pose", "actual_q"])
    try:
        pose = list(r.getActualTCPPose())
        pose[2] += 0.004
        with _connect(emu.host, SCRIPT_PORT) as rt:
            assert c.moveL(pose, 0.01, 1.2, True)
            gaps = []
            while len(gaps) < 40:
                v = struct.unpack(">i138d", _recv_exact(rt, 1108))
                gaps.append(np.abs(np.subtract(v[2:8], v[32:38])).max())
        assert max(gaps) > 5e-5, max(gaps)
        assert wait_until(lambda: np.abs(np.subtract(r.getActualTCPPose(), pose)).max() < 1e-6, timeout_s=2.0)
        time.sleep(0.5)
        with _connect(emu.host, SCRIPT_PORT) as rt:
            v = struct.unpack(">i138d", _recv_exact(rt, 1108))
        assert np.abs(np.subtract(v[2:8], v[32:38])).max() < 1e-7
        with _connect(emu.host, SECONDARY_PORT) as sec:
            _read_message(sec)  # version
            _, message = _read_message(sec)
        joints = dict(_sub_packages(message))[1]
        q_pairs = [struct.unpack_from(">dd", joints, 5 + 41 * j) for j in range(6)]  # q actual, q target per joint
        assert max(abs(a - t) for a, t in q_pairs) < 1e-7
    finally:
        c.stopScript()
        c.disconnect()
        r.disconnect()


def test_a_client_that_does_not_read_has_packets_skipped_not_its_connection_dropped():
    """ur_rtde keeps one connection to 30003 open and never reads the real-time stream; a CB3 keeps serving it (ur_rtde
    runs for hours). Here on a socket pair with 4 KiB buffers (on loopback the emulator's send buffer grows to a few MB,
    ~20 s of packets): once the socket is full, whole packets are skipped (at most one packet waits, so the stream
    stays framed), said once in the client's log, and the connection is kept (the outbox never nears the 64 KiB that
    drops a replying client); when the client reads again, it gets whole 1108-byte packets."""
    from drillgym.envs.real.emulator.nonblocking import Outbox, StreamClient
    from drillgym.envs.real.emulator.state_streams import StateStreams

    ours, theirs = socket.socketpair()
    ours.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    theirs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    ours.setblocking(False)
    lines = []
    client = StreamClient("script", bytearray(), Outbox(ours, 65536), lines.append)
    streams = StateStreams()
    state = _resting_state()
    try:
        for cycle in range(200):
            streams.tick(cycle * CYCLE_S, {**state, "timestamp": cycle * CYCLE_S}, [client])
            assert client.outbox.flush()  # never at the drop limit
            assert len(client.outbox.pending) <= 1108  # at most one packet waits
        assert streams.skipped[id(client)] > 100
        assert len(lines) == 1 and "does not read its realtime stream" in lines[0]
        theirs.settimeout(1.0)
        data = b""
        while len(data) < 3 * 1108:
            data += theirs.recv(65536)
        for offset in range(0, len(data) - 1107, 1108):
            assert struct.unpack_from(">i", data, offset)[0] == 1108  # framed: every packet whole
    finally:
        ours.close()
        theirs.close()


@pytest.mark.realtime
def test_a_client_that_never_reads_30003_can_still_send_programs(start_emulator):
    """ur_rtde's script client on 30003 sends programs and never reads (its control program at start, a custom
    function later): after 2 s of not reading (250 real-time packets sent to it), a program sent on the same
    connection still runs (standard digital output 6 set, seen over RTDE within 1 s)."""
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_digital_output_bits"])
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    try:
        s.connect((emu.host, SCRIPT_PORT))
        time.sleep(2.0)
        s.sendall(b"set_standard_digital_out(6, True)\n")
        assert wait_until(lambda: r.getActualDigitalOutputBits() & (1 << 6), timeout_s=1.0)
    finally:
        s.close()
        r.disconnect()
