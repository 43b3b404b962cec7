"""The reality generator: separate effects in other forms, real-schema logs with nothing privileged."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_diagnosis_effects import QUIET, scripted_channels

from drillgym.envs.effects import CHANNEL_GROUPS, EFFECTS
from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES
from drillgym.eval.diagnosis.reality.bone import ForceScaleReset
from drillgym.eval.diagnosis.reality.generate import build_reality, make_reality
from drillgym.eval.diagnosis.reality.library import REALITY_EFFECTS
from drillgym.eval.logs import read_episode_log

SETTINGS = {
    "ft_warmup": "ft_warmup:fz_n=3,fx_n=-1.5",
    "jittered_latency": "jittered_latency:mean_s=0.05,jitter_s=0.01",
    "stribeck_friction": "stribeck_friction:static_rad=3e-4,coulomb_rad=2e-4",
    "joint_offsets": "joint_offsets:dq0_rad=1e-3,dq1_rad=5e-4",
    "chuck_tool_length": "chuck_tool_length:dl_m=0.003,chuck_rad_per_nm=0.02",
    "density_layer": "density_layer:hardening=0.3,depth_m=0.001",
    "heat_softening": "heat_softening:softening_per_k=0.004",
    "entry_friction": "entry_friction:mu=0.3",
    "spindle_motor": "spindle_motor:sag_per_nm=150,time_constant_s=0.2",
    "bone_registration": "bone_registration:ex_m=1e-3,tilt_rad=0.08",
    "mount_resonance": "mount_resonance:freq_xy_hz=15,freq_z_hz=30,damping=0.05",
    "gear_backlash": "gear_backlash:play0_rad=2e-4,play1_rad=4e-4,play2_rad=3e-4",
    "wobbly_runout": "wobbly_runout:runout_m=3e-5",
    "ft_lateral_gain": "ft_lateral_gain:gain=0.2,crosstalk=0.01",
    "ft_load_bias": "ft_load_bias:bx_n=0.6,bz_n=-0.8",
    "tracker_smoothing": "tracker_smoothing:tau_s=0.1",
    "episode_warmup": "episode_warmup:fz_n=1,spread_n=3",
    "bone_void": "bone_void:length_m=0.001,depth_m=0.0015",
    "ft_broadband_noise": "ft_broadband_noise:sigma_n=0.1",
    "ft_torque_gain": "ft_torque_gain:gain=0.3",
    "joint_drift": "joint_drift:dq1_first_rad=5e-4,dq0_per_hole_rad=1e-4",  # the first hole: dq1 alone
}
TOL = {"force": 1e-3, "torque": 1e-5, "tracker": 1e-6, "q": 1e-6, "tcp": 1e-6}
UNTOUCHED = {"force": 1e-12, "torque": 1e-12, "tracker": 1e-12, "q": 1e-7, "tcp": 1e-7}


def run(spec: str | None):
    import gymnasium as gym

    env = gym.make("drillgym/UR5BoneDrill-v1", **QUIET)
    effects = build_reality(spec) if spec else []
    for e in effects:
        e.seed(np.random.default_rng(5))
    env.unwrapped.set_effects([ForceScaleReset(), *effects] if effects else None)
    out = scripted_channels(env)
    env.close()
    return out


@pytest.fixture(scope="module")
def baseline():
    return run(None)


def test_reality_effects_are_separate_classes_mapped_to_candidates():
    assert set(SETTINGS) == set(REALITY_EFFECTS)
    for name, cls in REALITY_EFFECTS.items():
        assert cls not in EFFECTS.values() and name not in EFFECTS
        assert cls.explains is None or cls.explains in EFFECTS
        assert (cls.explains is None) == (cls.location is not None)
    # each default candidate of the diagnosis has a truth among the reality effects (opt-in ones may too)
    assert {c.explains for c in REALITY_EFFECTS.values()} - {None} >= set(DIAGNOSIS_CANDIDATES)
    assert any(c.explains is None for c in REALITY_EFFECTS.values())  # and one effect is outside the library


@pytest.mark.parametrize("beta_deg", [15.0, 35.0])
def test_bone_registration_is_the_candidates_displacements_and_tilt_its_slope_share_per_episode(beta_deg):
    # candidate_values: the reality is the candidate at its displacements and tilt (its axis offset read at 25°);
    # displaced along the slope by ex, it is also the candidate at dz = ez + ex tan β of the episode's own β.
    import gymnasium as gym

    from drillgym.envs.effects import build_effects

    dz = 4e-4 + 1e-3 * math.tan(math.radians(beta_deg))
    forces = []
    for effects in (
        build_reality("bone_registration:ex_m=1e-3,ez_m=4e-4,tilt_rad=0.08"),
        build_effects(f"registration:surface_dz_m={dz},slope_error_rad=0.08"),
        build_effects(
            f"registration:surface_dz_m={4e-4 + 1e-3 * math.tan(math.radians(25))},entry_dx_m=1e-3,slope_error_rad=0.08"
        ),
    ):
        env = gym.make("drillgym/UR5BoneDrill-v1", **(QUIET | {"beta_deg": beta_deg}))
        env.reset(seed=1, options={"effects": effects})
        while not any(env.step(np.zeros(4, np.float32))[2:4]):
            pass
        forces.append(np.asarray(env.unwrapped.recorder.ft_force_n))
        env.close()
    np.testing.assert_allclose(forces[0], forces[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces[0], forces[2], rtol=0, atol=1e-9)


def test_spindle_motor_settles_on_the_candidates_torque_speed_line_and_lags_it_on_the_way():
    # The written-down equivalence (candidate_values): once the cut is steady, the motor with inertia sits where
    # spindle_sag puts the speed at once; while the torque rises at entry it is still faster (smaller forces).
    import gymnasium as gym

    from drillgym.envs.effects import build_effects

    thrust = []
    for effects in (
        build_reality("spindle_motor:sag_per_nm=150,time_constant_s=0.1"),
        build_effects("spindle_sag:sag_per_nm=150"),
    ):
        env = gym.make("drillgym/UR5BoneDrill-v1", **QUIET)
        env.reset(seed=1, options={"effects": effects})
        per_step = []
        while not any(env.step(np.zeros(4, np.float32))[2:4]):
            per_step.append(-env.unwrapped.cell.sample.force[2])
        thrust.append(np.array(per_step))
        env.close()
    motor, line = thrust
    last_cut = int(np.flatnonzero(line > 0.5 * line.max())[-1])  # the feed's end: 2 s (20 τ) after full engagement
    assert motor[last_cut] == pytest.approx(line[last_cut], rel=1e-6)
    rising = np.flatnonzero(line[:last_cut] < 0.95 * line.max())
    rising = rising[line[rising] > 0.2 * line.max()]
    assert np.mean(line[rising] - motor[rising]) > 0.05 and np.max(line[rising] - motor[rising]) > 0.1  # N


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_reality_effect_changes_exactly_its_channels(baseline, name):
    on = run(SETTINGS[name])
    n = {g: min(len(on[g]), len(baseline[g])) for g in CHANNEL_GROUPS}
    diff = {g: float(np.max(np.abs(on[g][: n[g]] - baseline[g][: n[g]]))) for g in CHANNEL_GROUPS}
    expected = set(REALITY_EFFECTS[name].channels)
    assert {g for g in CHANNEL_GROUPS if diff[g] > TOL[g]} == expected, diff
    # Untouched: no change beyond round-off (joint offsets that follow the pose move the encoders' view by
    # < 1e-7 rad while the servo catches up, a tenth of the RTDE resolution).
    assert all(diff[g] <= UNTOUCHED[g] for g in set(CHANNEL_GROUPS) - expected), diff


def test_make_reality_writes_real_schema_logs_with_nothing_privileged(tmp_path):
    truth = make_reality("ft_warmup:fz_n=2+bone_void:length_m=0.001", 3, 7, tmp_path / "logs")
    logs = sorted((tmp_path / "logs").glob("*.parquet"))
    assert len(logs) == 3
    controllers, scenarios = set(), set()
    for p in logs:
        header, df = read_episode_log(p)
        assert header["source"] == "real" and header["seed"] is None
        assert not [c for c in df.columns if c.startswith("sim_")]
        text = json.dumps(header)
        assert "ft_warmup" not in text and "bone_void" not in text and "effects" not in text
        assert header["scenario"]["latency_s"] == 0.014 and header["scenario"]["density_scale"] == 1.0
        controllers.add(header["controller"]["name"])
        scenarios.add((header["scenario"]["beta_deg"], header["scenario"]["feed_mm_s"], header["scenario"]["depth_mm"]))
    assert controllers == {"none", "li2023", "zhang2005"} and len(scenarios) > 1
    assert [e["name"] for e in truth["effects"]] == ["ft_warmup", "bone_void"]
    # Same seed, same logs.
    make_reality("ft_warmup:fz_n=2+bone_void:length_m=0.001", 1, 7, tmp_path / "again")
    a = read_episode_log(logs[0])[1]
    b = read_episode_log(tmp_path / "again" / "episode_000.parquet")[1]
    np.testing.assert_array_equal(a["ft_fz_n"], b["ft_fz_n"])


def test_make_reality_cli_keeps_the_truth_outside_the_log_folder(tmp_path):
    from drillgym.eval.cli import main

    assert (
        main(["make-reality", "--effects", "none", "--episodes", "1", "--seed", "0", "--out", str(tmp_path / "r")]) == 0
    )
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == ["episode_000.parquet"]
    assert json.loads((tmp_path / "r.truth.json").read_text())["effects"] == []


def test_unknown_reality_effects_are_refused():
    with pytest.raises(ValueError, match="unknown reality effect"):
        build_reality("ft_drift:fz_rate_n_s=0.01")  # a candidate is not a reality


def _tool_offsets_after_steps(spec: str, steps: int = 5) -> tuple[np.ndarray, np.ndarray]:
    import gymnasium as gym

    env = gym.make("drillgym/UR5BoneDrill-v1", **QUIET)
    env.unwrapped.set_effects(build_reality(spec))
    env.reset(seed=1)
    for _ in range(steps):
        env.step(np.zeros(4, dtype=np.float32))
    cell = env.unwrapped.cell
    tip = np.zeros(3) if cell.geometry_offset_task_m is None else cell.geometry_offset_task_m.copy()
    marker = np.zeros(3) if cell.marker_offset_base_m is None else cell.marker_offset_base_m.copy()
    env.close()
    return tip, marker


@pytest.mark.parametrize("order", [0, 1])
def test_effects_that_move_the_tool_add_up(order):
    # A stick-out error and joint zero errors together: the tip sits off by both, the marker by the joints'.
    length, joints = SETTINGS["chuck_tool_length"], SETTINGS["joint_offsets"]
    tip_l, marker_l = _tool_offsets_after_steps(length)
    tip_j, marker_j = _tool_offsets_after_steps(joints)
    both = f"{length}+{joints}" if order == 0 else f"{joints}+{length}"
    tip, marker = _tool_offsets_after_steps(both)
    assert np.allclose(tip_l, [0.0, 0.0, 0.003]) and not marker_l.any()
    np.testing.assert_allclose(tip, tip_l + tip_j, atol=1e-9)
    np.testing.assert_allclose(marker, marker_j, atol=1e-9)


@pytest.mark.parametrize("name", sorted(REALITY_EFFECTS))
def test_a_reality_effect_that_switches_nothing_on_is_refused_with_its_parameters_and_an_example(name):
    from drillgym.eval.diagnosis.reality.library import EXAMPLES, switches

    with pytest.raises(ValueError, match="switches nothing on") as refused:
        build_reality(name)
    for p in REALITY_EFFECTS[name].params:
        assert p.name in str(refused.value)
    assert EXAMPLES[name] in str(refused.value)
    shape = [p for p in REALITY_EFFECTS[name].params if p.name not in switches(REALITY_EFFECTS[name])]
    if shape:  # a shape parameter alone switches nothing on either
        value = shape[0].high if shape[0].high != shape[0].default else shape[0].low
        with pytest.raises(ValueError, match="switches nothing on"):
            build_reality(f"{name}:{shape[0].name}={value}")
    assert build_reality(EXAMPLES[name])  # the example does


def test_every_reality_example_is_the_benchmarks_moderate_case():
    from drillgym.eval.diagnosis.bench.cases import LATER_SINGLES, OUTSIDE, SINGLES
    from drillgym.eval.diagnosis.reality.library import EXAMPLES

    moderate = {name: specs[0] for name, specs in {**SINGLES, **LATER_SINGLES}.items()}
    moderate["bone_void"] = OUTSIDE[0]
    moderate["ft_broadband_noise"], moderate["ft_torque_gain"] = OUTSIDE[2], OUTSIDE[4]
    assert EXAMPLES == {name: moderate[name] for name in REALITY_EFFECTS}


def test_the_docs_and_the_help_list_every_reality_effects_parameters(capsys):
    from pathlib import Path

    from drillgym.eval.cli import main
    from drillgym.eval.diagnosis.reality.library import parameters_table

    docs = (Path(__file__).resolve().parents[2] / "docs" / "diagnosis.md").read_text()
    assert parameters_table() in docs  # regenerate the table in docs/diagnosis.md §5 if this fails
    with pytest.raises(SystemExit):
        main(["make-reality", "--help"])
    text = capsys.readouterr().out
    for name, cls in REALITY_EFFECTS.items():
        assert f"  {name}: " in text
        for p in cls.params:
            assert f" {p.name} [" in text


def test_make_reality_refuses_an_effect_without_parameters_before_writing_anything(tmp_path, capsys):
    from drillgym.eval.cli import main

    out = tmp_path / "r"
    assert main(["make-reality", "--effects", "density_layer", "--episodes", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "switches nothing on" in err and "hardening" in err and "density_layer:hardening=0.2" in err
    assert not out.exists() and not (tmp_path / "r.truth.json").exists()
