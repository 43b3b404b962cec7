"""The emulated Net F/T behaves as ATI's sensor where clients rely on it; each test names its source.

Sources: ATI's manual 9620-05-NET FT, "UDP Interface Using RDT" (request ``0x1234, command, sample_count``; commands
0x0000 stop, 0x0002 real-time, 0x0003 buffered, 0x0041 reset threshold latch, 0x0042 set software bias; 36-byte
records ``rdt_sequence, ft_sequence, status, 6 x int32 counts``; in buffered mode a packet holds "RDT buffer size"
records) and its web pages (``netftapi2.xml``: ``cfgcpf``, ``cfgcpt``, ``scfgfu``, ``scfgtu``), and pyNetFT 2.1.3
used unmodified (``.venv/bin/pip install pynetft``; its native core requests ``/netftapi2.xml`` before streaming).
"""

import socket
import struct
import time
import urllib.error
import urllib.request
from xml.etree import ElementTree

import numpy as np
import pytest
from real_cell import wait_until

from drillgym.envs.real import netft
from drillgym.envs.real.emulator.sensor_streams import CMD_RESET_THRESHOLD_LATCH, CMD_START_BUFFERED

pytestmark = pytest.mark.realtime  # real-time streams: run alone (see the Makefile)

RATE_HZ = 500.0
TOOL_WEIGHT_N = (0.3, -0.2, 2.5)
"""The emulated F/T's constant offset (the tool's weight, sensor frame): what it reads at rest."""


def _udp(host):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.settimeout(1.0)
    s.connect((host, netft.RDT_PORT))
    return s


def _drain(s, quiet_s=0.1):
    """Read until nothing has come for ``quiet_s``; the datagrams read."""
    s.settimeout(max(quiet_s, 1e-3))
    got = []
    try:
        while True:
            got.append(s.recv(4096))
    except TimeoutError:
        pass
    s.settimeout(1.0)
    return got


def _records(packet):
    assert len(packet) % netft.RECORD.size == 0, len(packet)
    return [netft.RECORD.unpack_from(packet, i) for i in range(0, len(packet), netft.RECORD.size)]


def _http(emu, target, method="GET"):
    url = f"http://{emu.host}:{emu.info['ports']['ft_http']}{target}"
    try:
        with urllib.request.urlopen(urllib.request.Request(url, method=method), timeout=2.0) as reply:
            return reply.status, reply.headers, reply.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def test_pynetft_with_its_default_setup_reads_the_calibration_from_netftapi2_xml(start_emulator):
    """pyNetFT's default set-up has no calibration override: it reads ``netftapi2.xml`` and scales the RDT counts by
    ``cfgcpf`` / ``cfgcpt``. Served 2.5e6 counts/N (not the 1e6 a client might assume), it must report the source
    SENSOR with those counts, units N and N-m, and at rest the tool's weight: the mean of 100 records (noise ~0.003 N)
    within 0.02 N, where a wrong scale would be off by 60 % (1.5 N in z). Only the web port differs from pyNetFT's
    defaults (80 needs root; the emulator serves ``--ft-http-port``)."""
    pynetft = pytest.importorskip("pynetft")
    emu = start_emulator(extra_args=["--counts-per-force", "2500000"])
    config = pynetft.Config(sensor_host=emu.host, http_port=emu.info["ports"]["ft_http"])
    with pynetft.Client(config) as client:
        samples = client.samples(timeout=2.0)
        forces = [next(samples).force for _ in range(100)]
        health = client.health()
    sensor = health.sensor_configuration
    assert sensor is not None and sensor.source == pynetft.CalibrationSource.SENSOR
    assert sensor.calibration.counts_per_force_unit == 2_500_000
    assert sensor.calibration.force_unit == pynetft.ForceUnit.NEWTON
    assert sensor.calibration.torque_unit == pynetft.TorqueUnit.NEWTON_METER
    np.testing.assert_allclose(np.mean(forces, axis=0), TOOL_WEIGHT_N, atol=0.02)
    assert health.ft_stall_count == 0 and health.ft_backward_count == 0 and health.malformed_count == 0


