"""The dashboard server (TCP 29999) of a CB3: a welcome line, then one reply line per command line.

Answer texts are UR's (Dashboard Server manual for CB3, "Dashboard Server, port 29999"): ``load`` answers
``Loading program: <p>`` or ``File not found: <p>``; ``get loaded program`` ``Loaded program: <p>`` or
``No program loaded``; ``power on`` ``Powering on``; ``power off`` ``Powering off``; ``brake release``
``Brake releasing``; ``get robot model`` the model (``UR5``). The emulator has no program files: ``load`` of any
``.urp`` answers ``File not found`` (and its log says why), so a client never believes a program was loaded.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from drillgym.envs.real.emulator.script import ControlProgram, RuntimeState

WELCOME = "Connected: Universal Robots Dashboard Server\n"
ROBOT_MODEL = "UR5"
UNLOCK_REFUSED = (
    "Cannot unlock protective stop until 5s after occurrence. Always inspect cause of protective stop before unlocking"
)
"""UR's answer to ``unlock protective stop`` sent within 5 s of the stop (Dashboard Server manual)."""
POLYSCOPE_VERSION = "URSoftware 3.15.7.106331 (Sep 07 2022)"
COMMANDS_KEPT = 100


class Dashboard:
    """Answers dashboard commands from the emulated controller's state.

    Args:
        program: the control program (play/stop/pause state).
        protective_stopped: whether the arm is protective-stopped.
        unlock: releases a protective stop at the given time; False when refused (within 5 s of the stop).
    """

    def __init__(
        self, program: ControlProgram, protective_stopped: Callable[[], bool], unlock: Callable[[float], bool]
    ) -> None:
        self.program = program
        self.protective_stopped = protective_stopped
        self.unlock = unlock
        self.commands: deque[str] = deque(maxlen=COMMANDS_KEPT)
        """The latest commands (bounded: a client may send any number)."""
        self.notes: list[str] = []
        """What a reply left out (the emulator's log prints these)."""

    def reply(self, line: str, t_s: float) -> tuple[str, bool]:
        """Reply (without newline) to one command line, and whether to close the connection."""
        cmd = line.strip()
        self.commands.append(cmd)
        prog = self.program
        safety = "PROTECTIVE_STOP" if self.protective_stopped() else "NORMAL"
        simple = {
            "polyscopeversion": POLYSCOPE_VERSION,
            "robotmode": f"Robotmode: {prog.robot_mode}",
            "get robot model": ROBOT_MODEL,
            "get loaded program": "No program loaded",
            "safetymode": f"Safetymode: {safety}",
            "safetystatus": f"Safetystatus: {safety}",
            "programstate": f"{prog.runtime_state.name} rtde_control",
            "running": f"Program running: {'true' if prog.running else 'false'}",
            "close safety popup": "closing safety popup",
            "is in remote control": "true",
        }
        low = cmd.lower()
        if low in simple:
            return simple[low], False
        if low == "stop":
            prog.stop("dashboard stop", t_s)
            return "Stopped", False
        if low == "pause":
            prog.pause("dashboard pause", t_s)
            return "Pausing program", False
        if low == "play":
            if prog.runtime_state == RuntimeState.PAUSED and not self.protective_stopped():
                prog.resume(t_s)
                return "Starting program", False
            return "Failed to execute: Play", False
        power = self._power_or_load(cmd, t_s)
        if power is not None:
            return power, False
        if low == "unlock protective stop":
            return ("Protective stop releasing" if self.unlock(t_s) else UNLOCK_REFUSED), False
        if low == "quit":
            return "Disconnected", True
        return f"Could not understand: '{cmd}'", False

    def _power_or_load(self, cmd: str, t_s: float) -> str | None:
        """The arm's power and brakes, and ``load``; None for any other command."""
        prog, low = self.program, cmd.lower()
        if low == "power off":
            prog.stop("power off", t_s)
            prog.robot_mode = "POWER_OFF"
            return "Powering off"
        if low == "power on":
            if prog.robot_mode == "POWER_OFF":
                prog.robot_mode = "IDLE"
            return "Powering on"
        if low == "brake release":
            if prog.robot_mode == "IDLE":
                prog.robot_mode = "RUNNING"
            return "Brake releasing"
        if low.startswith("load ") and not low.startswith("load installation"):
            name = cmd[5:].strip()
            self.notes.append(f"load {name!r}: the emulator has no program files (not emulated)")
            return f"File not found: {name}"
        return None
