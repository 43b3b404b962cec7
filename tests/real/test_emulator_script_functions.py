"""Programs on the script ports as a CB3 takes them; each test names the behaviour and the source it follows.

Sources: ``ur_rtde`` 1.6.5's ``RTDEControlInterface::sendCustomScriptFunction`` / ``sendCustomScript``
(``rtde_control_interface.cpp``: stop the control script, send ``def NAME():`` wrapped in
``write_output_integer_register(0 +OFFSET, 1)`` ... ``(0 +OFFSET, 2)`` on its 30003 connection, poll that register
until it reads 2 for up to 300 s, then upload its control program again on the same connection and wait until it
runs); the URScript manual and UR's "Client Interface" documentation (a program sent to 30001-30003 runs at once, a
``def`` program up to its ``end``, bare statements line by line; the controller reads CRLF line ends).
"""

import socket
import threading

import pytest
import rtde_control
import rtde_receive
from real_cell import wait_until

from drillgym.envs.real.emulator.config import PRIMARY_PORT, SCRIPT_PORT, SECONDARY_PORT
from drillgym.envs.real.emulator.control import handle_control
from drillgym.envs.real.emulator.registers import Registers
from drillgym.envs.real.emulator.script import ControlProgram, RuntimeState, control_script_offset
from drillgym.envs.real.emulator.script_framing import split_programs


def _send(host, port, data):
    with socket.create_connection((host, port), timeout=2.0) as s:
        s.sendall(data)


def _frame(*chunks):
    inbox, programs = bytearray(), []
    for chunk in chunks:
        inbox.extend(chunk)
        programs += split_programs(inbox)
    return programs, bytes(inbox)


class _World:
    """What a foreign program touches of the cell: nothing but a stop."""

    def stop_motion(self):
        pass

    def seed_specimen(self, seed):
        raise AssertionError(f"reached with seed {seed}")


def test_programs_are_framed_at_their_unindented_end_with_lf_or_crlf():
    """URScript / Client Interface: a ``def`` or ``sec`` program runs once its closing ``end`` arrived (nested blocks end
    on indented ``end`` lines), bare statements line by line; CRLF ends lines as LF does; ``ur_rtde`` sends its custom
    function and its control program back to back on one connection, so one chunk may hold two programs, and a
    program may span chunks."""
    assert _frame(b"def a():\r\n  set_standard_digital_out(1, True)\r\nend\r\n") == (
        ["def a():\n  set_standard_digital_out(1, True)\nend\n"],
        b"",
    )
    two = b"def f():\n\tdef g():\n\t\tx = 1\n\tend\n\tg()\nend\ndef rtde_control():\n  y = 2\nend\n"
    assert _frame(two)[0] == [
        "def f():\n\tdef g():\n\t\tx = 1\n\tend\n\tg()\nend\n",
        "def rtde_control():\n  y = 2\nend\n",
    ]
    assert _frame(b"def a():\r\n  x = 1\r", b"\ne", b"nd\r\n") == (["def a():\n  x = 1\nend\n"], b"")
    assert _frame(b"# note\n  set_standard_digital_out(2, False)\nfoo()\ndef b():\nend\n")[0] == [
        "set_standard_digital_out(2, False)\nfoo()\n",
        "def b():\nend\n",
    ]
    assert _frame(b"sec s():\n  x = 1\n") == ([], b"sec s():\n  x = 1\n")  # waits for its end


def test_register_writes_in_a_foreign_program_run_as_ur_rtde_expects():
    """``sendCustomScriptFunction`` writes ``write_output_integer_register(0 +OFFSET, 1)`` first and ``(0 +OFFSET, 2)``
    last: the emulator runs both (the sum as written, offset 0 or 24), so the register ends at 2, the value ur_rtde
    polls for. Float registers too; an index beyond the 48 registers or a value beyond int32 is not run (logged as
    not emulated), and nothing raises."""
    regs = Registers()
    program = ControlProgram(regs, _World())  # type: ignore[arg-type]
    text = (
        "def custom():\n\twrite_output_integer_register(0 +24, 1)\n\tset_standard_digital_out(3, True)\n"
        "\twrite_output_float_register(5, -2.5e-1)\n\twrite_output_integer_register(48, 1)\n"
        "\twrite_output_integer_register(1, 4294967296)\n\tsleep(0.5)\n\twrite_output_integer_register(0 +24, 2)\nend\n"
    )
    program.run_script(text, 1.0, SCRIPT_PORT)
    assert regs.output_int[24] == 2 and regs.output_double[5] == -0.25 and regs.output_int[1] == 0
    assert program.digital_out_bits == 1 << 3 and program.runtime_state == RuntimeState.STOPPED
    assert (
        "ran 4 statement(s)" in program.events[-1].detail
        and "3 other line(s) not emulated" in program.events[-1].detail
    )


def test_only_ur_rtdes_control_program_is_taken_for_it():
    """A program is ur_rtde's control program when it is named ``rtde_control`` and carries the register offset ur_rtde
    injects (0 or 24); a user's program that is only named so (no offset, or one ur_rtde never injects, e.g. 99999,
    which used to index past the 48 registers and end the emulator) runs as any other program."""
    header = "def rtde_control():\n    global reg_offset_int = # int register offset\n"
    assert control_script_offset(header + "24    global x = 1\nend\n") == 24
    assert control_script_offset(header + "0    global x = 1\nend\n") == 0
    assert control_script_offset(header + "99999    global x = 1\nend\n") is None
    assert control_script_offset('def rtde_control():\n  textmsg("mine")\nend\n') is None
    regs = Registers()
    program = ControlProgram(regs, _World())  # type: ignore[arg-type]
    program.run_script(header + "99999    global x = 1\nend\n", 0.0, SCRIPT_PORT)
    program.tick(0.008)
    assert program.runtime_state == RuntimeState.STOPPED and program.scripts_loaded == 0


