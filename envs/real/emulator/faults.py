"""Injected faults of the emulated cell: what is active, and the schedule given on the command line."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from drillgym.envs.errors import UserError
from drillgym.envs.real.emulator.config import FAULT_KINDS, ScheduledFault

if TYPE_CHECKING:
    from drillgym.envs.real.emulator.script import ControlProgram
    from drillgym.envs.real.emulator.world import EmulatedCell


class FaultTarget(Protocol):
    """What a fault acts on: the emulator's cell, its control program and its robot ports."""

    world: EmulatedCell
    program: ControlProgram
    first_servo_t_s: float | None
    """Emulator time of the first ``servoL`` (s), None before it; scheduled faults count from it."""

    def log(self, line: str) -> None:
        """Write one line to the emulator's log."""
        ...

    def drop_link(self) -> None:
        """Close the robot ports and every connection on them."""
        ...

    def open_robot_ports(self) -> None:
        """Listen on the robot ports again."""
        ...

    def unlock_protective_stop(self, t_s: float, wait: bool = True) -> bool:
        """Release a protective stop at emulator time ``t_s`` (s); whether it was released."""
        ...


@dataclass
class FaultState:
    """Active faults; :meth:`apply` switches one on, :meth:`clear` all off."""

    scheduled: list[ScheduledFault] = field(default_factory=list)
    delay_s: float = 0.0
    """Every RTDE data package leaves this late (s)."""
    freeze_rtde_until_s: float | None = None
    """No RTDE data packages until then (connections stay open; inf: until cleared)."""
    stale_ft: bool = False
    """The Net F/T stops sending records."""
    stale_tracker: bool = False
    link_down_until_s: float | None = None
    """The robot ports are closed until then (inf: until cleared)."""
    history: list[str] = field(default_factory=list)

    def apply(self, emulator: FaultTarget, kind: str, value: float, t_s: float) -> None:
        """Switch on fault ``kind`` (``value``: delay in s, or link-down duration in s, 0 = until cleared)."""
        if kind not in FAULT_KINDS:
            raise UserError(f"fault kind {kind!r}; choose from {FAULT_KINDS}")
        self.history.append(f"{t_s:.3f} {kind} {value:g}")
        emulator.log(f"fault injected: {kind} ({value:g})")
        if kind == "protective_stop":
            emulator.world.protective_stop(t_s)
            emulator.program.pause("protective stop", t_s)
        elif kind == "drop_link":
            emulator.drop_link()
            self.link_down_until_s = t_s + value if value > 0 else math.inf
        elif kind == "delay":
            self.delay_s = value
        elif kind == "freeze_rtde":
            self.freeze_rtde_until_s = t_s + value if value > 0 else math.inf
        elif kind == "stale_ft":
            self.stale_ft = True
        elif kind == "stale_tracker":
            self.stale_tracker = True

    def clear(self, emulator: FaultTarget, t_s: float) -> None:
        """Every fault off: link restored, protective stop released, program resumed if it was paused."""
        self.delay_s = 0.0
        self.freeze_rtde_until_s = None
        self.stale_ft = self.stale_tracker = False
        if self.link_down_until_s is not None:
            self.link_down_until_s = None
            emulator.open_robot_ports()
        if emulator.world.halted:
            emulator.unlock_protective_stop(t_s, wait=False)
            emulator.program.resume(t_s)
        self.history.append(f"{t_s:.3f} clear")

    def fire_scheduled(self, emulator: FaultTarget, t_s: float) -> None:
        """Inject the scheduled faults that are due (times count from the first ``servoL``)."""
        if not self.scheduled or emulator.first_servo_t_s is None:
            return
        for fault in [f for f in self.scheduled if t_s - emulator.first_servo_t_s >= f.after_s]:
            self.scheduled.remove(fault)
            self.apply(emulator, fault.kind, fault.value, t_s)

    def rtde_frozen(self, t_s: float) -> bool:
        """Whether RTDE output is frozen at ``t_s``."""
        if self.freeze_rtde_until_s is not None and t_s >= self.freeze_rtde_until_s:
            self.freeze_rtde_until_s = None
        return self.freeze_rtde_until_s is not None

    def expire(self, emulator: FaultTarget, t_s: float) -> None:
        """Bring a temporarily dropped link back up."""
        if self.link_down_until_s is not None and t_s >= self.link_down_until_s:
            self.link_down_until_s = None
            emulator.open_robot_ports()
            emulator.log("link restored")

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "delay_s": self.delay_s,
            "freeze_rtde": self.freeze_rtde_until_s is not None,
            "stale_ft": self.stale_ft,
            "stale_tracker": self.stale_tracker,
            "link_down": self.link_down_until_s is not None,
            "scheduled": [f"{f.kind}:{f.value:g}@{f.after_s:g}" for f in self.scheduled],
            "history": list(self.history),
        }
