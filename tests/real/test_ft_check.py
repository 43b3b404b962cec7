"""``drillgym ft-check`` against the emulator: a known mass hung from the tool (the emulator's ``ft_load``)."""

import json
import math
import re

import pytest

from drillgym.eval.cli import main
from drillgym.eval.real.ft_check import STANDARD_GRAVITY_M_S2

MASS_KG = 0.5


def _check(monkeypatch, capsys, emu, load, *extra):
    """Run ft-check; when it asks for the mass, the emulator hangs ``load`` (a control request) on the sensor."""
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: emu.control({"cmd": "ft_load", **load}) and "")
    code = main(["ft-check", "--ft", emu.host, "--mass-kg", str(MASS_KG), "--average-s", "0.5", *extra])
    return code, capsys.readouterr()


def test_a_known_mass_passes_within_the_tolerance(start_emulator, monkeypatch, capsys):
    emu = start_emulator(extra_args=["--counts-per-force", "2000000"])  # read from the sensor, not assumed
    code, out = _check(monkeypatch, capsys, emu, {"mass_kg": MASS_KG}, "--json")
    result = json.loads(out.out[out.out.index("{") :])
    assert code == 0 and result["passed"] and result["calibration"]["counts_per_force"] == 2_000_000
    # m·g, independently: 0.5 kg × 9.80665 m/s² = 4.903 N, along the sensor's -z
    assert result["expected_force_n"] == pytest.approx(4.903325)
    assert result["measured_force_change_n"] == pytest.approx(MASS_KG * 9.80665, rel=0.01)
    assert result["force_change_sensor_n"][2] < 0 and math.hypot(*result["force_change_sensor_n"][:2]) < 0.05


def test_a_sensor_reading_ten_percent_high_fails_with_exit_1(start_emulator, monkeypatch, capsys):
    emu = start_emulator()
    high = {"force_n": [0.0, 0.0, -1.1 * MASS_KG * STANDARD_GRAVITY_M_S2]}
    code, out = _check(monkeypatch, capsys, emu, high)
    assert code == 1 and "FAIL" in out.out
    error_pct = float(re.search(r"\(([+-][\d.]+) %", out.out).group(1))
    assert error_pct == pytest.approx(10.0, abs=0.5)  # the 10 % it was given, within the 0.5 s means' noise


def test_a_counts_per_force_that_disagrees_with_the_sensor_is_refused(start_emulator, monkeypatch, capsys):
    emu = start_emulator()
    code, out = _check(monkeypatch, capsys, emu, {"mass_kg": MASS_KG}, "--counts-per-force", "2000000")
    assert code == 2 and "ft-check: error:" in out.err and "1e+06 counts/N" in out.err
