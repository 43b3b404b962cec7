"""The UR controller emulator against the real, unmodified ur_rtde 1.6.5 client (and the Net F/T client)."""

import socket
import time

import numpy as np
import pytest
import rtde_control
import rtde_receive
from real_cell import wait_until

from drillgym.envs.cell_params import CellParams
from drillgym.envs.real.emulator.config import DASHBOARD_PORT
from drillgym.envs.real.netft import NetFTCalibration, NetFTClient
from drillgym.envs.scenario import Scenario

pytestmark = pytest.mark.realtime  # timing-sensitive: run alone (see the Makefile)


def _fresh_timestamp(r):
    """The controller timestamp (s) of the first package to arrive from now, and this process's clock then."""
    last = r.getTimestamp()
    assert wait_until(lambda: r.getTimestamp() != last, poll_s=0.0005)
    return r.getTimestamp(), time.monotonic()


def test_receive_interface_streams_the_full_default_recipe(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host)
    try:
        # 125 Hz state on the controller clock: over two seconds of this process's clock, the controller's
        # advances as much, give or take how late each of the two packages read arrived (each read is taken as a
        # new package shows; on a 2-core machine under load a package was once seen 52 ms late, so 0.1 s)
        t0, m0 = _fresh_timestamp(r)
        time.sleep(2.0)
        t1, m1 = _fresh_timestamp(r)
        assert t1 - t0 == pytest.approx(m1 - m0, abs=0.1)
        pose = np.array(r.getActualTCPPose())
        np.testing.assert_allclose(pose[:3], [-0.45, -0.11, 0.11], atol=1e-9)  # drill tip 10 mm above the entry
        assert len(r.getActualQ()) == 6 and r.getSafetyStatusBits() == 1 and r.getRobotMode() == 7
        assert not r.isProtectiveStopped() and len(r.getPayloadCog()) == 3
    finally:
        r.disconnect()
    assert [len(o) for o in emu.control({"cmd": "contract"})["output_recipes"]] == [57]


def test_unknown_variable_is_refused_like_a_controller_does(start_emulator):
    emu = start_emulator()
    with pytest.raises(RuntimeError, match="bogus_var"):
        rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "bogus_var"])


def _settled_tcp(r, expected, timeout_s=2.0):
    """The streamed TCP position once it shows ``expected`` (a command shows in the next 125 Hz packages;
    on a busy machine a few of them later), or the last one read after ``timeout_s``."""
    wait_until(lambda: np.max(np.abs(np.subtract(r.getActualTCPPose()[:3], expected))) <= 2e-6, timeout_s)
    return r.getActualTCPPose()[:3]


