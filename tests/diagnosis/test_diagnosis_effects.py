"""Candidate effects: each changes the channels its physics says, and only those; off means untouched."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.envs.cell_params import CellParams
from drillgym.envs.constants import SUBSTEPS_PER_STEP
from drillgym.envs.effects import CHANNEL_GROUPS, EFFECTS, TraceView, build_effects, parse_effect_spec
from drillgym.envs.scenario import Scenario

QUIET = {
    "ft_noise_n": 0.0,
    "tracker_noise_mm": 0.0,
    "bone_variability": 0.0,
    "depth_mm": 3.0,
    "feed_mm_s": 1.0,
    "beta_deg": 25.0,
}
TOL = {"force": 1e-3, "torque": 1e-5, "tracker": 1e-6, "q": 1e-6, "tcp": 1e-6}

# A moderate value of each effect, chosen so its physics is visible in a 3 mm hole.
SETTINGS = {
    "ft_drift": "ft_drift:fz_rate_n_s=0.02,fx_rate_n_s=-0.01",
    "latency": "latency:extra_latency_s=0.05",
    "joint_friction": "joint_friction:coulomb_rad=2e-4,viscous_s=0.02",
    "kinematic_offset": "kinematic_offset:dy_base_m=5e-4,dz_base_m=-2e-4",
    "tool_length": "tool_length:dl_m=0.003",
    "density_gradient": "density_gradient:offset=0.1,gradient_per_m=60",
    "thermal_softening": "thermal_softening:softening=0.3,work_j=5",
    "skid_friction": "skid_friction:mu=0.2",
    "spindle_sag": "spindle_sag:sag_per_nm=150",
    "registration": "registration:surface_dz_m=4e-4,entry_dx_m=5e-4,slope_error_rad=0.08",
    "ft_resonance": "ft_resonance:amplitude=1,freq_lateral_hz=15,freq_axial_hz=30,damping=0.05",
    "joint_backlash": "joint_backlash:play_rad=3e-4",
    "tool_runout": "tool_runout:runout_m=3e-5",
    "servo_deadband": "servo_deadband:band_m=2e-4",
    "ft_gain": "ft_gain:fxy_gain=0.2,fz_gain=-0.1,fx_from_fz=0.02,fy_from_fz=-0.01",
    "ft_contact_bias": "ft_contact_bias:bx_n=0.5,bz_n=-0.8",
    "tracker_latency": "tracker_latency:latency_s=0.07",
    "ft_episode_drift": "ft_episode_drift:fy_rate_n_s=0.015,fz_rate_n_s=-0.02",
    "kinematic_offset_trend": "kinematic_offset_trend:dy_first_m=5e-4,dz_first_m=-2e-4",  # position 0: the first
}


def scripted_action(k: int) -> np.ndarray:
    """Open-loop commands (the same whatever the effect does): a slow lateral wave and a feed change."""
    a = np.zeros(4, dtype=np.float32)
    a[0] = 0.15 * np.sin(0.2 * k)
    a[1] = 0.1 * np.cos(0.15 * k)
    a[3] = 0.25 if 30 <= k < 60 else 0.0
    return a


def scripted_channels(env: gym.Env) -> dict[str, np.ndarray]:
    """Reset ``env`` (seed 1), run the scripted actions to the end and return its channels."""
    env.reset(seed=1)
    u = env.unwrapped
    q, tracker, tcp, k = [], [], [], 0
    while True:
        _, _, te, tr, _ = env.step(scripted_action(k))
        k += 1
        q.append(u.cell.q_motor_rad.copy())
        tracker.append(u.tracker_reading.copy())
        tcp.append(u.rtde_tcp_base.copy())
        if te or tr:
            break
    return {
        "force": np.asarray(u.recorder.ft_force_n),
        "torque": np.asarray(u.recorder.ft_torque_nm),
        "tracker": np.array(tracker),
        "q": np.array(q),
        "tcp": np.array(tcp),
    }


def run_open_loop(spec: str | None) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Channels of a scripted episode, and the replay's engaged share per sample."""
    env = gym.make("drillgym/UR5BoneDrill-v1", **QUIET)
    env.unwrapped.set_effects(build_effects(spec) if spec else None)
    out = scripted_channels(env)
    u = env.unwrapped
    tips = np.asarray(u.recorder.tip_task_m)
    share = np.interp(
        tips[:, 2] + tips[:, 0] * u.cell.solver.tan_beta, u.cell.table.depth_m, u.cell.table.engaged_fraction
    )
    env.close()
    return out, share


