"""The Net F/T's own calibration over its TCP interface (port 49151): what its counts mean.

ATI Net F/T manual, "TCP Interface", big-endian:

* ``READCALINFO`` request, 20 bytes: ``uint8 command = 1`` and 19 reserved zero bytes;
* response, 24 bytes: ``uint16 0x1234, uint8 force_units, uint8 torque_units, uint32 counts_per_force,
  uint32 counts_per_torque, uint16 scale_factors[6]``. Unit codes: force 1 lbf, 2 N, 3 klbf, 4 kN, 5 kgf,
  6 gf; torque 1 lbf·in, 2 lbf·ft, 3 N·m, 4 N·mm, 5 kgf·cm, 6 kN·m.

The same numbers are on the sensor's web page (``netftapi2.xml``: ``cfgcpf``, ``cfgcpt``, ``scfgfu``,
``scfgtu``). ``drillgym run`` reads them before moving and refuses to run when they disagree with what it
was told: a wrong counts-per-force rescales every force, the force limit included.
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass

from drillgym.envs.errors import UserError
from drillgym.envs.real.net_errors import connect_error
from drillgym.envs.real.netft import RDT_HEADER, NetFTCalibration

CAL_PORT = 49151
CMD_READCALINFO = 1
CAL_REQUEST = struct.Struct(">B19x")
CAL_RESPONSE = struct.Struct(">HBBII6H")
FORCE_UNITS = {1: "lbf", 2: "N", 3: "klbf", 4: "kN", 5: "kgf", 6: "gf"}
TORQUE_UNITS = {1: "lbf-in", 2: "lbf-ft", 3: "N-m", 4: "N-mm", 5: "kgf-cm", 6: "kN-m"}
SI_UNITS = (2, 3)
"""N and N·m: the only units drillgym reads (its forces are SI throughout)."""


@dataclass(frozen=True)
class DeviceCalibration:
    """What the sensor reports: counts per unit and its units."""

    calibration: NetFTCalibration
    force_units: str
    torque_units: str

    @property
    def si(self) -> bool:
        """Whether the sensor reports in N and N·m."""
        return (self.force_units, self.torque_units) == ("N", "N-m")


def pack_calinfo_request() -> bytes:
    """A 20-byte ``READCALINFO`` request."""
    return CAL_REQUEST.pack(CMD_READCALINFO)


def pack_calinfo(calibration: NetFTCalibration, force_unit: int = 2, torque_unit: int = 3) -> bytes:
    """The sensor's 24-byte answer (units N and N·m unless told otherwise; scale factors 1)."""
    return CAL_RESPONSE.pack(
        RDT_HEADER,
        force_unit,
        torque_unit,
        round(calibration.counts_per_force),
        round(calibration.counts_per_torque),
        *([1] * 6),
    )


def unpack_calinfo(data: bytes) -> DeviceCalibration:
    """Parse a ``READCALINFO`` answer; ``ValueError`` if it is not one."""
    if len(data) < CAL_RESPONSE.size:
        raise UserError(f"calibration answer too short ({len(data)} bytes)")
    header, fu, tu, cpf, cpt, *_ = CAL_RESPONSE.unpack_from(data)
    if header != RDT_HEADER:
        raise UserError(f"not a Net F/T calibration answer (header 0x{header:04x})")
    return DeviceCalibration(
        NetFTCalibration(float(cpf), float(cpt)), FORCE_UNITS.get(fu, f"code {fu}"), TORQUE_UNITS.get(tu, f"code {tu}")
    )


def read_calibration(host: str, port: int = CAL_PORT, timeout_s: float = 2.0) -> DeviceCalibration:
    """Ask the sensor at ``host`` for its calibration.

    Raises ``OSError`` if it does not answer (its message names ``host:port`` and what to check), ``ValueError``
    if the answer is not a calibration.
    """
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as s:
            s.sendall(pack_calinfo_request())
            data = b""
            while len(data) < CAL_RESPONSE.size:
                chunk = s.recv(CAL_RESPONSE.size - len(data))
                if not chunk:
                    break
                data += chunk
    except OSError as e:
        raise connect_error(e, host, port, "the F/T sensor's calibration (Net F/T TCP interface)") from e
    return unpack_calinfo(data)


def check_calibration(given: NetFTCalibration | None, device: DeviceCalibration) -> NetFTCalibration:
    """The calibration to use: the device's, checked against the one the user gave (if any).

    Raises ``ValueError`` when the device reports other units than N and N·m, or counts that differ from
    ``given`` by more than one count.
    """
    if not device.si:
        raise UserError(
            f"the F/T sensor reports forces in {device.force_units} and torques in {device.torque_units}; "
            "set it to N and N-m (its web page, Settings) before drilling"
        )
    dev = device.calibration
    if given is not None and (
        abs(given.counts_per_force - dev.counts_per_force) > 1
        or abs(given.counts_per_torque - dev.counts_per_torque) > 1
    ):
        raise UserError(
            f"the F/T sensor's calibration is {dev.counts_per_force:g} counts/N and {dev.counts_per_torque:g} "
            f"counts/N-m, but --counts-per-force {given.counts_per_force:g} and --counts-per-torque "
            f"{given.counts_per_torque:g} were given: every force (the force limit included) would be scaled wrong"
        )
    return dev
