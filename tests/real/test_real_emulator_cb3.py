"""The emulator behaves like a CB3 where clients rely on it; each test names the documented behaviour it checks.

Sources: UR's "Dashboard Server, port 29999" (CB3 answer texts), UR's "Remote Control Via TCP/IP" and the
URScript manual (a program sent to the primary 30001, secondary 30002 or real-time 30003 interface runs at
once; a ``def`` program or bare statements replace the running program, a ``sec`` program runs beside it), the
RTDE guide (field names and types: ``actual_qd``, ``actual_TCP_speed``, ``speed_scaling``,
``actual_digital_output_bits``, ``tcp_offset``; ``robot_mode`` 3 POWER_OFF, 5 IDLE, 7 RUNNING) and ur_rtde's
API reference (``moveL(..., asynchronous=True)`` returns at once while the robot moves, ``stopL`` stops it,
``getAsyncOperationProgress`` is >= 0 while an async operation runs, < 0 when it is done;
``isProgramRunning`` is False once the control script was stopped).
"""

import socket
import struct
import time

import numpy as np
import pytest
import rtde_control
import rtde_io
import rtde_receive
from real_cell import wait_until

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.config import DASHBOARD_PORT, PRIMARY_PORT, SCRIPT_PORT, SECONDARY_PORT

pytestmark = pytest.mark.realtime  # timing-sensitive: run alone (see the Makefile)


def _send_script(host, port, text):
    with socket.create_connection((host, port), timeout=2.0) as s:
        s.sendall(text.encode())  # the controller runs it within a few cycles: the tests wait for its effects


_wait = wait_until


@pytest.mark.parametrize("port", [SCRIPT_PORT, PRIMARY_PORT, SECONDARY_PORT])
def test_a_program_sent_to_a_script_port_replaces_the_control_script(start_emulator, port):
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_digital_output_bits", "runtime_state"])
    try:
        assert c.isProgramRunning()
        _send_script(emu.host, port, "def spindle_on():\n  set_standard_digital_out(2, True)\n  sleep(0.5)\nend\n")
        assert _wait(lambda: not c.isProgramRunning())  # ur_rtde sees its control script stopped
        assert _wait(lambda: r.getActualDigitalOutputBits() & 0b100)  # the statement it can run, it ran
        assert r.getRuntimeState() == 1  # STOPPED
        events = [e["detail"] for e in emu.control({"cmd": "events"})["events"]]
        said = [e for e in events if e.startswith("program (replaced")]
        assert said and "spindle_on" in said[0] and "1 other line(s) not emulated" in said[0]
        assert emu.status()["stop_reason"].startswith("replaced by the program")
    finally:
        c.disconnect()
        r.disconnect()


def test_bare_statements_replace_the_program_and_a_secondary_program_does_not(start_emulator):
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_digital_output_bits"])
    try:
        _send_script(emu.host, SECONDARY_PORT, "sec io():\n  set_standard_digital_out(3, True)\nend\n")
        assert _wait(lambda: r.getActualDigitalOutputBits() & 0b1000) and c.isProgramRunning()
        _send_script(emu.host, PRIMARY_PORT, "set_standard_digital_out(3, False)\n")
        assert _wait(lambda: not c.isProgramRunning() and not r.getActualDigitalOutputBits() & 0b1000)
    finally:
        c.disconnect()
        r.disconnect()


def _dashboard(host, *commands):
    with socket.create_connection((host, DASHBOARD_PORT), timeout=2.0) as s:
        f = s.makefile("rw", newline="\n")
        f.readline()  # welcome
        replies = []
        for cmd in commands:
            f.write(cmd + "\n")
            f.flush()
            replies.append(f.readline().rstrip("\n"))
        return replies


def test_dashboard_power_brakes_load_and_model_answer_with_urs_texts(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "robot_mode"])
    try:
        assert _dashboard(emu.host, "get robot model", "get loaded program", "load /programs/drill.urp") == [
            "UR5",
            "No program loaded",
            "File not found: /programs/drill.urp",  # the emulator has no program files, and says so
        ]
        assert _dashboard(emu.host, "power off", "robotmode") == ["Powering off", "Robotmode: POWER_OFF"]
        assert _wait(lambda: r.getRobotMode() == 3)
        with pytest.raises(RuntimeError):  # no program starts on a powered-off arm
            rtde_control.RTDEControlInterface(emu.host)
        assert _dashboard(emu.host, "power on", "robotmode") == ["Powering on", "Robotmode: IDLE"]
        assert _dashboard(emu.host, "brake release", "robotmode") == ["Brake releasing", "Robotmode: RUNNING"]
        assert _wait(lambda: r.getRobotMode() == 7)
        assert _dashboard(emu.host, "make coffee") == ["Could not understand: 'make coffee'"]
    finally:
        r.disconnect()
    assert "no program files" in emu.log_tail()