def channels(spec: str | None) -> dict[str, np.ndarray]:
    return run_open_loop(spec)[0]


@pytest.fixture(scope="module")
def baseline():
    return channels(None)


def max_diff(a: np.ndarray, b: np.ndarray) -> float:
    n = min(len(a), len(b))
    return float(np.max(np.abs(a[:n] - b[:n]))) if n else 0.0


def test_every_candidate_has_a_setting_and_documented_parameters():
    assert len(EFFECTS) >= 8
    assert set(SETTINGS) == set(EFFECTS)
    for cls in EFFECTS.values():
        assert cls.__doc__ and cls.summary and cls.params
        assert cls.channels <= set(CHANNEL_GROUPS)
        for p in cls.params:
            assert p.low <= p.default <= p.high and p.description


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_effect_changes_exactly_its_channels(baseline, name):
    on = channels(SETTINGS[name])
    changed = {g for g in CHANNEL_GROUPS if max_diff(on[g], baseline[g]) > TOL[g]}
    untouched = {g for g in CHANNEL_GROUPS if max_diff(on[g], baseline[g]) <= 1e-12}  # float round-off at most
    expected = set(EFFECTS[name].channels)
    assert changed == expected, f"{name}: changed {sorted(changed)}, physics says {sorted(expected)}"
    assert untouched == set(CHANNEL_GROUPS) - expected, (
        f"{name}: {sorted(set(CHANNEL_GROUPS) - expected - untouched)} moved a little"
    )


BEFORE_CONTACT_MARGIN_SAMPLES = 10
"""F/T samples left out before the first contact (the sensor's filter spreads the contact force back)."""


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_effect_changes_exactly_its_declared_channels_before_contact(name):
    # The diagnosis credits an effect with gap before contact only where its physics reaches there.
    spec = SETTINGS[name] if name != "tool_length" else "tool_length:dl_m=0.001"  # 3 mm starts in the bone
    base, share_base = run_open_loop(None)
    on, share_on = run_open_loop(spec)
    first = min(np.flatnonzero(share_base > 0)[0], np.flatnonzero(share_on > 0)[0]) - BEFORE_CONTACT_MARGIN_SAMPLES
    assert first > 5 * SUBSTEPS_PER_STEP, "the scripted episode must start clear of the bone"
    per_step = {"tracker", "q", "tcp"}
    changed = set()
    for g in CHANNEL_GROUPS:
        n = first // SUBSTEPS_PER_STEP if g in per_step else first
        if max_diff(on[g][:n], base[g][:n]) > 1e-12:
            changed.add(g)
    assert changed == set(EFFECTS[name].channels_before_contact), (
        f"{name}: before contact changed {sorted(changed)}, declared {sorted(EFFECTS[name].channels_before_contact)}"
    )
    assert EFFECTS[name].channels_before_contact <= EFFECTS[name].channels


def test_runout_moves_the_lateral_force_and_its_moment_only(baseline):
    on = channels(SETTINGS["tool_runout"])
    assert max_diff(on["force"][:, :2], baseline["force"][:, :2]) > 0.05
    assert max_diff(on["force"][:, 2], baseline["force"][:, 2]) == 0.0
    assert max_diff(on["torque"][:, 2], baseline["torque"][:, 2]) == 0.0


def test_effects_at_their_defaults_leave_the_episode_bit_identical(baseline):
    off = channels("+".join(EFFECTS))
    for g in CHANNEL_GROUPS:
        assert max_diff(off[g], baseline[g]) == 0.0, g


