"""``drillgym emulate``: a UR CB3 controller + ATI Net F/T + marker stream on a loopback address.

Run it in its own process (``ur_rtde``'s constructors hold the GIL, so an in-process emulator deadlocks);
connect ``ur_rtde`` (or ``drillgym run --robot HOST``) to the printed address. Ends on Ctrl-C / SIGTERM,
a ``{"cmd": "shutdown"}`` on the control port, or after ``--max-lifetime-s``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import signal
from typing import Any

from drillgym.envs.errors import UserError
from drillgym.envs.key_values import convert, split_items
from drillgym.envs.real.emulator.config import (
    CONTROL_PORT,
    DASHBOARD_PORT,
    FT_HTTP_PORT,
    PRIMARY_PORT,
    RTDE_PORT,
    SCRIPT_PORT,
    SECONDARY_PORT,
    EmulatorConfig,
    ScheduledFault,
)
from drillgym.envs.real.emulator.server import Emulator
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration
from drillgym.envs.real.netft_calibration import CAL_PORT
from drillgym.envs.real.tracker import TRACKER_PORT
from drillgym.envs.scenario import Scenario


def parse_scenario(text: str | None) -> Scenario:
    """A scenario from JSON (``{"beta_deg": 20}``) or ``key=value,key=value`` (user units, as the env takes)."""
    if not text:
        return Scenario()
    if text.lstrip().startswith("{"):
        try:
            values = json.loads(text)
        except json.JSONDecodeError as e:
            raise UserError(f"--scenario {text!r}: not valid JSON ({e})") from e
        return Scenario.from_kwargs(**values)
    types = {f.name: f.type for f in dataclasses.fields(Scenario)}
    items = split_items(text, f"--scenario {text!r} (keys: {', '.join(sorted(types))})")
    unknown = sorted(set(items) - set(types))
    if unknown:
        raise UserError(f"--scenario: unknown key(s) {unknown}; expected key=value with key in {sorted(types)}")
    # text and flags as they are; every other field is a number (user units, as the env takes)
    kinds = {key: str(types[key]) if str(types[key]) in ("str", "bool") else float for key in items}
    kwargs: dict[str, Any] = {key: convert(key, raw, kinds[key]) for key, raw in items.items()}
    return Scenario.from_kwargs(**kwargs)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``emulate``."""
    parser.add_argument("--host", default="127.0.0.1", help="loopback address to serve on (127.0.0.0/8)")
    parser.add_argument("--scenario", default=None, help="physical cell: JSON or key=value,... (env arguments)")
    parser.add_argument("--seed", type=int, default=0, help="specimen seed (same meaning as the sim's reset seed)")
    parser.add_argument("--ft-rate-hz", type=float, default=500.0, help="Net F/T record rate (Hz)")
    parser.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="KIND[:VALUE]@SECONDS",
        help="inject a fault SECONDS after the first servoL: protective_stop, drop_link[:SECONDS], delay:SECONDS, "
        "freeze_rtde[:SECONDS], stale_ft, stale_tracker (repeatable)",
    )
    parser.add_argument(
        "--counts-per-force",
        type=float,
        default=NetFTCalibration.counts_per_force,
        help="the emulated Net F/T's calibration: counts per N (served on its TCP port, READCALINFO)",
    )
    parser.add_argument(
        "--counts-per-torque", type=float, default=NetFTCalibration.counts_per_torque, help="counts per N·m"
    )
    parser.add_argument("--ft-cal-port", type=int, default=CAL_PORT, help="the Net F/T's TCP port (calibration)")
    parser.add_argument(
        "--ft-http-port",
        type=int,
        default=FT_HTTP_PORT,
        help=f"the Net F/T's web server (/netftapi2.xml; a real sensor: 80, here {FT_HTTP_PORT}: no root needed)",
    )
    parser.add_argument(
        "--ft-rdt-buffer-size", type=int, default=1, help="records per packet of buffered RDT streaming (1-40)"
    )
    parser.add_argument("--max-lifetime-s", type=float, default=3600.0, help="exit by itself after this long (s)")
    parser.add_argument("--parent-pid", type=int, default=None, help="exit when this parent process is gone")
    for name, port in (
        ("rtde", RTDE_PORT),
        ("dashboard", DASHBOARD_PORT),
        ("script", SCRIPT_PORT),
        ("primary", PRIMARY_PORT),
        ("secondary", SECONDARY_PORT),
        ("control", CONTROL_PORT),
        ("ft", RDT_PORT),
        ("tracker", TRACKER_PORT),
    ):
        parser.add_argument(f"--{name}-port", type=int, default=port, help=f"{name} port (default {port})")


def config_from_args(args: argparse.Namespace) -> EmulatorConfig:
    """The emulator configuration the options describe."""
    return EmulatorConfig(
        host=args.host,
        scenario=parse_scenario(args.scenario),
        seed=args.seed,
        rtde_port=args.rtde_port,
        dashboard_port=args.dashboard_port,
        script_port=args.script_port,
        primary_port=args.primary_port,
        secondary_port=args.secondary_port,
        control_port=args.control_port,
        ft_port=args.ft_port,
        ft_cal_port=args.ft_cal_port,
        ft_http_port=args.ft_http_port,
        ft_rdt_buffer_size=args.ft_rdt_buffer_size,
        calibration=NetFTCalibration(args.counts_per_force, args.counts_per_torque),
        tracker_port=args.tracker_port,
        ft_rate_hz=args.ft_rate_hz,
        max_lifetime_s=args.max_lifetime_s,
        parent_pid=args.parent_pid,
        faults=tuple(ScheduledFault.parse(f) for f in args.fault),
    )


def run(args: argparse.Namespace) -> int:
    """Serve until told to stop."""
    emulator = Emulator(config_from_args(args))

    def _stop(_signum: int, _frame: object) -> None:
        emulator.shutdown = True

    previous = {sig: signal.signal(sig, _stop) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        return emulator.run()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
