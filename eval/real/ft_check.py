"""Check the F/T sensor's force scale with a known mass before drilling.

The command is :mod:`drillgym.eval.cli.ft_check`.

Reads the sensor's calibration from the sensor itself (Net F/T TCP 49151, ``READCALINFO``; refused when it is not
in N and N·m, or disagrees with ``--counts-per-force``), averages the force unloaded, asks for the known mass to be
hung from the tool (or waits ``--wait-s`` without asking), averages again, and compares the magnitude of the force
change with m·g (g = 9.80665 m/s², standard gravity; local g differs by less than 0.3 %). Exit status 0 when the
relative error is within ``--tolerance-pct``, 1 when not (the force scale is wrong: do not drill), 2 on bad
input or a sensor that cannot be read.

The emulator takes a known load on its control port (``{"cmd": "ft_load", "mass_kg": M}``), so the check can
be tried without a sensor.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

STANDARD_GRAVITY_M_S2 = 9.80665


def _mean_force_n(ft: Any, duration_s: float) -> tuple[np.ndarray, float, int]:
    """Mean force (N, sensor frame) over ``duration_s``, its per-axis standard deviation's norm, the count."""
    t0 = time.monotonic()
    time.sleep(duration_s)
    records = ft.since(t0)
    if len(records) < 10:
        where = "{}:{}".format(*ft.address) if hasattr(ft, "address") else "the sensor"
        raise OSError(
            f"only {len(records)} F/T records from {where} in {duration_s:g} s: is the sensor streaming? "
            "check its RDT port (--ft HOST:PORT) and that no firewall drops UDP from it"
        )
    forces = np.array([r.wrench[:3] for r in records])
    return forces.mean(axis=0), float(np.linalg.norm(forces.std(axis=0))), len(records)


def check(
    ft: Any, mass_kg: float, tolerance_pct: float, average_s: float, wait: Any, settle_s: float = 0.5
) -> dict[str, Any]:
    """Unloaded and loaded force means around ``wait()`` (which returns once the mass hangs); the verdict.

    The loaded mean starts ``settle_s`` after ``wait()`` returns: a hung mass swings, and the records in flight
    when it was hung still hold the unloaded force.
    """
    unloaded, noise0, n0 = _mean_force_n(ft, average_s)
    wait()
    time.sleep(settle_s)
    loaded, noise1, n1 = _mean_force_n(ft, average_s)
    delta = loaded - unloaded
    expected = mass_kg * STANDARD_GRAVITY_M_S2
    measured = float(np.linalg.norm(delta))
    error_pct = 100.0 * (measured - expected) / expected
    return {
        "mass_kg": mass_kg,
        "expected_force_n": expected,
        "measured_force_change_n": measured,
        "force_change_sensor_n": delta.tolist(),
        "error_pct": error_pct,
        "tolerance_pct": tolerance_pct,
        "noise_n": max(noise0, noise1),
        "records": [n0, n1],
        "passed": abs(error_pct) <= tolerance_pct,
    }
