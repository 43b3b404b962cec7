"""UR's own RTDE client against the emulator: the default recipe of its ``record.py`` example, recorded at 125 Hz.

Source: Universal Robots' RTDE Python Client Library (BSD-3-Clause),
https://github.com/UniversalRobots/RTDE_Python_Client_Library at commit 647788c: ``examples/record.py`` with
``examples/record_configuration.xml`` (the 32 output fields of :data:`RECORD_RECIPE`, with their types),
``rtde/rtde.py`` (the exchange: protocol version 2, controller version, an output setup at ``--frequency`` 125 Hz
whose answer must list exactly the XML's types or record.py gives up, start, data packages, pause) and
``rtde/csv_writer.py`` (a space-separated CSV, a vector as ``name_0`` ... ``name_N``). The client is not on PyPI and
its code is not kept in this repository, so two tests:

* a raw-protocol one that always runs: what record.py sends and reads, on the wire;
* one that runs record.py itself, unmodified, from a checkout of that repository named by the environment variable
  ``DRILLGYM_UR_RTDE_CLIENT`` (the folder holding ``rtde/`` and ``examples/``; skipped without one).

Both record while ``ur_rtde`` moves the arm, and check the recording against ``ur_rtde``'s ``RTDEReceiveInterface``
(same controller cycles, same ``actual_q``) and the dashboard (robot mode, safety mode, program state). The meaning
of ``safety_status`` (1 NORMAL, 3 PROTECTIVE_STOP: the safety status types of UR's Client Interface, which the RTDE
guide does not list) is from UR's forum answer "What are the values of robot safety_status in RTDE" (thread 29904).
"""

from __future__ import annotations

import csv
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rtde_control
import rtde_receive
from real_cell import wait_until

from drillgym.envs.real.emulator.config import DASHBOARD_PORT, RTDE_PORT
from drillgym.envs.real.emulator.rtde_protocol import NOT_EMULATED
from drillgym.envs.real.emulator.script import RuntimeState
from drillgym.envs.real.emulator.state import ROBOT_MODES

pytestmark = pytest.mark.realtime  # timing-sensitive: run alone (see the Makefile)

RECORD_RECIPE: list[tuple[str, str]] = [
    ("timestamp", "DOUBLE"),
    ("target_q", "VECTOR6D"),
    ("target_qd", "VECTOR6D"),
    ("target_qdd", "VECTOR6D"),
    ("target_current", "VECTOR6D"),
    ("target_moment", "VECTOR6D"),
    ("actual_q", "VECTOR6D"),
    ("actual_qd", "VECTOR6D"),
    ("actual_current", "VECTOR6D"),
    ("joint_control_output", "VECTOR6D"),
    ("actual_TCP_pose", "VECTOR6D"),
    ("actual_TCP_speed", "VECTOR6D"),
    ("actual_TCP_force", "VECTOR6D"),
    ("target_TCP_pose", "VECTOR6D"),
    ("target_TCP_speed", "VECTOR6D"),
    ("actual_digital_input_bits", "UINT64"),
    ("joint_temperatures", "VECTOR6D"),
    ("actual_execution_time", "DOUBLE"),
    ("robot_mode", "INT32"),
    ("joint_mode", "VECTOR6INT32"),
    ("safety_status", "INT32"),
    ("actual_tool_accelerometer", "VECTOR3D"),
    ("speed_scaling", "DOUBLE"),
    ("target_speed_fraction", "DOUBLE"),
    ("actual_momentum", "DOUBLE"),
    ("actual_main_voltage", "DOUBLE"),
    ("actual_robot_voltage", "DOUBLE"),
    ("actual_robot_current", "DOUBLE"),
    ("actual_joint_voltage", "VECTOR6D"),
    ("actual_digital_output_bits", "UINT64"),
    ("runtime_state", "UINT32"),
    ("joint_position_deviation_ratio", "DOUBLE"),
]
"""The ``out`` recipe of ``examples/record_configuration.xml`` at 647788c, in its order (the rest is commented out)."""
NAMES = [n for n, _ in RECORD_RECIPE]
FORMATS = {"DOUBLE": "d", "INT32": "i", "UINT32": "I", "UINT64": "Q", "VECTOR3D": "3d", "VECTOR6D": "6d"}
FORMATS["VECTOR6INT32"] = "6i"
"""RTDE types -> struct formats, as ``rtde/serialize.py`` unpacks them (big-endian)."""
WIDTHS = {"VECTOR3D": 3, "VECTOR6D": 6, "VECTOR6INT32": 6}
SAMPLES = 250
"""record.py's ``--samples``. Its loop counts from 1 and stops once the count reaches ``--samples``: it writes
``--samples - 1`` rows (249)."""
CYCLE_S = 0.008
SAFETY_MODES = {"NORMAL": 1, "PROTECTIVE_STOP": 3}
CLIENT_ENV = "DRILLGYM_UR_RTDE_CLIENT"