def test_netftapi2_xml_serves_calibration_units_and_rdt_settings(start_emulator):
    """ATI's ``netftapi2.xml`` (and ``?index=N``, N = 0-15 configurations): the counts per force and torque, their
    units (a sensor spells them ``N`` and ``Nm``), the RDT rate and buffer size as configured. The emulator answers
    HEAD without a body, another path 404, another method 405, an index beyond 15 400."""
    emu = start_emulator(
        extra_args=["--counts-per-force", "1000000", "--counts-per-torque", "1000", "--ft-rdt-buffer-size", "8"]
    )
    status, headers, body = _http(emu, "/netftapi2.xml")
    assert status == 200 and headers["Content-Type"] == "text/xml"
    page = ElementTree.fromstring(body)
    assert page.tag == "netft"
    fields = {child.tag: child.text for child in page}
    assert (fields["cfgcpf"], fields["cfgcpt"], fields["scfgfu"], fields["scfgtu"]) == ("1000000", "1000", "N", "Nm")
    assert (fields["comrdtrate"], fields["comrdtbsiz"], fields["setcfgsel"]) == ("500", "8", "0")
    assert _http(emu, "/netftapi2.xml?index=15")[2] == body
    assert _http(emu, "/netftapi2.xml?index=16")[0] == 400
    assert _http(emu, "/netftapi2.xml", method="HEAD")[2] == b""
    assert _http(emu, "/setting.cgi")[0] == 404
    assert _http(emu, "/netftapi2.xml", method="POST")[0] == 405


def _receive_until_quiet(s, quiet_s=0.3):
    """(arrival time, packet) of every datagram until none has come for ``quiet_s``."""
    got = []
    s.settimeout(quiet_s)
    try:
        while True:
            packet = s.recv(65536)
            got.append((time.monotonic(), packet))
    except TimeoutError:
        pass
    s.settimeout(1.0)
    return got


def test_a_restarted_stream_is_paced_at_the_configured_rate(start_emulator):
    """ATI RDT: records leave at the configured output rate (500 Hz: one every 2 ms). After a stop and 0.3 s idle, a new
    start must not flush a backlog (the emulator used to send ~54 records within 5 ms): record k of the new stream may
    not arrive before (k - 1) x 2 ms after the request was sent. A loaded machine only delays records, so this bound
    holds under any load; 0.5 ms is left for the order of the two processes' clock reads (the same monotonic clock)."""
    emu = start_emulator()
    s = _udp(emu.host)
    try:
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 0))
        for _ in range(20):
            s.recv(4096)
        s.send(netft.pack_request(netft.CMD_STOP, 0))
        _drain(s)
        time.sleep(0.3)
        t_request = time.monotonic()
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 60))
        got = _receive_until_quiet(s)
    finally:
        s.close()
    sequences = [netft.RECORD.unpack(p)[0] for _, p in got]
    assert sequences[0] == 1 and len(got) >= 30
    earliest = [t_request + (k - 1) / RATE_HZ - 0.0005 for k in sequences]
    late_enough = [t >= bound for (t, _), bound in zip(got, earliest, strict=True)]
    assert all(late_enough), [k for k, ok in zip(sequences, late_enough, strict=True) if not ok][:5]


def test_the_rdt_sequence_counts_records_of_one_stream_and_rests_while_idle(start_emulator):
    """ATI RDT: ``rdt_sequence`` is the record's position in its stream (1 for the first record after a request, +1 per
    record), and nothing is sent while stopped: a counted request of 50 ends by itself, no datagram arrives in the
    0.3 s idle after it, and the next stream starts again at 1. Records the emulator's loop could not send in time
    (a loaded machine) are gaps in the sequence, and the emulator counts them (status ``ft_records_lost``): received
    plus lost is the 50 asked for. ``ft_sequence``, the sensor's internal sample counter, runs forward and on while
    idle: at least 0.3 s x 7000 Hz x 0.9 further (10 % for the requests' own latency)."""
    emu = start_emulator()
    s = _udp(emu.host)
    try:
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 50))
        first = [netft.RECORD.unpack(p) for _, p in _receive_until_quiet(s)]
        lost = emu.status()["ft_records_lost"]
        time.sleep(0.3)
        assert _drain(s) == []
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 0))
        again = netft.RECORD.unpack(s.recv(4096))
        s.send(netft.pack_request(netft.CMD_STOP, 0))
    finally:
        s.close()
    sequences = [r[0] for r in first]
    assert sequences[0] == 1 and np.all(np.diff(sequences) > 0) and sequences[-1] <= 50
    assert len(first) + lost == 50
    assert np.all(np.diff([r[1] for r in first]) > 0)
    assert again[0] == 1
    assert again[1] - first[-1][1] >= 0.3 * 7000 * 0.9


