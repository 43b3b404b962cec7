"""What the emulator's control port and state packages read of the running emulator.

:class:`EmulatorHost` is the interface :mod:`~drillgym.envs.real.emulator.control` and
:mod:`~drillgym.envs.real.emulator.state` are written against;
:class:`drillgym.envs.real.emulator.server.Emulator` implements it. The helpers never import the server,
so the server imports them and no module imports back.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from drillgym.envs.real.emulator.faults import FaultTarget

if TYPE_CHECKING:
    from drillgym.envs.real.emulator.config import EmulatorConfig
    from drillgym.envs.real.emulator.faults import FaultState
    from drillgym.envs.real.emulator.registers import Registers
    from drillgym.envs.real.emulator.rtde_server import RtdeConnection
    from drillgym.envs.real.emulator.sensor_streams import SensorStreams


class EmulatorHost(FaultTarget, Protocol):
    """The running emulator as its helpers see it (besides :class:`FaultTarget`'s cell, program and ports).

    Attributes:
        config: how it was started.
        faults: the injected faults.
        regs: the RTDE registers (inputs the client wrote, package counts).
        rtde: open RTDE connections.
        sensors: the F/T and tracker streams.
        output_recipes: the RTDE output recipes set up so far (field names).
        input_recipes: the RTDE input recipes set up so far (field names).
        controller_ticks: 125 Hz controller ticks so far.
        late_ticks: ticks that came late.
        shutdown: set to stop the emulator's loop.
    """

    config: EmulatorConfig
    faults: FaultState
    regs: Registers
    rtde: list[RtdeConnection]
    sensors: SensorStreams
    output_recipes: list[list[str]]
    input_recipes: list[list[list[str]]]
    controller_ticks: int
    late_ticks: int
    shutdown: bool

    def now(self) -> float:
        """Emulator time (s)."""
        ...
