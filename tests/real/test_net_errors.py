"""A port in use, a refused connection, a silent sensor: one line naming HOST:PORT and what to check.

Fast (no streaming): the emulator fails before it serves, the F/T clients fail before they read.
"""

import errno
import socket
import threading

from drillgym.envs.real.emulator.config import CONTROL_PORT
from drillgym.envs.real.emulator.process import free_loopback_host, ports_free
from drillgym.envs.real.net_errors import bind_error, connect_error
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration
from drillgym.envs.real.netft_calibration import CAL_PORT, CAL_REQUEST, pack_calinfo
from drillgym.eval.cli import main


def test_emulate_on_a_port_in_use_names_host_port_and_the_way_out(capsys):
    host = free_loopback_host()
    with socket.socket() as busy:  # something else already listens on the control port
        busy.bind((host, CONTROL_PORT))
        busy.listen(1)
        assert main(["emulate", "--host", host, "--max-lifetime-s", "0.5"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drillgym emulate: error: ") and "\n" not in err
    assert f"{host}:{CONTROL_PORT}" in err and "Address already in use" in err
    assert f"is another emulator or URSim running on {host}?" in err and "--host 127.0.0.X" in err
    assert "--control-port" in err
    assert ports_free(host)  # the ports it had bound before the busy one are released


def test_ft_check_against_nothing_names_the_calibration_port_and_says_ping(capsys):
    host = free_loopback_host()  # nothing listens there
    assert main(["ft-check", "--ft", host, "--mass-kg", "0.5", "--wait-s", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drillgym ft-check: error: ") and "\n" not in err
    assert f"{host}:{CAL_PORT}" in err and "Connection refused" in err
    assert f"is the sensor at {host} powered and reachable? check the address with ping {host}" in err
    assert f"drillgym emulate --host {host}" in err  # loopback: the emulator is the likely sensor


def test_ft_check_with_a_silent_rdt_stream_names_the_rdt_port(capsys):
    host = free_loopback_host()
    with socket.socket() as cal:  # a sensor that answers READCALINFO but streams nothing
        cal.bind((host, CAL_PORT))
        cal.listen(1)

        def answer() -> None:
            conn, _ = cal.accept()
            with conn:
                conn.recv(CAL_REQUEST.size)
                conn.sendall(pack_calinfo(NetFTCalibration()))

        server = threading.Thread(target=answer, daemon=True)
        server.start()
        code = main(["ft-check", "--ft", host, "--mass-kg", "0.5", "--wait-s", "0", "--average-s", "0.2"])
        server.join(timeout=2.0)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err
    assert f"0 F/T records from {host}:{RDT_PORT}" in err and "is the sensor streaming?" in err


def test_hints_for_the_other_errnos():
    timeout = connect_error(TimeoutError("timed out"), "192.168.1.1", CAL_PORT, "the sensor")
    assert isinstance(timeout, TimeoutError)
    assert "192.168.1.1:49151: no answer (timed out)" in str(timeout) and "ping 192.168.1.1" in str(timeout)
    assert "emulate" not in str(timeout)  # not a loopback address: no emulator hint
    unknown = connect_error(socket.gaierror(-2, "Name or service not known"), "sensr", CAL_PORT, "the sensor")
    assert "sensr:49151" in str(unknown) and "IP address" in str(unknown)
    not_here = bind_error(OSError(errno.EADDRNOTAVAIL, "Cannot assign requested address"), "10.0.0.5", 30004, "RTDE")
    assert not_here.errno == errno.EADDRNOTAVAIL and "10.0.0.5:30004" in str(not_here)
    assert "--host 127.0.0.X" in str(not_here)
    low = bind_error(PermissionError(errno.EACCES, "Permission denied"), "127.0.0.2", 80, "RTDE", "--rtde-port")
    assert isinstance(low, PermissionError) and "below 1024" in str(low) and "--rtde-port" in str(low)