def test_the_control_port_answers_any_line():
    """The control port answers every line with one JSON reply (docs/deployment.md): a line that is not a JSON object
    with a string ``cmd`` (a list, a number, ``cmd`` not a string, nesting deeper than the JSON parser recurses) and a
    request whose argument overflows (``1e999`` as a seed) get ``"ok": false`` and the connection stays open."""

    class _Host:
        world = _World()

        def now(self):
            return 0.0

    deep = "[" * 100_000 + "]" * 100_000
    for line in ("[1]", "7", '{"cmd": 5}', deep, "nope"):
        reply, close = handle_control(_Host(), line)  # type: ignore[arg-type]
        assert reply["ok"] is False and reply["error"].startswith("bad request") and not close
    reply, close = handle_control(_Host(), '{"cmd": "specimen", "seed": 1e999}')  # type: ignore[arg-type]
    assert reply["ok"] is False and not close


@pytest.mark.realtime
def test_send_custom_script_function_returns_and_the_control_script_runs_again(start_emulator):
    """ur_rtde's ``sendCustomScriptFunction`` returns True once the function's last register write (2) is seen, then
    re-uploads its control program and waits until it runs; it used to block for its 300 s timeout because the
    emulator ran no register write. Here it must return within 10 s (a few controller cycles of work, with margin for a
    loaded machine), the function's digital output be set, and the control interface work afterwards (a short
    ``moveL`` arrives, 1 µm)."""
    emu = start_emulator()
    c = rtde_control.RTDEControlInterface(emu.host)
    r = rtde_receive.RTDEReceiveInterface(
        emu.host, 125.0, ["timestamp", "actual_digital_output_bits", "actual_TCP_pose"]
    )
    try:
        result = {}
        worker = threading.Thread(
            target=lambda: result.update(ok=c.sendCustomScriptFunction("spindle", "set_standard_digital_out(5, True)")),
            daemon=True,
        )
        worker.start()
        worker.join(10.0)
        assert result.get("ok") is True, "sendCustomScriptFunction did not return within 10 s"
        assert r.getActualDigitalOutputBits() & (1 << 5)
        assert c.isProgramRunning()
        events = [e["detail"] for e in emu.control({"cmd": "events"})["events"]]
        assert any("'def spindle():'" in e for e in events)
        pose = list(r.getActualTCPPose())
        pose[2] += 0.001
        assert c.moveL(pose, 0.05, 1.2)
        assert wait_until(lambda: abs(r.getActualTCPPose()[2] - pose[2]) < 1e-6)
    finally:
        c.stopScript()
        c.disconnect()
        r.disconnect()


@pytest.mark.realtime
@pytest.mark.parametrize("port", [PRIMARY_PORT, SECONDARY_PORT, SCRIPT_PORT])
def test_a_crlf_program_runs_like_an_lf_one(start_emulator, port):
    """The controller reads CRLF programs (a script saved on Windows): a ``def`` program with CRLF line ends and, in the
    same send, a second one run in order (standard digital outputs 4 set, then 7 set and 4 cleared), seen over RTDE
    within 1 s; they used to wait forever for an LF ``end`` line and be dropped with the connection."""
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp", "actual_digital_output_bits"])
    try:
        _send(emu.host, port, b"def on():\r\n  set_standard_digital_out(4, True)\r\nend\r\n")
        assert wait_until(lambda: r.getActualDigitalOutputBits() & (1 << 4), timeout_s=1.0)
        two = b"def a():\r\n  set_standard_digital_out(7, True)\r\nend\r\ndef b():\r\n  set_standard_digital_out(4, False)\r\nend\r\n"
        _send(emu.host, port, two)
        assert wait_until(lambda: r.getActualDigitalOutputBits() & 0b10010000 == 0b10000000, timeout_s=1.0)
    finally:
        r.disconnect()


@pytest.mark.realtime
def test_a_user_program_named_like_the_control_script_does_not_end_the_emulator(start_emulator):
    """A program named ``rtde_control`` that is not ur_rtde's (here with a register offset of 99999, which used to index
    past the 48 registers in the controller cycle and end the process) runs as a foreign program: it replaces the
    running one, the emulator keeps ticking (25 more controller cycles within 2 s) and ur_rtde can connect afterwards
    and finds its own control program running."""
    emu = start_emulator()
    program = b"def rtde_control():\n    global reg_offset_int = # int register offset\n99999    global x = 1\nend\n"
    _send(emu.host, SCRIPT_PORT, program)
    _send(emu.host, SECONDARY_PORT, b'def rtde_control():\n  textmsg("mine")\nend\n')
    assert wait_until(lambda: emu.status()["stop_reason"].startswith("replaced by the program 'def rtde_control():'"))
    ticks = emu.status()["controller_ticks"]
    assert wait_until(lambda: emu.status()["controller_ticks"] > ticks + 25)
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        assert c.isProgramRunning() and emu.status()["scripts_loaded"] == 1
    finally:
        c.stopScript()
        c.disconnect()
