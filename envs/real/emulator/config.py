"""Configuration of one emulated UR cell: addresses, ports, the physical scenario, scheduled faults."""

from __future__ import annotations

from dataclasses import dataclass, field

from drillgym.envs.errors import UserError
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration
from drillgym.envs.real.netft_calibration import CAL_PORT
from drillgym.envs.real.tracker import TRACKER_PORT
from drillgym.envs.scenario import Scenario

RTDE_PORT = 30004
DASHBOARD_PORT = 29999
SCRIPT_PORT = 30003
"""The real-time interface; ``ur_rtde`` 1.6.5 uploads its control program here (not to 30002)."""
PRIMARY_PORT = 30001
SECONDARY_PORT = 30002
"""The primary and secondary client interfaces: they take URScript too (their state stream is not emulated)."""
FT_HTTP_PORT = 8080
"""The emulated Net F/T's web page (``/netftapi2.xml``); a real sensor serves it on 80, which only root may bind."""
CONTROL_PORT = 30100
"""The emulator's own JSON control port (fault injection, status, truth); not a UR port."""
FAULT_KINDS = ("protective_stop", "drop_link", "delay", "freeze_rtde", "stale_ft", "stale_tracker")


@dataclass(frozen=True)
class ScheduledFault:
    """A fault injected ``after_s`` seconds after the first ``servoL`` of the emulator's life."""

    kind: str
    after_s: float
    value: float = 0.0
    """``delay``: seconds of delay; ``drop_link``, ``freeze_rtde``: seconds (0: until cleared)."""

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise UserError(f"fault kind {self.kind!r}; choose from {FAULT_KINDS}")
        if self.after_s < 0 or self.value < 0:
            raise UserError(f"fault {self.kind}: times must be >= 0, got after {self.after_s}, value {self.value}")

    @classmethod
    def parse(cls, text: str) -> ScheduledFault:
        """``KIND@SECONDS`` or ``KIND:VALUE@SECONDS`` (e.g. ``protective_stop@3``, ``delay:0.02@1``)."""
        head, at, when = text.partition("@")
        if not at:
            raise UserError(f"fault {text!r}: expected KIND[:VALUE]@SECONDS")
        kind, _, value = head.partition(":")
        return cls(kind, float(when), float(value) if value else 0.0)


@dataclass
class EmulatorConfig:
    """Everything an emulator process needs."""

    host: str = "127.0.0.1"
    """Loopback address to serve on (127.0.0.0/8 only)."""
    scenario: Scenario = field(default_factory=Scenario)
    seed: int = 0
    rtde_port: int = RTDE_PORT
    dashboard_port: int = DASHBOARD_PORT
    script_port: int = SCRIPT_PORT
    primary_port: int = PRIMARY_PORT
    secondary_port: int = SECONDARY_PORT
    control_port: int = CONTROL_PORT
    ft_port: int = RDT_PORT
    ft_cal_port: int = CAL_PORT
    """The Net F/T's TCP interface (``READCALINFO``: its counts per N and per N·m)."""
    ft_http_port: int = FT_HTTP_PORT
    """The Net F/T's web server (``/netftapi2.xml``); a real sensor serves it on 80."""
    ft_rdt_buffer_size: int = 1
    """Records per packet of buffered RDT streaming (the sensor's "RDT buffer size", 1-40)."""
    tracker_port: int = TRACKER_PORT
    ft_rate_hz: float = 500.0
    """Net F/T record rate (Hz)."""
    tracker_rate_hz: float = 60.0
    calibration: NetFTCalibration = field(default_factory=NetFTCalibration)
    max_lifetime_s: float = 3600.0
    """The process exits by itself after this long (s)."""
    parent_pid: int | None = None
    """Exit when this process is gone (the test or tool that started the emulator)."""
    faults: tuple[ScheduledFault, ...] = ()

    def __post_init__(self) -> None:
        if not self.host.startswith("127."):
            raise UserError(f"host={self.host!r}: the emulator serves on loopback (127.0.0.0/8) only")
        if not 100.0 <= self.ft_rate_hz <= 7000.0:
            raise UserError(f"ft_rate_hz={self.ft_rate_hz} outside [100, 7000]")
        if not 1 <= self.ft_rdt_buffer_size <= 40:
            raise UserError(f"ft_rdt_buffer_size={self.ft_rdt_buffer_size} outside [1, 40]")
        if not 1.0 <= self.tracker_rate_hz <= 500.0:
            raise UserError(f"tracker_rate_hz={self.tracker_rate_hz} outside [1, 500]")
