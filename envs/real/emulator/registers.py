"""The controller's RTDE register file: what clients write (inputs) and what the program writes (outputs)."""

from __future__ import annotations

from dataclasses import dataclass, field

N_REGISTERS = 48


@dataclass
class Registers:
    """Input and output registers of the emulated controller, shared by every RTDE connection."""

    input_int: list[int] = field(default_factory=lambda: [0] * N_REGISTERS)
    input_double: list[float] = field(default_factory=lambda: [0.0] * N_REGISTERS)
    output_int: list[int] = field(default_factory=lambda: [0] * N_REGISTERS)
    output_double: list[float] = field(default_factory=lambda: [0.0] * N_REGISTERS)
    other_inputs: dict[str, object] = field(default_factory=dict)
    """Inputs that are not numbered registers (IO masks, ``external_force_torque``, ...)."""
    input_write_t_s: list[float] = field(default_factory=lambda: [-1.0] * N_REGISTERS)
    """When each input int register was last written (emulator clock, s): the RTDE watchdog reads it."""
    packages: int = 0
    """Input data packages received."""
    last_package_t_s: float = -1.0
    last_package_names: tuple[str, ...] = ()
    """The fields of the newest input data package."""

    def write(self, name: str, value: object, t_s: float) -> None:
        """Store one input field of a data package."""
        if name.startswith("input_int_register_"):
            i = int(name.rsplit("_", 1)[1])
            self.input_int[i] = int(value)  # type: ignore[call-overload]
            self.input_write_t_s[i] = t_s
        elif name.startswith("input_double_register_"):
            self.input_double[int(name.rsplit("_", 1)[1])] = float(value)  # type: ignore[arg-type]
        else:
            self.other_inputs[name] = value

    def read_output(self, name: str) -> object | None:
        """An output or input register named ``name``, or None if it is not a register."""
        kind, _, index = name.rpartition("_")
        if not index.isdigit():
            return None
        i = int(index)
        tables: dict[str, list[int] | list[float]] = {
            "output_int_register": self.output_int,
            "output_double_register": self.output_double,
            "input_int_register": self.input_int,
            "input_double_register": self.input_double,
        }
        table = tables.get(kind)
        return table[i] if table is not None and i < N_REGISTERS else None
