"""The Net F/T's calibration: read from the sensor (TCP READCALINFO), checked against the command line."""

import json

import pytest
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.envs.real.netft import NetFTCalibration
from drillgym.envs.real.netft_calibration import (
    DeviceCalibration,
    check_calibration,
    pack_calinfo,
    pack_calinfo_request,
    read_calibration,
    unpack_calinfo,
)
from drillgym.eval.cli import main
from drillgym.eval.logs import read_episode_log

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)


def test_the_wire_format_is_atis():
    request = pack_calinfo_request()
    assert len(request) == 20 and request[0] == 1 and not any(request[1:])
    answer = pack_calinfo(NetFTCalibration(1_000_000, 2_000_000))
    assert len(answer) == 24 and answer[:2] == b"\x12\x34"
    device = unpack_calinfo(answer)
    assert device.si and device.calibration == NetFTCalibration(1_000_000.0, 2_000_000.0)
    assert unpack_calinfo(pack_calinfo(NetFTCalibration(1, 1), force_unit=1, torque_unit=1)).force_units == "lbf"
    with pytest.raises(ValueError, match="header"):
        unpack_calinfo(b"\x00" * 24)


def test_a_calibration_that_disagrees_with_the_sensor_or_other_units_is_refused():
    device = DeviceCalibration(NetFTCalibration(2_000_000.0, 1_000_000.0), "N", "N-m")
    assert check_calibration(None, device) == device.calibration
    assert check_calibration(NetFTCalibration(2_000_000.0, 1_000_000.0), device) == device.calibration
    with pytest.raises(ValueError, match="scaled wrong"):
        check_calibration(NetFTCalibration(), device)
    with pytest.raises(ValueError, match="set it to N and N-m"):
        check_calibration(None, DeviceCalibration(NetFTCalibration(), "lbf", "lbf-in"))


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_run_reads_the_emulated_sensors_calibration_and_refuses_a_wrong_one(start_emulator, tmp_path, capsys):
    emu = start_emulator(scenario={"feed_mm_s": 3.0, "depth_mm": 3.0}, extra_args=["--counts-per-force", "2000000"])
    assert read_calibration(emu.host).calibration.counts_per_force == 2_000_000.0
    argv = ["run", "--robot", emu.host, "--scenario", "feed_mm_s=3,depth_mm=3", "--yes", "--max-gap-ms", "500"]
    assert main([*argv, "--counts-per-force", "1000000", "--out", str(tmp_path / "wrong")]) == 2
    assert "scaled wrong" in capsys.readouterr().err and not (tmp_path / "wrong").exists()
    assert emu.status()["command_counts"] == {}  # refused before anything was sent
    assert main([*argv, "--out", str(tmp_path / "read")]) == 0
    results = json.loads((tmp_path / "read" / "metrics.json").read_text())
    header, _ = read_episode_log(tmp_path / "read" / results[0]["log"])
    assert header["run"]["ft_calibration"] == {
        "counts_per_force": 2_000_000.0,
        "counts_per_torque": 1_000_000.0,
        "source": "sensor",
    }
    assert 1.0 < results[0]["metrics"]["thrust_max_n"] < 100.0  # forces in N, as with the default counts
