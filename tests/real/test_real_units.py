"""Real-cell building blocks that need no emulator: poses, safety checks, Net F/T and tracker wire formats,
resampling, contact detection, emulator configuration."""

import math

import numpy as np
import pytest

from drillgym.envs.cell_params import R_BASE_TASK
from drillgym.envs.metrics import EpisodeRecorder
from drillgym.envs.real import netft, safety, tracker
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.emulator.cli import parse_scenario
from drillgym.envs.real.emulator.config import EmulatorConfig, ScheduledFault
from drillgym.envs.real.emulator.rtde_protocol import PackageReader, pack
from drillgym.envs.real.metrics import CONTACT_FORCE_N, cell_metrics, contact_flags
from drillgym.envs.real.poses import matrix_to_pose, matrix_to_rotvec, pose_to_matrix, rotvec_to_matrix
from drillgym.envs.real.sampling import FTBinner, path_at


def _random_rotation(rng):
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_rotation_vector_round_trip_including_half_turns():
    rng = np.random.default_rng(0)
    rotations = [_random_rotation(rng) for _ in range(50)] + [R_BASE_TASK, np.eye(3), np.diag([1.0, -1.0, -1.0])]
    for rot in rotations:
        rv = matrix_to_rotvec(rot)
        assert np.linalg.norm(rv) <= math.pi + 1e-9
        np.testing.assert_allclose(rotvec_to_matrix(rv), rot, atol=1e-9)


def test_tool_down_pose_matches_the_ur_convention():
    # the drill along -z of the base: UR's rotation vector for x_task=+y_base, y_task=+x_base is pi*(1,1,0)/sqrt2
    np.testing.assert_allclose(np.abs(matrix_to_rotvec(R_BASE_TASK)), [math.pi / math.sqrt(2)] * 2 + [0.0], atol=1e-9)
    pose = np.array([-0.45, -0.11, 0.1, *matrix_to_rotvec(R_BASE_TASK)])
    np.testing.assert_allclose(matrix_to_pose(pose_to_matrix(pose)), pose, atol=1e-12)
    with pytest.raises(ValueError, match="6 values"):
        pose_to_matrix(np.zeros(5))


def test_safety_bits_name_the_stop():
    assert safety.check_safety_bits(0b1, 0.0) is None
    fault = safety.check_safety_bits(0b100, 1.5)
    assert fault is not None and fault.reason == "protective_stop" and "protective stop" in fault.message
    fault = safety.check_safety_bits(1 << 7, 0.0)
    assert fault is not None and fault.reason == "safety_stop" and "emergency stop" in fault.message


def test_workspace_force_age_and_tracking_checks():
    lim = SafetyLimits()
    assert safety.check_workspace(np.array([0.001, -0.002, 0.005]), 6e-3, lim, "target", 0.0) is None
    fault = safety.check_workspace(np.array([0.01, 0.0, 0.0]), 6e-3, lim, "target", 2.0)
    assert fault is not None and fault.reason == "workspace" and "10.00" in fault.message
    assert safety.check_workspace(np.array([0.0, 0.0, 0.0085]), 6e-3, lim, "target", 0.0) is not None
    assert safety.check_force(np.array([3.0, 4.0, 0.0, 9, 9, 9]), 5.0, 0.0) is None
    assert safety.check_force(np.array([3.0, 4.0, 0.1, 0, 0, 0]), 5.0, 0.0).reason == "force_limit"
    assert safety.check_age("ft", 0.01, 0.05, 0.0) is None
    assert safety.check_age("ft", None, 0.05, 0.0).reason == "ft_stale"
    assert "120 ms" in safety.check_age("rtde", 0.12, 0.05, 0.0).message
    assert safety.check_tracking(np.zeros(3), np.array([0.004, 0.0, 0.0]), lim, 0.0).reason == "tracking"


