"""Before a real run: read the F/T sensor's calibration and seed an emulated cell's specimen.

What :mod:`drillgym.eval.cli.run` (``drillgym run``) does before anything moves, as library functions.
"""

from __future__ import annotations

import sys
from typing import Any

from drillgym.envs import REAL_ENV_ID
from drillgym.envs.real.devices import split_host_port
from drillgym.envs.real.emulator.process import emulator_control
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration
from drillgym.envs.real.netft_calibration import check_calibration, read_calibration

ENV_ID = REAL_ENV_ID


def ft_calibration(ft_address: str, given: NetFTCalibration | None) -> tuple[NetFTCalibration, str]:
    """The F/T calibration to use and where it came from: the sensor's (checked against ``given``), else ``given``.

    Raises ``ValueError`` when the sensor's disagrees with ``given`` or is not in N and N·m. A sensor that
    does not answer on its TCP port leaves ``given`` (or the default), with a warning.
    """
    host, _ = split_host_port(ft_address, RDT_PORT)
    try:
        device = read_calibration(host, timeout_s=1.0)
    except OSError as e:
        used = "the given calibration" if given else "the default calibration (unchecked)"
        print(f"warning: {e}; using {used}", file=sys.stderr)  # e names host:CAL_PORT and what to check
        return (given or NetFTCalibration()), ("command line" if given else "default, unchecked")
    return check_calibration(given, device), "sensor" if given is None else "sensor, matches the command line"


def seed_emulated_specimen(host: str, seed: int) -> dict[str, Any] | None:
    """On the UR emulator, draw the next specimen from ``seed`` (as the sim's ``reset(seed=seed)``); else None.

    The emulator answers on its control port; a real controller has none there, so the probe costs one
    refused connection and changes nothing.
    """
    try:
        reply = emulator_control(host, {"cmd": "specimen", "seed": int(seed)}, timeout_s=0.5)
    except (OSError, RuntimeError):
        return None
    return {k: reply[k] for k in ("specimen", "seed", "hardness_factor", "replaced_now")}
