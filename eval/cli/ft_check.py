"""``drillgym ft-check``: check the F/T sensor's force scale with a known mass (:mod:`drillgym.eval.real.ft_check`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from drillgym.envs.errors import UserError
from drillgym.eval.real.ft_check import check


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``ft-check``."""
    parser.add_argument("--ft", required=True, help="Net F/T HOST[:PORT] (RDT port; the calibration is read on 49151)")
    parser.add_argument("--mass-kg", type=float, required=True, help="the known mass to hang from the tool (kg)")
    parser.add_argument(
        "--tolerance-pct", type=float, default=5.0, help="largest relative error of the force change vs m·g (%%)"
    )
    parser.add_argument("--average-s", type=float, default=1.0, help="averaging time of each reading (s)")
    parser.add_argument(
        "--settle-s",
        type=float,
        default=0.5,
        help="records ignored after the mass is hung, while it stops swinging and the reading settles (s)",
    )
    parser.add_argument(
        "--wait-s",
        type=float,
        default=None,
        help="do not ask: wait this long after the unloaded reading, then read the loaded one (s)",
    )
    parser.add_argument(
        "--counts-per-force", type=float, default=None, help="expected counts per N (checked against the sensor's)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    """Read the calibration, take the two readings, report; 1 if the force scale is off."""
    from drillgym.envs.real.devices import split_host_port
    from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration, NetFTClient
    from drillgym.envs.real.netft_calibration import check_calibration, read_calibration

    if not (math.isfinite(args.mass_kg) and args.mass_kg > 0):
        raise UserError(f"--mass-kg={args.mass_kg:g} must be > 0")
    if not args.tolerance_pct > 0 or not args.average_s > 0 or (args.wait_s is not None and args.wait_s < 0):
        raise UserError("--tolerance-pct and --average-s must be > 0, --wait-s >= 0")
    if not args.settle_s >= 0:
        raise UserError(f"--settle-s={args.settle_s} must be >= 0")
    host, port = split_host_port(args.ft, RDT_PORT)
    given = None if args.counts_per_force is None else NetFTCalibration(args.counts_per_force)
    device = read_calibration(host)
    calibration = check_calibration(
        None if given is None else NetFTCalibration(given.counts_per_force, device.calibration.counts_per_torque),
        device,
    )
    if args.wait_s is None and not sys.stdin.isatty():
        raise UserError("stdin is not a terminal: cannot ask when the mass hangs; pass --wait-s")

    def wait() -> None:
        if args.wait_s is not None:
            time.sleep(args.wait_s)
            return
        input(f"Hang the {args.mass_kg:g} kg mass from the tool, let it settle, then press Enter: ")

    ft = NetFTClient(host, port, calibration)
    try:
        if args.wait_s is None:
            print(f"Unloaded reading ({args.average_s:g} s): keep the tool still, nothing attached.")
        result = check(ft, args.mass_kg, args.tolerance_pct, args.average_s, wait, args.settle_s)
    finally:
        ft.close()
    result["calibration"] = {"counts_per_force": calibration.counts_per_force, "source": "sensor (READCALINFO)"}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        verdict = "PASS" if result["passed"] else "FAIL: the force scale is off; do not drill"
        print(
            f"ft-check {host}:{port}: {calibration.counts_per_force:g} counts/N (from the sensor); "
            f"{args.mass_kg:g} kg -> expected {result['expected_force_n']:.3f} N, measured "
            f"{result['measured_force_change_n']:.3f} N ({result['error_pct']:+.2f} %, tolerance "
            f"±{args.tolerance_pct:g} %, noise {result['noise_n']:.3f} N): {verdict}"
        )
    return 0 if result["passed"] else 1