def test_switching_effects_off_again_restores_the_default_cell(baseline):
    env = gym.make("drillgym/UR5BoneDrill-v1", **QUIET)
    on = "+".join(SETTINGS[n] for n in ("tool_length", "kinematic_offset", "registration", "spindle_sag"))
    env.reset(seed=1, options={"effects": build_effects(on)})
    slowest = env.unwrapped.scenario.spindle_rpm
    while not any(env.step(scripted_action(0))[2:4]):  # the spindle sags in the cut
        slowest = min(slowest, env.unwrapped.cell.spindle_rpm)
    assert slowest < 0.95 * env.unwrapped.scenario.spindle_rpm
    env.reset(seed=1, options={"effects": None})
    cell = env.unwrapped.cell
    assert cell.spindle_rpm == cell.scenario.spindle_rpm and cell.solver.beta_rad == cell.scenario.beta_rad
    assert cell.geometry_offset_task_m is None and cell.marker_offset_base_m is None
    assert cell.sensor_arm_m == cell.tcp_offset_m
    np.testing.assert_array_equal(cell.C_tool, cell.tool.compliance_tool_m_n())
    env.close()


@pytest.mark.parametrize("name", [n for n, c in EFFECTS.items() if c.sensor_only])
def test_sensor_only_effect_on_a_trace_matches_the_simulated_one(name):
    # The fast path the diagnosis fits with: the effect applied to recorded readings. The simulated one
    # acts before the sensor's resolution (0.01-0.02 N), so the two agree to it.
    base, share = run_open_loop(None)
    sim = channels(SETTINGS[name])
    n = len(base["force"])
    arm = CellParams().sensor_to_chuck_m + QUIET.get("stickout_mm", Scenario().stickout_mm) * 1e-3
    t_s = (np.arange(n) + 1) * 0.01
    tracker = np.repeat(base["tracker"], SUBSTEPS_PER_STEP, axis=0)[:n]  # held over each step's samples
    view = TraceView(t_s, base["force"].copy(), base["torque"].copy(), share, arm, 20000.0, tracker.copy())
    effect = EFFECTS[name](**parse_effect_spec(SETTINGS[name])[0][1])
    effect.apply_to_trace(view)
    # One resolution step, or for a filter the reading's rounding (half a step) through the filter (at most
    # its impulse response's l1 norm times it) plus the simulated reading's own rounding.
    resolution = np.array([0.0101, 0.0101, 0.0201])
    steps = 0.5 * _rounding_gain(effect) + 0.5 if name == "ft_resonance" else 1.0
    bound = steps * resolution
    if name == "ft_gain":  # a matrix carries each axis's rounding into the others: |C| · (half steps), plus its own
        bound = np.abs(effect.matrix()) @ (0.5 * resolution) + 0.5 * resolution
    assert np.all(np.max(np.abs(view.force_n - sim["force"]), axis=0) <= bound)
    assert np.max(np.abs(view.torque_nm - sim["torque"])) <= steps * 2e-4
    # the env reads the tracker once per step: the trace holds every reading the simulated delay line had
    assert view.tracker_m is not None
    assert max_diff(view.tracker_m[SUBSTEPS_PER_STEP - 1 :: SUBSTEPS_PER_STEP], sim["tracker"]) <= 1e-9


def _rounding_gain(effect) -> float:
    """l1 norm of the impulse response of ``W -> W + a (H W − W)``: the most it can amplify a bounded error."""
    from scipy import signal

    from drillgym.envs.effects.resonance import mode_filter

    impulse = np.zeros(2000)
    impulse[0] = 1.0
    gains = []
    for key in ("freq_lateral_hz", "freq_axial_hz"):
        b, a = mode_filter(effect.values[key], effect.values["damping"])
        h = impulse + effect.values["amplitude"] * (signal.lfilter(b, a, impulse) - impulse)
        gains.append(float(np.abs(h).sum()))
    return max(gains)


def test_effect_specs_and_parameters_are_validated():
    assert parse_effect_spec("a:x=1,y=2e-3+b") == [("a", {"x": 1.0, "y": 0.002}), ("b", {})]
    with pytest.raises(ValueError, match="unknown effect"):
        build_effects("warp_drive")
    with pytest.raises(ValueError, match="unknown parameter"):
        build_effects("latency:delay=0.1")
    with pytest.raises(ValueError, match="outside"):
        build_effects("latency:extra_latency_s=5")
    with pytest.raises(ValueError, match="expected key=value"):
        parse_effect_spec("latency:0.1")