def test_async_movel_moves_reports_speeds_and_stops_on_stopl(start_emulator):
    emu = start_emulator()
    fields = ["timestamp", "actual_TCP_pose", "actual_TCP_speed", "actual_qd", "target_qd"]
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, fields)
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        assert np.allclose(r.getActualTCPSpeed(), 0.0) and np.allclose(r.getActualQd(), 0.0)  # at rest
        pose = list(r.getActualTCPPose())
        target = list(pose)
        target[2] += 0.01
        t0 = time.monotonic()
        assert c.moveL(target, 0.02, 0.5, True)
        assert time.monotonic() - t0 < 0.3  # returned at once (the move takes 0.5 s)
        assert c.getAsyncOperationProgress() >= 0  # running
        # mid-move (the ramp to 0.02 m/s at 0.5 m/s^2 takes 40 ms of the 0.5 s move): the speed is along z
        assert _wait(lambda: r.getActualTCPSpeed()[2] == pytest.approx(0.02, rel=0.15), 0.4)
        speed = np.array(r.getActualTCPSpeed())
        assert np.linalg.norm(speed[:2]) < 1e-3
        assert np.linalg.norm(r.getActualQd()) > 1e-3
        c.stopL(2.0)  # ur_rtde returns nothing
        assert _wait(lambda: np.allclose(r.getActualTCPSpeed(), 0.0, atol=1e-6))  # the next states show it stopped
        z_stopped = r.getActualTCPPose()[2]
        time.sleep(0.1)  # not a synchronisation: nothing may move in this time, however long it takes
        assert r.getActualTCPPose()[2] == pytest.approx(z_stopped, abs=1e-6)  # and it stays, short of the target
        assert z_stopped < target[2] - 0.002
        assert c.getAsyncOperationProgress() < 0  # done
    finally:
        c.disconnect()
        r.disconnect()


def test_speed_slider_and_digital_outputs_set_over_rtde_are_reflected(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(
        emu.host, 125.0, ["timestamp", "speed_scaling", "target_speed_fraction", "actual_digital_output_bits"]
    )
    io = rtde_io.RTDEIOInterface(emu.host)
    try:
        assert r.getSpeedScaling() == 1.0
        assert io.setSpeedSlider(0.5) and io.setStandardDigitalOut(4, True) and io.setConfigurableDigitalOut(1, True)
        assert _wait(lambda: r.getSpeedScaling() == 0.5) and r.getTargetSpeedFraction() == 0.5
        assert _wait(lambda: r.getActualDigitalOutputBits() == (1 << 4) | (1 << 9))
        assert io.setStandardDigitalOut(4, False)
        assert _wait(lambda: r.getActualDigitalOutputBits() == 1 << 9)
    finally:
        io.disconnect()
        r.disconnect()


def test_tcp_offset_is_served_and_follows_set_tcp(start_emulator):
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        assert c.setTcp([0.0, 0.0, 0.123, 0.0, 0.0, 0.0])
        with socket.create_connection((emu.host, 30004), timeout=2.0) as s:  # a raw RTDE client, as UR's own
            s.sendall(rp.pack(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)))
            reader = rp.PackageReader()

            def next_package():
                while True:
                    for kind, payload in reader.feed(s.recv(4096)):
                        return kind, payload

            assert next_package() == (rp.REQUEST_PROTOCOL_VERSION, b"\x01")
            s.sendall(rp.pack(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"timestamp,tcp_offset"))
            kind, payload = next_package()
            assert kind == rp.SETUP_OUTPUTS and payload[1:] == b"DOUBLE,VECTOR6D"
            s.sendall(rp.pack(rp.START))
            assert next_package()[0] == rp.START
            kind, payload = next_package()
            values = struct.unpack(">B7d", payload)
            np.testing.assert_allclose(values[2:], [0.0, 0.0, 0.123, 0.0, 0.0, 0.0], atol=1e-12)
    finally:
        c.disconnect()


@pytest.mark.parametrize(("frequency_hz", "divider"), [(25.0, 5), (40.0, 3)])
def test_a_lower_rtde_frequency_sends_every_nth_controller_cycle(start_emulator, frequency_hz, divider):
    """CB3: outputs at most 125 Hz (UR's client library, ``CB3_MAX_FREQUENCY``); a lower frequency is served on
    the 125 Hz controller clock, every ``divider`` cycles; a frequency that 125 Hz does not divide is logged."""
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, frequency_hz, ["timestamp"])
    try:
        stamps = set()
        deadline = time.monotonic() + 0.6
        while time.monotonic() < deadline:
            stamps.add(round(r.getTimestamp() / 0.008))  # controller cycles since start
            time.sleep(0.002)
    finally:
        r.disconnect()
    cycles = np.diff(sorted(stamps))
    assert len(cycles) >= 3 and np.all(cycles % divider == 0), cycles
    said = "served every 3 controller cycle(s)" in emu.log_tail(20000)
    assert said == (125.0 % frequency_hz != 0)