def test_buffered_streaming_sends_rdt_buffer_size_records_per_packet(start_emulator):
    """ATI RDT command 0x0003 (start buffered streaming): each packet holds "RDT buffer size" records (here 10), with
    increasing ``rdt_sequence`` numbers from 1 (consecutive unless the emulator reports lost records). A packet leaves
    when its last record is due: packet k not before (10 k - 1) x 2 ms after the request (0.5 ms for the clock reads'
    order). A counted request of 25 records sends 10, 10 and the last 5, then nothing."""
    emu = start_emulator(extra_args=["--ft-rdt-buffer-size", "10"])
    s = _udp(emu.host)
    try:
        t_request = time.monotonic()
        s.send(netft.pack_request(CMD_START_BUFFERED, 0))
        packets = []
        for _ in range(5):
            packets.append((s.recv(4096), time.monotonic()))
        s.send(netft.pack_request(netft.CMD_STOP, 0))
        _drain(s)
        lost = emu.status()["ft_records_lost"]
        assert all(len(p) == 10 * netft.RECORD.size for p, _ in packets)
        sequences = [r[0] for p, _ in packets for r in _records(p)]
        assert sequences[0] == 1 and np.all(np.diff(sequences) > 0) and sequences[-1] <= 50 + lost
        for k, (_, t) in enumerate(packets, start=1):
            assert t >= t_request + (10 * k - 1) / RATE_HZ - 0.0005
        s.send(netft.pack_request(CMD_START_BUFFERED, 25))
        counted = [len(_records(p)) for _, p in _receive_until_quiet(s)]
        if emu.status()["ft_records_lost"] == lost:  # none lost to a stall: the packets are exactly these
            assert counted == [10, 10, 5]
        else:
            assert sum(counted) < 25 and max(counted) <= 10
    finally:
        s.close()


def test_reset_threshold_latch_and_bias_are_understood_other_commands_are_logged(start_emulator):
    """ATI RDT commands 0x0041 (reset threshold latch; no thresholds are emulated, so there is nothing to reset) and
    0x0042 (set software bias) are understood: the stream goes on, nothing counted as a bad request, and after the
    bias the records read zero (mean of 50 within 0.05 N: the noise is ~0.003 N). 0x0004 (multi-unit streaming, not
    emulated) and a datagram that is not a request are counted and logged."""
    emu = start_emulator()
    s = _udp(emu.host)
    try:
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 0))
        s.recv(4096)
        s.send(netft.pack_request(CMD_RESET_THRESHOLD_LATCH, 0))
        s.send(netft.pack_request(netft.CMD_SET_SOFTWARE_BIAS, 0))
        assert wait_until(lambda: emu.status()["ft_records_sent"] > 100)
        _drain(s, quiet_s=0.0)
        counts = [_records(s.recv(4096))[0][3:6] for _ in range(50)]
        assert np.linalg.norm(np.mean(counts, axis=0) / 1e6) < 0.05
        assert emu.status()["ft_bad_requests"] == 0
        s.send(struct.pack(">HHI", netft.RDT_HEADER, 0x0004, 0))
        s.send(b"\x00\x01")
        assert wait_until(lambda: emu.status()["ft_bad_requests"] == 2)
        s.send(netft.pack_request(netft.CMD_STOP, 0))
    finally:
        s.close()
    log = emu.log_tail(20000)
    assert "RDT command 0x0004" in log and "is not an RDT request" in log


def test_the_net_ft_ports_survive_hostile_input(start_emulator):
    """No input ends or stalls the emulator (issue 43, item 3) on the Net F/T's ports: datagrams of 0, 2, 9 and 60000
    bytes and a wrong header on RDT; a request head of 20 kB without its end (answered 431), a line that is not HTTP
    (400) and binary garbage on the web port; a short and an unknown command on the calibration port. Afterwards the
    controller still ticks (RTDE's clock advances), the RDT stream still streams and the page is still served."""
    emu = start_emulator()
    s = _udp(emu.host)
    port = emu.info["ports"]["ft_http"]
    try:
        for datagram in (b"", b"\x12\x34", b"\x12\x34\x00\x02\x00\x00\x00\x00\x00", b"\xff" * 60000, b"\x00" * 8):
            s.send(datagram)
        with socket.create_connection((emu.host, port), timeout=2.0) as web:
            web.sendall(b"GET /" + b"a" * 20000)
            assert web.recv(100).startswith(b"HTTP/1.1 431")
        for request in (b"HELLO\r\n\r\n", bytes(range(256)) + b"\r\n\r\n"):
            with socket.create_connection((emu.host, port), timeout=2.0) as web:
                web.sendall(request)
                assert web.recv(100).startswith(b"HTTP/1.1 400")
        for request in (b"\x01", b"\x07" + b"\x00" * 19):
            with socket.create_connection((emu.host, emu.info["ports"]["ft_cal"]), timeout=2.0) as cal:
                cal.sendall(request)
                cal.shutdown(socket.SHUT_WR)
                cal.recv(100)  # nothing or a close; the emulator must not wait for more
        ticks = emu.status()["controller_ticks"]
        assert wait_until(lambda: emu.status()["controller_ticks"] > ticks + 25)
        s.send(netft.pack_request(netft.CMD_START_REALTIME, 5))
        assert [_records(s.recv(4096))[0][0] for _ in range(5)] == [1, 2, 3, 4, 5]
        assert _http(emu, "/netftapi2.xml")[0] == 200
    finally:
        s.close()
