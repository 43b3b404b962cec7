"""The ``rtde_control`` program as the emulated controller runs it: command handshake and motions.

``ur_rtde`` uploads a URScript program that polls ``input_int_register_0`` (+ offset) every controller
cycle and answers in ``output_int_register_0``: 1 ready, 2 done. Real-time commands (``servoL``, ...) are
processed and answered "ready" every cycle; other commands run once (until done) and wait for the client to
clear the register (command 0). This class re-implements that behaviour (not the script) for the commands the
drilling cell uses; any other command is logged as unsupported and answered "done" so a client never hangs.

Any other program sent to a script port (30001, 30002, 30003) replaces the running one, as on a CB3 (URScript
manual: a program sent to the primary, secondary or real-time interface is executed at once; a ``def``
program or bare statements replace the running program, a ``sec`` program runs beside it). The emulator does
not interpret URScript: of such a program it runs only the statements :data:`EMULATED_STATEMENTS` names, top to
bottom and at once (a ``sleep`` takes no time), and logs an event naming what it did not run; the program then ends
(runtime state STOPPED, ``ur_rtde`` sees its control script stopped). The register writes are what
``ur_rtde``'s ``sendCustomScriptFunction`` waits for: it wraps the function in
``write_output_integer_register(0 +OFFSET, 1)`` ... ``write_output_integer_register(0 +OFFSET, 2)`` and polls that
register until it reads 2 (``UR_CONTROLLER_DONE_WITH_CMD``, up to 300 s), then uploads its control program again
(``ur_rtde/rtde_control_interface.cpp``, ``sendCustomScript``).

A program is ``ur_rtde``'s control program only if it is named ``rtde_control`` *and* carries the register offset
``ur_rtde`` injects (0 or 24, its lower and upper register range); a user's program that is merely named so runs as
any other program.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from drillgym.envs.real.emulator.registers import N_REGISTERS, Registers
from drillgym.envs.real.emulator.world import EmulatedCell


class RuntimeState(IntEnum):
    """``runtime_state`` of a UR controller."""

    STOPPING = 0
    STOPPED = 1
    PLAYING = 2
    PAUSING = 3
    PAUSED = 4
    RESUMING = 5


class Command(IntEnum):
    """``ur_rtde`` command ids the emulator implements (``ur_rtde/rtde.h``)."""

    NO_CMD = 0
    MOVEL = 3
    SPEED_STOP = 15
    SERVO_STOP = 16
    SERVOL = 24
    SET_TCP = 29
    STOPL = 33
    SET_WATCHDOG = 35
    STOP_SCRIPT = 255


REALTIME_COMMANDS = frozenset({24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71})
"""Commands the program processes every cycle and answers "ready" (the control loop's first branch)."""
READY = 1
DONE = 2
PROGRAM_HEADER = "def rtde_control():"
INT_OFFSET_RE = re.compile(r"reg_offset_int = # int register offset\n(\d+)")
CONTROL_SCRIPT_OFFSETS = (0, 24)
"""Register offsets ``ur_rtde`` injects into its control program (lower and upper register range)."""
DIGITAL_OUT_RE = re.compile(r"^\s*set_standard_digital_out\(\s*(\d)\s*,\s*(True|False)\s*\)\s*$")
"""Standard digital output n := b."""
_INDEX = r"(\d{1,3}(?:\s*\+\s*\d{1,3})?)"
"""A register number, or a sum of two as ``ur_rtde`` writes it (``0 +24``)."""
INT_REGISTER_RE = re.compile(rf"^\s*write_output_integer_register\(\s*{_INDEX}\s*,\s*([+-]?\d{{1,10}})\s*\)\s*$")
FLOAT_REGISTER_RE = re.compile(
    rf"^\s*write_output_float_register\(\s*{_INDEX}\s*,\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*\)\s*$"
)
EMULATED_STATEMENTS = ("set_standard_digital_out", "write_output_integer_register", "write_output_float_register")
"""The URScript statements the emulator runs in a program other than ``ur_rtde``'s (output registers 0-47)."""
INT32_RANGE = (-(2**31), 2**31 - 1)
ASYNC_RUNNING_BIT = 1 << 15
"""``ur_rtde``'s async progress register (output int 2 + offset): bit 15 set while an async move runs."""


def control_script_offset(text: str) -> int | None:
    """The register offset of ``ur_rtde``'s control program, or None if ``text`` is another program.

    It is ``ur_rtde``'s program when it starts with :data:`PROGRAM_HEADER` and carries the integer register offset
    ``ur_rtde`` injects, one of :data:`CONTROL_SCRIPT_OFFSETS`.
    """
    if not text.startswith(PROGRAM_HEADER):
        return None
    m = INT_OFFSET_RE.search(text)
    if m is None or len(m.group(1)) > 3 or int(m.group(1)) not in CONTROL_SCRIPT_OFFSETS:
        return None
    return int(m.group(1))


@dataclass
class CommandEvent:
    """One command the program started (for tests and the control port)."""

    t_s: float
    cmd: int
    detail: str = ""


class ControlProgram:
    """The running ``rtde_control`` program: one :meth:`tick` per controller cycle (8 ms)."""

    def __init__(self, registers: Registers, world: EmulatedCell, max_events: int = 10000) -> None:
        self.regs = registers
        self.world = world
        self.runtime_state = RuntimeState.STOPPED
        self.offset = 0
        self.executing = False
        self.pending: int | None = None
        self.watchdog_hz = 0.0
        self.stop_reason = ""
        self.events: list[CommandEvent] = []
        self.max_events = max_events
        self.counts: Counter[int] = Counter()
        self.unsupported: Counter[int] = Counter()
        self.servo_updates = 0
        self.servo_ticks_without_update = 0
        self.servo_active = False
        self.last_servo_pose: list[float] | None = None
        self.last_servo_params: list[float] | None = None
        self._last_packages = -1
        self.scripts_loaded = 0
        self.script_text = ""
        self.foreign_programs = 0
        self.digital_out_bits = 0
        """Standard (bits 0-7), configurable (8-15) and tool (16-17) digital outputs, as ``actual_digital_output_bits``."""
        self.async_move = False
        self._async_writes = 0
        self._async_op_id = 0
        self.robot_mode = "RUNNING"
        """``POWER_OFF``, ``IDLE`` (powered, brakes engaged) or ``RUNNING`` (dashboard ``power off``, ``power on``,
        ``brake release``); programs run only when RUNNING."""

    # ------------------------------------------------------------------ lifecycle
    def run_script(self, text: str, t_s: float, port: int) -> None:
        """A program or statements received on a script port (see the module docstring)."""
        offset = control_script_offset(text)
        if offset is not None:
            self.load(text, t_s, offset)
            return
        first = text.strip().splitlines()[0][:60] if text.strip() else ""
        secondary = text.lstrip().startswith("sec ")
        if not secondary:
            self.foreign_programs += 1
            self.stop(f"replaced by the program {first!r} sent to port {port}", t_s)
        ran, skipped = self._run_statements(text)
        kind = "secondary program (runs beside the running one)" if secondary else "program (replaced the running one)"
        self._event(
            t_s,
            -1,
            f"{kind} {first!r} on port {port}: ran {ran} statement(s) of {', '.join(EMULATED_STATEMENTS)}; "
            f"{skipped} other line(s) not emulated (URScript is not interpreted); it has ended",
        )

    def _run_statements(self, text: str) -> tuple[int, int]:
        """Run the :data:`EMULATED_STATEMENTS` of ``text`` in order; (statements run, other lines)."""
        ran = skipped = 0
        for line in text.splitlines():
            body = line.strip()
            if not body or body.startswith("#") or body == "end" or body.startswith(("def ", "sec ")):
                continue
            if self._run_statement(body):
                ran += 1
            else:
                skipped += 1
        return ran, skipped

    def _run_statement(self, body: str) -> bool:
        """Run one statement if the emulator knows it (arguments in range); whether it ran."""
        m = DIGITAL_OUT_RE.match(body)
        if m is not None:
            bit = 1 << int(m.group(1))
            self.digital_out_bits = (
                (self.digital_out_bits | bit) if m.group(2) == "True" else (self.digital_out_bits & ~bit)
            )
            return True
        m = INT_REGISTER_RE.match(body) or FLOAT_REGISTER_RE.match(body)
        if m is None:
            return False
        index = sum(int(part) for part in m.group(1).split("+"))
        if not 0 <= index < N_REGISTERS:
            return False
        if m.re is INT_REGISTER_RE:
            value = int(m.group(2))
            if not INT32_RANGE[0] <= value <= INT32_RANGE[1]:
                return False
            self.regs.output_int[index] = value
        else:
            self.regs.output_double[index] = float(m.group(2))
        return True

    def set_digital_outputs(self, mask: int, values: int, shift: int) -> None:
        """RTDE ``*_digital_output_mask`` / ``*_digital_output`` inputs (8 bits at ``shift``)."""
        m, v = (mask & 0xFF) << shift, (values & 0xFF) << shift
        self.digital_out_bits = (self.digital_out_bits & ~m) | (v & m)

    def load(self, text: str, t_s: float, offset: int) -> bool:
        """Start ``ur_rtde``'s control program with its register ``offset`` (False, and an event, if powered off)."""
        if self.robot_mode != "RUNNING":
            self.stop_reason = f"program not started: robot mode {self.robot_mode} (dashboard power on, brake release)"
            self._event(t_s, -1, self.stop_reason)
            return False
        self.offset = offset
        self.script_text = text
        self.scripts_loaded += 1
        self.runtime_state = RuntimeState.PLAYING
        self.executing = False
        self.pending = None
        self.watchdog_hz = 0.0
        self.stop_reason = ""
        self.regs.output_int[self.offset] = READY
        self.regs.output_int[self.offset + 2] = 0
        self._event(t_s, -1, f"program rtde_control started (register offset {self.offset})")
        return True

    def stop(self, reason: str, t_s: float) -> None:
        """The program ends (stop script, dashboard stop, RTDE watchdog); the arm stops."""
        if self.runtime_state in (RuntimeState.PLAYING, RuntimeState.PAUSED):
            self._event(t_s, -1, f"program stopped: {reason}")
        self.runtime_state = RuntimeState.STOPPED
        self.stop_reason = reason
        self.servo_active = False
        self.world.stop_motion()
        self._async_finished()

    def pause(self, reason: str, t_s: float) -> None:
        """Protective stop: the program pauses."""
        if self.runtime_state == RuntimeState.PLAYING:
            self.runtime_state = RuntimeState.PAUSED
            self.stop_reason = reason
            self.servo_active = False
            self._event(t_s, -1, f"program paused: {reason}")

    def resume(self, t_s: float) -> None:
        """Play again after a pause."""
        if self.runtime_state == RuntimeState.PAUSED:
            self.runtime_state = RuntimeState.PLAYING
            self._event(t_s, -1, "program resumed")

    @property
    def running(self) -> bool:
        """``runtime_state == PLAYING``."""
        return self.runtime_state == RuntimeState.PLAYING

    # ------------------------------------------------------------------ cycle
    def tick(self, t_s: float) -> None:
        """One controller cycle: watchdog, then the command register."""
        if not self.running:
            return
        regs, off = self.regs, self.offset
        if self.async_move and self.world.move_done():
            self._async_finished()
        if self.watchdog_hz > 0 and t_s - regs.input_write_t_s[off] > 1.0 / self.watchdog_hz:
            self.stop(f"RTDE watchdog: no input for {t_s - regs.input_write_t_s[off]:.3f} s", t_s)
            return
        cmd = regs.input_int[off]
        fresh = regs.packages != self._last_packages
        self._last_packages = regs.packages
        if cmd in REALTIME_COMMANDS:
            self._realtime(cmd, t_s, fresh)
            regs.output_int[off] = READY
            return
        if self.servo_active and cmd != Command.NO_CMD:
            self.servo_active = False
        if cmd == Command.NO_CMD:
            self.executing = False
            self.pending = None
            regs.output_int[off] = READY
            return
        if not self.executing:
            self.executing = True
            self._start(cmd, t_s)
        if self.pending is not None and self._finished(self.pending):
            self.pending = None
            regs.output_int[off] = DONE

    def on_input(self, t_s: float) -> None:
        """Called for every input data package: digital outputs it sets; real-time commands as they arrive."""
        names = self.regs.last_package_names
        for i, kind in enumerate(("standard", "configurable", "tool")):
            if f"{kind}_digital_output_mask" in names:
                other = self.regs.other_inputs
                mask, values = other[f"{kind}_digital_output_mask"], other.get(f"{kind}_digital_output", 0)
                self.set_digital_outputs(int(mask), int(values), 8 * i)  # type: ignore[call-overload]
        if not self.running:
            return
        cmd = self.regs.input_int[self.offset]
        if cmd not in REALTIME_COMMANDS:
            return
        self.counts[cmd] += 1
        if cmd == Command.SERVOL:
            self.servo_updates += 1
            d = self.regs.input_double[self.offset : self.offset + 11]
            self.last_servo_pose, self.last_servo_params = list(d[:6]), list(d[6:11])
        else:
            self.unsupported[cmd] += 1
            self._event(t_s, cmd, "unsupported real-time command (ignored)")

    def _realtime(self, cmd: int, t_s: float, fresh: bool) -> None:
        """A real-time command in this cycle: the newest servo target goes to the arm."""
        if cmd != Command.SERVOL or self.last_servo_pose is None:
            return
        if not self.servo_active:
            self.servo_active = True
            self._event(t_s, cmd, "servoL stream started")
        if fresh:
            self.world.servo_to(np.array(self.last_servo_pose), self.regs.last_package_t_s)
        else:
            self.servo_ticks_without_update += 1

    def _start(self, cmd: int, t_s: float) -> None:
        d = self.regs.input_double[self.offset : self.offset + 8]
        self.counts[cmd] += 1
        self.pending = cmd
        if cmd == Command.MOVEL:
            speed = d[6] * self.speed_fraction
            self.world.move_linear(np.array(d[:6]), speed, t_s)
            if self.regs.input_int[self.offset + 1] == 1:  # async: done at once, the arm keeps moving
                self._async_started()
                self.pending = None
                self.regs.output_int[self.offset] = DONE
            kind = "asynchronous moveL" if self.async_move else "moveL"
            self._event(t_s, cmd, f"{kind} to {np.round(d[:3], 6).tolist()} at {speed:.4f} m/s")
        elif cmd in (Command.SERVO_STOP, Command.STOPL, Command.SPEED_STOP):
            self.world.stop_motion()
            self._async_finished()
            self._event(t_s, cmd, f"stop (deceleration {d[0]:.2f} m/s²)")
        elif cmd == Command.SET_TCP:
            self.world.set_tcp(np.array(d[:6]))
            self._event(t_s, cmd, f"TCP set to {np.round(d[:6], 6).tolist()}")
        elif cmd == Command.SET_WATCHDOG:
            self.watchdog_hz = float(d[0])
            self._event(t_s, cmd, f"RTDE watchdog at {d[0]:.1f} Hz")
        elif cmd == Command.STOP_SCRIPT:
            self.pending = None
            self.stop("stop script command", t_s)
        else:
            self.unsupported[cmd] += 1
            self._event(t_s, cmd, "unsupported command; answered done without acting")

    @property
    def speed_fraction(self) -> float:
        """The speed slider (RTDE ``speed_slider_fraction`` under ``speed_slider_mask``), 0..1."""
        if not int(self.regs.other_inputs.get("speed_slider_mask", 0) or 0):  # type: ignore[call-overload]
            return 1.0
        value = float(self.regs.other_inputs.get("speed_slider_fraction", 1.0))  # type: ignore[arg-type]
        return min(max(value, 0.0), 1.0)

    def _write_async(self, running: bool) -> None:
        """ur_rtde's async progress register: change count in bits 16-22, operation id in 24-30, bit 15 running."""
        self._async_writes = (self._async_writes + 1) % 128
        value = (self._async_writes << 16) + (self._async_op_id << 24) + (ASYNC_RUNNING_BIT if running else 0)
        self.regs.output_int[self.offset + 2] = value

    def _async_started(self) -> None:
        self._async_op_id = (self._async_op_id + 1) % 128
        self.async_move = True
        self._write_async(True)

    def _async_finished(self) -> None:
        if self.async_move:
            self.async_move = False
            self._write_async(False)

    def _finished(self, cmd: int) -> bool:
        if cmd == Command.MOVEL:
            return self.world.move_done()
        return True

    def _event(self, t_s: float, cmd: int, detail: str) -> None:
        if len(self.events) < self.max_events:
            self.events.append(CommandEvent(t_s, cmd, detail))