def test_rate_limit_and_correction_clip():
    out = safety.rate_limit(np.zeros(3), np.array([0.003, 0.004, 0.0]), 0.001)
    np.testing.assert_allclose(out, [0.0006, 0.0008, 0.0])
    np.testing.assert_allclose(safety.rate_limit(np.zeros(3), np.full(3, 1e-4), 1.0), np.full(3, 1e-4))
    np.testing.assert_allclose(
        safety.clip_correction(np.array([0.01, -0.01, 0.0005]), SafetyLimits()), [2e-3, -2e-3, 5e-4]
    )


def test_limits_validate():
    with pytest.raises(ValueError, match="max_tcp_speed_m_s"):
        SafetyLimits(max_tcp_speed_m_s=float("nan"))
    with pytest.raises(ValueError, match="exceeds the action scale"):
        SafetyLimits(max_correction_m=0.01)
    assert ServoParams().period_s == pytest.approx(0.008)


def test_netft_wire_format_and_calibration():
    cal = netft.NetFTCalibration(counts_per_force=1e6, counts_per_torque=2e6)
    wrench = np.array([1.5, -0.25, 7.0, 0.01, -0.02, 0.003])
    counts = cal.to_counts(wrench)
    assert counts[:3] == [1_500_000, -250_000, 7_000_000] and counts[3] == 20_000
    record = netft.pack_record(7, 99, 0, counts)
    assert len(record) == 36
    seq, ft_seq, status, *raw = netft.RECORD.unpack(record)
    assert (seq, ft_seq, status) == (7, 99, 0)
    np.testing.assert_allclose(cal.to_si(np.array(raw)), wrench)
    request = netft.pack_request(netft.CMD_START_REALTIME, 0)
    assert request == bytes.fromhex("1234000200000000")
    assert netft.unpack_request(request) == (2, 0)
    with pytest.raises(ValueError, match="not an RDT request"):
        netft.unpack_request(b"\x00" * 8)
    with pytest.raises(ValueError):
        netft.NetFTCalibration(counts_per_force=0.0)


def test_tracker_wire_format_and_specs():
    rec = tracker.pack_tracker_record(3, 1.25, np.array([0.1, -0.2, 0.3]), True)
    magic, seq, t, x, y, z, valid = tracker.RECORD.unpack(rec)
    assert (magic, seq, t, x, y, z, valid) == (b"DGTR", 3, 1.25, 0.1, -0.2, 0.3, 1)
    assert tracker.unpack_tracker_request(tracker.REQUEST.pack(b"DGTR", 1)) is True
    assert isinstance(tracker.make_tracker("none"), tracker.NoTracker)
    with pytest.raises(ValueError, match="udp:HOST"):
        tracker.make_tracker("ndi")


def _record(t, fx):
    return netft.FTRecord(t, 0, 0, np.array([fx, 0.0, 0.0, 0.0, 0.0, 0.0]))


def test_ft_bins_average_records_and_hold_through_gaps():
    binner = FTBinner(t0=100.0, bias=np.array([1.0, 0, 0, 0, 0, 0]))
    recs = [_record(100.001, 2.0), _record(100.006, 4.0), _record(100.012, 6.0), _record(100.035, 9.0)]
    times, w = binner.bins_until(recs, 100.04)
    np.testing.assert_allclose(times, [0.01, 0.02, 0.03, 0.04])
    np.testing.assert_allclose(w[:, 0], [2.0, 5.0, 5.0, 8.0])  # mean minus bias; bin 3 empty -> held
    assert binner.empty_bins == 1 and binner.open_bin_start == pytest.approx(100.04)
    assert binner.bins_until(recs, 100.045)[0] == []


def test_path_is_read_per_sample():
    depth, phase = path_at([0.0, 0.012, 0.03], [0.004, 0.012, 0.02], [-3e-3, -2.9e-3, -2.8e-3], [0, 0, 1])
    np.testing.assert_allclose(depth, [-3e-3, -2.9e-3, -2.8e-3])
    assert phase == [0, 0, 1]
    with pytest.raises(ValueError):
        path_at([0.0], [], [], [])