def test_control_interface_uploads_its_program_and_commands_move(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_TCP_pose", "runtime_state"])
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        assert c.isProgramRunning()
        pose = list(r.getActualTCPPose())
        pose[2] += 0.002
        assert c.moveL(pose, 0.02, 0.5)
        np.testing.assert_allclose(_settled_tcp(r, pose[:3]), pose[:3], atol=2e-6)
        for _ in range(25):
            t = c.initPeriod()
            pose[0] += 2e-5
            assert c.servoL(pose, 0.25, 1.2, 0.008, 0.1, 300)
            c.waitPeriod(t)
        np.testing.assert_allclose(_settled_tcp(r, pose[:3]), pose[:3], atol=2e-6)
        assert c.servoStop()
        assert c.setTcp([0.0, 0.0, 0.15, 0.0, 0.0, 0.0])
        default_tcp_m = CellParams().sensor_to_chuck_m + Scenario().stickout_m
        expected = [*pose[:2], pose[2] - (0.15 - default_tcp_m)]  # the new TCP is further down the drill
        np.testing.assert_allclose(_settled_tcp(r, expected), expected, atol=2e-6)
        c.stopScript()
        assert not c.isProgramRunning()
    finally:
        del c, r
    st = emu.status()
    assert st["command_counts"] == {"3": 1, "16": 1, "24": 25, "29": 1, "255": 1}
    assert st["scripts_loaded"] == 1 and st["runtime_state"] == "STOPPED"


def test_protective_stop_refuses_motion_and_the_dashboard_reports_it(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host)
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        emu.fault("protective_stop")
        assert wait_until(r.isProtectiveStopped) and r.getSafetyMode() == 3
        pose = list(r.getActualTCPPose())
        pose[2] += 0.001
        assert not c.moveL(pose, 0.02, 0.5)
        with socket.create_connection((emu.host, DASHBOARD_PORT), timeout=2) as s:
            f = s.makefile("rw")
            assert f.readline().startswith("Connected: Universal Robots Dashboard Server")
            for cmd, reply in (("safetymode", "Safetymode: PROTECTIVE_STOP"), ("PolyscopeVersion", "URSoftware 3.15")):
                f.write(cmd + "\n")
                f.flush()
                assert f.readline().startswith(reply)
            # UR's Dashboard Server manual: an unlock within 5 s of the stop is refused, with this answer
            f.write("unlock protective stop\n")
            f.flush()
            assert f.readline().startswith("Cannot unlock protective stop until 5s after occurrence.")
            assert r.isProtectiveStopped()
            time.sleep(5.1)  # the manual's rule, not a synchronisation: 5.1 s after the refusal is > 5 s after the stop
            f.write("unlock protective stop\n")
            f.flush()
            assert f.readline().strip() == "Protective stop releasing"
            assert wait_until(lambda: not r.isProtectiveStopped())
        emu.fault("protective_stop")  # again, for the harness's own clear
        assert wait_until(r.isProtectiveStopped)
        emu.control({"cmd": "clear_faults"})
        assert wait_until(lambda: not r.isProtectiveStopped())
        # the control interface reads its own RTDE connection, which can show the resumed program a package or
        # more after the receive interface shows the released stop (beside two busy processes it did not yet)
        assert wait_until(c.isProgramRunning)
    finally:
        c.disconnect()
        r.disconnect()


def test_rtde_watchdog_stops_the_program_when_commands_stop(start_emulator):
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        assert c.setWatchdog(20.0)  # 20 Hz: the program stops once no command came for 50 ms
        assert wait_until(lambda: not c.isProgramRunning())
        assert "RTDE watchdog" in emu.status()["stop_reason"]
    finally:
        c.disconnect()


def _last_records(client, n, timeout_s=2.0):
    """The newest ``n`` F/T records once that many have arrived (at 125-1000 Hz: well within ``timeout_s``)."""
    assert wait_until(lambda: len(client.since(0.0)) >= n, timeout_s), len(client.since(0.0))
    return client.since(0.0)[-n:]


def test_netft_stream_counts_calibration_and_bias(start_emulator):
    """The rate is the RDT sequence's advance over this process's clock: half a second of it is ~500 records at
    1 kHz, and the two reads' arrival lag (a few ms on a busy machine) moves the ratio by about 1 %; 10 % is left
    for a stream the sensor thread paces on its own clock. The tare is the tool's weight in the sensor frame
    (0.3, -0.2, 2.5) N; the noise of a mean of 100 records is about 0.003 N, far under 0.02 N."""
    emu = start_emulator(extra_args=["--ft-rate-hz", "1000"])
    client = NetFTClient(emu.host, calibration=NetFTCalibration())
    try:
        first = _last_records(client, 1)[0]
        time.sleep(0.5)
        last = client.latest()
        rate_hz = (last.rdt_sequence - first.rdt_sequence) / (last.t_recv_s - first.t_recv_s)
        assert rate_hz == pytest.approx(1000.0, rel=0.1)
        mean = np.mean([r.wrench for r in _last_records(client, 100)], axis=0)
        np.testing.assert_allclose(mean[:3], [0.3, -0.2, 2.5], atol=0.02)  # the tool's weight: tare it
        t_bias = time.monotonic()
        client.bias()

        def tared():
            recs = client.since(t_bias)[-50:]
            return len(recs) == 50 and np.linalg.norm(np.mean([r.wrench for r in recs], axis=0)[:3]) < 0.05

        assert wait_until(tared)
        assert client.status_errors == 0 and client.malformed == 0
    finally:
        client.close()


def test_wrong_calibration_is_visible_in_the_readings(start_emulator):
    emu = start_emulator()
    client = NetFTClient(emu.host, calibration=NetFTCalibration(counts_per_force=2e6))
    try:
        recs = _last_records(client, 50)
        np.testing.assert_allclose(np.mean([r.wrench for r in recs], axis=0)[2], 1.25, atol=0.02)
    finally:
        client.close()