Row = dict[str, Any]


# ---------------------------------------------------------------------------------------------- the raw protocol
def _recv_exact(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        assert chunk, "the emulator closed the connection"
        data += chunk
    return data


def _send(sock: socket.socket, kind: str, payload: bytes = b"") -> None:
    sock.sendall(struct.pack(">HB", 3 + len(payload), ord(kind)) + payload)


def _receive(sock: socket.socket, kind: str) -> bytes:
    """The payload of the next package of ``kind``; data packages and text messages before it are skipped, as
    ``rtde/rtde.py``'s ``__recv`` does (pause and setup answers arrive after data already queued)."""
    while True:
        size, got = struct.unpack(">HB", _recv_exact(sock, 3))
        payload = _recv_exact(sock, size - 3)
        if chr(got) == kind:
            return payload
        assert chr(got) in "UM", f"unexpected package {chr(got)!r} while waiting for {kind!r}"


def _unpack(payload: bytes, recipe: list[tuple[str, str]]) -> Row:
    """One data package (recipe id, then the fields) as a row: a vector as a tuple."""
    st = struct.Struct(">B" + "".join(FORMATS[t] for _, t in recipe))
    flat = st.unpack(payload)
    assert flat[0] == 1  # the recipe id the setup answered
    row, pos = {}, 1
    for name, kind in recipe:
        width = WIDTHS.get(kind, 1)
        row[name] = tuple(flat[pos : pos + width]) if width > 1 else flat[pos]
        pos += width
    return row


def _open_recording(host: str, recipe: list[tuple[str, str]]) -> socket.socket:
    """Connect and set up as ``rtde.RTDE`` does for record.py: protocol 2, controller version, outputs, start."""
    sock = socket.create_connection((host, RTDE_PORT), timeout=5.0)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    _send(sock, "V", struct.pack(">H", 2))
    assert _receive(sock, "V") == b"\x01"
    _send(sock, "v")
    assert struct.unpack(">IIII", _receive(sock, "v"))[:2] == (3, 15)  # PolyScope 3.15: a CB3
    _send(sock, "O", struct.pack(">d", 125.0) + ",".join(n for n, _ in recipe).encode())
    answer = _receive(sock, "O")
    assert answer[0] == 1 and answer[1:].decode().split(",") == [t for _, t in recipe]  # else record.py gives up
    _send(sock, "S")
    assert _receive(sock, "S") == b"\x01"
    return sock


def _close_recording(sock: socket.socket) -> None:
    _send(sock, "P")
    assert _receive(sock, "P") == b"\x01"
    sock.close()


def _record_raw(host: str) -> list[Row]:
    """What record.py records, read on the wire: ``SAMPLES - 1`` data packages of :data:`RECORD_RECIPE`."""
    sock = _open_recording(host, RECORD_RECIPE)
    rows = [_unpack(_receive(sock, "U"), RECORD_RECIPE) for _ in range(SAMPLES - 1)]
    _close_recording(sock)
    return rows


# ---------------------------------------------------------------------------------------------- record.py itself
def _csv_header() -> list[str]:
    """``rtde/csv_writer.py``'s header: a name, or ``name_0`` ... for a vector."""
    return [f"{n}_{i}" if t in WIDTHS else n for n, t in RECORD_RECIPE for i in range(WIDTHS.get(t, 1))]


def _read_csv(path: Path) -> list[Row]:
    with path.open(newline="") as f:
        reader = csv.reader(f, delimiter=" ")
        assert next(reader) == _csv_header()  # every column of the recipe, in order
        lines = list(reader)
    rows = []
    for line in lines:
        values = iter(line)
        row: Row = {}
        for name, kind in RECORD_RECIPE:
            cast = float if kind in ("DOUBLE", "VECTOR3D", "VECTOR6D") else int
            width = WIDTHS.get(kind, 1)
            items = tuple(cast(next(values)) for _ in range(width))
            row[name] = items if width > 1 else items[0]
        assert next(values, None) is None
        rows.append(row)
    return rows


def _record_with_record_py(client: Path, host: str, out_dir: Path) -> list[Row]:
    """Run ``examples/record.py`` unmodified (its own ``record_configuration.xml``, its default 125 Hz)."""
    output = out_dir / "robot_data.csv"
    proc = subprocess.run(
        [sys.executable, "record.py", "--host", host, "--samples", str(SAMPLES), "--output", str(output)],
        cwd=client / "examples",
        env={**os.environ, "PYTHONPATH": str(client)},
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    # record.py exits 0 even when it gives up on the setup (it logs and calls sys.exit()): judge by what it wrote
    assert proc.returncode == 0 and "Complete!" in proc.stdout, proc.stdout[-500:] + proc.stderr[-2000:]
    return _read_csv(output)


# ---------------------------------------------------------------------------------------------- the check
def _dashboard(host: str, *commands: str) -> list[str]:
    with socket.create_connection((host, DASHBOARD_PORT), timeout=2.0) as s:
        f = s.makefile("rw")
        assert f.readline().startswith("Connected: Universal Robots Dashboard Server")
        replies = []
        for cmd in commands:
            f.write(cmd + "\n")
            f.flush()
            replies.append(f.readline().rstrip("\n"))
        return replies


def _record_while_moving(emu: Any, record: Callable[[], list[Row]]) -> tuple[list[Row], list[tuple[float, Any]]]:
    """Record (``record`` in a thread) while ``ur_rtde`` moves the TCP 4 mm up, then rests; meanwhile read
    ``RTDEReceiveInterface``'s (timestamp, actual_q) as often as it updates."""
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_q", "actual_TCP_pose"])
    c = rtde_control.RTDEControlInterface(emu.host)
    result: dict[str, Any] = {}

    def _run() -> None:
        try:
            result["rows"] = record()
        except BaseException as e:  # re-raised below, in the test's thread
            result["error"] = e

    try:
        target = list(r.getActualTCPPose())
        target[2] += 0.004
        thread = threading.Thread(target=_run, daemon=True)
        thread.start()
        set_up = wait_until(lambda: NAMES in emu.control({"cmd": "contract"})["output_recipes"], 30.0, 0.02)
        assert set_up, "the recorder never set up its recipe"
        assert c.moveL(target, 0.005, 0.5, True)  # asynchronous: about 0.8 s of the 2 s recorded
        seen = []
        while thread.is_alive():
            t_before, q, t_after = r.getTimestamp(), r.getActualQ(), r.getTimestamp()
            if t_before == t_after:  # no package arrived between the two reads (most of the time)
                seen.append((t_before, q))
            time.sleep(0.003)
        thread.join()
    finally:
        c.disconnect()
        r.disconnect()
    if "error" in result:
        raise result["error"]
    return result["rows"], seen


def _check_recording(emu: Any, rows: list[Row], seen: list[tuple[float, Any]]) -> None:
    assert len(rows) == SAMPLES - 1 and all(set(row) == set(NAMES) for row in rows)
    t = np.array([row["timestamp"] for row in rows])
    np.testing.assert_allclose(np.diff(t), CYCLE_S, rtol=0, atol=1e-9)  # 125 Hz, every controller cycle, in order
    # the modes the dashboard reports (the recording's state: nothing changed them since)
    robot, safety, program = _dashboard(emu.host, "robotmode", "safetymode", "programstate")
    assert {row["robot_mode"] for row in rows} == {ROBOT_MODES[robot.removeprefix("Robotmode: ")]} == {7}
    assert {row["safety_status"] for row in rows} == {SAFETY_MODES[safety.removeprefix("Safetymode: ")]} == {1}
    assert {row["runtime_state"] for row in rows} == {RuntimeState[program.split()[0]]} == {RuntimeState.PLAYING}
    # served constants stay constant (docs/deployment.md §6 lists them)
    for name in NAMES:
        if name in NOT_EMULATED:
            assert len({row[name] for row in rows}) == 1, name
    assert {row["joint_position_deviation_ratio"] for row in rows} == {0.0}
    # the arm moved, then rested: ur_rtde read, at the same controller timestamps, the recorded actual_q, or (a read
    # can straddle a package) a value within the motion between the neighbouring samples
    q = np.array([row["actual_q"] for row in rows])
    assert np.ptp(q, axis=0).max() > 1e-3  # moved (the IK step of a resting arm still changes q by ~1e-16)
    np.testing.assert_allclose(q[-1], q[-25], rtol=0, atol=1e-12)  # and came to rest
    index = {ts: i for i, ts in enumerate(t.tolist())}
    matched = exact = 0
    for ts, q_seen in seen:
        i = index.get(ts)
        if i is None or not 0 < i < len(rows) - 1:
            continue
        near = q[i - 1 : i + 2]
        assert np.all(near.min(axis=0) <= q_seen) and np.all(q_seen <= near.max(axis=0)), (ts, q_seen, near)
        matched += 1
        exact += bool(np.array_equal(q_seen, q[i]))
    assert matched >= 50 and exact >= 0.9 * matched, (matched, exact)


def test_record_recipe_on_the_wire_streams_every_field_at_125_hz(start_emulator):
    """record.py's exchange and recipe (rtde/rtde.py, examples/record_configuration.xml at 647788c), raw."""
    emu = start_emulator()
    rows, seen = _record_while_moving(emu, lambda: _record_raw(emu.host))
    _check_recording(emu, rows, seen)


def test_urs_record_py_records_the_emulator_unmodified(start_emulator, tmp_path):
    """examples/record.py at 647788c, run as it ships: ``python record.py --host H --samples 250 --output F``."""
    client = os.environ.get(CLIENT_ENV)
    if not client:
        pytest.skip(
            f"{CLIENT_ENV} names no checkout of UniversalRobots/RTDE_Python_Client_Library (commit 647788c; "
            "not on PyPI, not kept here)"
        )
    root = Path(client)
    assert (root / "examples" / "record.py").is_file() and (root / "rtde" / "rtde.py").is_file(), root
    emu = start_emulator()
    rows, seen = _record_while_moving(emu, lambda: _record_with_record_py(root, emu.host, tmp_path))
    _check_recording(emu, rows, seen)


def test_safety_status_follows_the_protective_stop(start_emulator):
    """``safety_status`` (Client Interface safety status types) equals ``safety_mode`` in every package, and
    ``safety_status_bits`` agrees (bit 0 normal, bit 2 protective stopped), through a stop and its clearing."""
    emu = start_emulator()
    recipe = [("timestamp", "DOUBLE"), ("safety_status", "INT32"), ("safety_mode", "INT32")]
    recipe.append(("safety_status_bits", "UINT32"))
    sock = _open_recording(emu.host, recipe)
    seen = []

    def _read_until(status: int) -> None:
        for _ in range(1000):  # 8 s of packages: only a broken emulator reads them all
            row = _unpack(_receive(sock, "U"), recipe)
            seen.append(row)
            if row["safety_status"] == status:
                return
        pytest.fail(f"safety_status never became {status}")

    try:
        _read_until(1)
        emu.fault("protective_stop")
        _read_until(3)
        assert emu.status()["protective_stopped"]
        emu.control({"cmd": "clear_faults"})
        _read_until(1)
    finally:
        _close_recording(sock)
    bits = {1: 1 << 0, 3: 1 << 2}
    assert all(row["safety_status"] == row["safety_mode"] for row in seen)
    assert all(row["safety_status_bits"] == bits[row["safety_status"]] for row in seen)
    assert [row["safety_status"] for row in seen][-1] == 1 and 3 in {row["safety_status"] for row in seen}