def test_contact_flags_online_equal_batch_and_metrics_skip_true_tip():
    rng = np.random.default_rng(1)
    force = np.zeros((60, 3))
    force[20:] = [0.2, 0.1, -2.0]
    force += 0.02 * rng.standard_normal(force.shape)
    batch = contact_flags(force)
    online = []
    for k in range(0, 60, 5):
        online += contact_flags(force[k : k + 5], force[max(k - 4, 0) : k] if k else None)
    assert batch == online
    assert batch[:20] == [0] * 20 and batch[25:] == [1] * 35
    assert CONTACT_FORCE_N < 1.0
    rec = EpisodeRecorder(
        t_s=list(np.arange(1, 61) * 0.01),
        phase=[1] * 60,
        stage=[4] * 60,
        depth_cmd_m=list(np.linspace(0, 2e-3, 60)),
        deviation_m=[1e-3] * 60,
        ft_force_n=list(force),
        tracker_deviation_m=[2e-4] * 60,
    )
    m = cell_metrics(rec, entry_depth_m=0.5e-3, depth_m=2e-3)
    assert math.isnan(m["deviation_mean_mm"]) and math.isnan(m["hole_offset_mm"])
    assert m["thrust_max_n"] == pytest.approx(2.0, abs=0.1) and m["tracker_deviation_mean_mm"] == pytest.approx(0.2)
    assert m["drill_time_s"] < 0.4  # from F/T contact (sample 20 on), not from the recorded stage


def test_cell_metrics_of_a_simulated_episode_read_its_record_as_the_real_cells_lists():
    """The sim's recorder (array channels) gives the metrics its channels give as the real cell's list recorder."""
    from drillgym.envs.drill_env import UR5BoneDrillEnv

    env = UR5BoneDrillEnv(pybullet_world=False)
    env.reset(seed=0)
    for _ in range(120):
        env.step(np.zeros(4, np.float32))
    rec, sc = env.recorder, env.scenario
    lists = EpisodeRecorder(**{k: list(v) for k, v in rec.channels().items()})
    sim, real = (cell_metrics(r, sc.entry_depth_m, sc.depth_m) for r in (rec, lists))
    assert sim.keys() == real.keys()
    assert all(sim[k] == real[k] or (math.isnan(sim[k]) and math.isnan(real[k])) for k in sim)
    assert not math.isnan(sim["thrust_max_n"])  # the F/T contact was found


def test_rtde_package_reader_reassembles_a_split_stream():
    stream = pack(ord("V"), b"\x00\x02") + pack(ord("v")) + pack(ord("U"), b"\x01" + bytes(20))
    reader = PackageReader()
    out = []
    for i in range(0, len(stream), 3):
        out += reader.feed(stream[i : i + 3])
    assert [k for k, _ in out] == [ord("V"), ord("v"), ord("U")] and out[2][1] == b"\x01" + bytes(20)


def test_emulator_configuration_is_checked():
    with pytest.raises(ValueError, match="loopback"):
        EmulatorConfig(host="192.168.1.5")
    fault = ScheduledFault.parse("delay:0.02@1.5")
    assert (fault.kind, fault.value, fault.after_s) == ("delay", 0.02, 1.5)
    with pytest.raises(ValueError, match="choose from"):
        ScheduledFault.parse("meteor@1")
    sc = parse_scenario("beta_deg=20,feed_mm_s=1,tracker=false,bone=buffalo_femur")
    assert sc.beta_deg == 20.0 and sc.feed_mm_s == 1.0 and sc.tracker is False
    assert parse_scenario('{"depth_mm": 4}').depth_mm == 4.0
    with pytest.raises(ValueError, match="key=value"):
        parse_scenario("speed=3")
