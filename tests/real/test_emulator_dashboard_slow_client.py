"""A dashboard client that sends but never reads its replies cannot stop the emulator (issue 43, item 3).

Before the fix the emulator sent each reply with a blocking ``sendall``: once the client's receive window and the
emulator's send buffer were full, the one loop that also runs the 125 Hz controller, RTDE, the F/T stream and the
physics waited on that client, for as long as it held the socket, and logged nothing. Now replies wait in a
bounded outbox, the client is dropped and logged once 64 KiB pile up, and the RTDE stream goes on.

The bar, 100 ms without an RTDE data package, is issue 43's acceptance bar and the real env's own staleness limit
(``SafetyLimits.rtde_stale_s``, 0.1 s): a longer gap stops a drilling episode. 125 Hz packages are 8 ms apart, so
the bar leaves the emulator's ordinary scheduling jitter on a loaded 2-core machine (tens of ms) room.
"""

import socket
import time

import pytest
from real_cell import wait_until
from rtde_watcher import RtdeWatcher

from drillgym.envs.real.emulator.config import CONTROL_PORT, DASHBOARD_PORT
from drillgym.envs.real.emulator.dashboard import WELCOME

pytestmark = pytest.mark.realtime  # timing-sensitive: run alone (see the Makefile)

STALL_BAR_S = 0.1


def _flood_without_reading(host: str, port: int, line: bytes, seconds: float) -> tuple[int, bool]:
    """Send ``line`` over and over, never reading, until the emulator drops us or ``seconds`` (s) have passed.

    Returns the bytes sent and whether we were dropped. The replies must exceed what the kernel buffers before the
    emulator's own outbox fills: up to 4 MiB on the emulator's side (Linux's ``tcp_wmem`` maximum) plus our small
    receive window; a ``polyscopeversion`` line (17 bytes) is answered with 39, so about 2 MB of them suffice.
    """
    sent, dropped = 0, False
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting: a small window from the start
    with s:
        s.connect((host, port))
        s.setblocking(False)
        chunk = line * (8192 // len(line))
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                sent += s.send(chunk)
            except BlockingIOError:
                time.sleep(0.002)
            except OSError:  # reset by the emulator once it dropped us
                dropped = True
                break
    return sent, dropped


def _dashboard_answers(host: str) -> str:
    with socket.create_connection((host, DASHBOARD_PORT), timeout=2.0) as s:
        f = s.makefile("rw", newline="\n")
        assert f.readline() == WELCOME
        f.write("robotmode\n")
        f.flush()
        return f.readline().strip()


def test_a_dashboard_client_that_never_reads_is_dropped_and_rtde_streams_on(start_emulator):
    emu = start_emulator()
    watcher = RtdeWatcher(emu.host).start()
    try:
        t0 = time.monotonic()
        sent, dropped = _flood_without_reading(emu.host, DASHBOARD_PORT, b"polyscopeversion\n", seconds=10.0)
        t1 = time.monotonic()
        assert watcher.error is None, watcher.error
        assert watcher.max_gap_s(t0, t1) <= STALL_BAR_S, watcher.max_gap_s(t0, t1)
        assert dropped, f"still connected after {sent} bytes"
        assert wait_until(lambda: "dashboard: client does not read its replies" in emu.log_tail(20000), 2.0)
        assert _dashboard_answers(emu.host).startswith("Robotmode:")  # the next client is served
    finally:
        watcher.stop()


def test_a_dashboard_line_without_end_is_refused_and_rtde_streams_on(start_emulator):
    """A line longer than 4 KiB without a newline drops its client (nothing a dashboard command needs is longer)."""
    emu = start_emulator()
    watcher = RtdeWatcher(emu.host).start()
    try:
        t0 = time.monotonic()
        _, dropped = _flood_without_reading(emu.host, DASHBOARD_PORT, b"x", seconds=2.0)
        t1 = time.monotonic()
        assert dropped and wait_until(lambda: "more than 4096 bytes without a newline" in emu.log_tail(20000), 2.0)
        assert watcher.error is None and watcher.max_gap_s(t0, t1) <= STALL_BAR_S
        assert _dashboard_answers(emu.host).startswith("Robotmode:")
    finally:
        watcher.stop()


def test_a_control_port_client_that_never_reads_is_dropped_and_rtde_streams_on(start_emulator):
    """The emulator's JSON control port shares the loop: the same outbox bound holds there."""
    emu = start_emulator()
    watcher = RtdeWatcher(emu.host).start()
    try:
        t0 = time.monotonic()
        _, dropped = _flood_without_reading(emu.host, CONTROL_PORT, b'{"cmd": "status"}\n', seconds=10.0)
        t1 = time.monotonic()
        assert watcher.error is None and watcher.max_gap_s(t0, t1) <= STALL_BAR_S, watcher.max_gap_s(t0, t1)
        assert dropped and wait_until(lambda: "control: client does not read" in emu.log_tail(20000), 2.0)
        assert emu.status()["rtde_connections"] == 1  # the watcher's; the control port answers the next client
    finally:
        watcher.stop()
