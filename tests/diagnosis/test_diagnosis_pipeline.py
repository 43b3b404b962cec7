"""The diagnosis end to end on small generated realities: names what it should, stays quiet on clean data."""

from __future__ import annotations

import json

import pytest

from drillgym.eval.diagnosis.bench.cases import Case, full_cases, quick_cases
from drillgym.eval.diagnosis.bench.run import score_case, summarise
from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, diagnose
from drillgym.eval.diagnosis.episodes import load_episodes
from drillgym.eval.diagnosis.reality.generate import make_reality

CANDIDATES = ("ft_drift", "tool_runout", "latency")
REQUIRED_EFFECT_KEYS = {"name", "params", "heldout_gap_before", "heldout_gap_after", "shrink", "ci_low", "ci_high"}


def diagnosed(tmp_path, spec: str, seed: int, episodes: int = 6, candidates: tuple[str, ...] = CANDIDATES) -> dict:
    make_reality(spec, episodes, seed, tmp_path / "logs")
    eps, skipped = load_episodes(tmp_path / "logs")
    assert not skipped
    return diagnose(eps, DiagnoseOptions(workers=1, candidates=candidates, progress=False))


def test_a_drifting_ft_sensor_is_named_and_the_gap_shrinks(tmp_path):
    res = diagnosed(tmp_path, "ft_warmup:fz_n=3,fx_n=-1.5,fy_n=1", seed=11)
    assert res["verdict"] == "explained" and res["named"] == ["ft_drift"]
    best = res["effects"][0]
    assert REQUIRED_EFFECT_KEYS <= set(best)
    assert best["shrink"] >= 0.6 and best["ci_low"] <= best["shrink"] <= best["ci_high"]
    assert best["heldout_gap_after"] < best["heldout_gap_before"]
    where = res["where"]["all_episodes"]
    fz = where["channels"].index("fz_n")
    q1 = where["channels"].index("q1_rad")
    retract = where["stages"].index("retract")
    assert where["normalised"][fz][retract] > 10 * max(where["normalised"][q1][retract], 1.0)


def test_clean_data_names_no_effect(tmp_path):
    res = diagnosed(tmp_path, "none", seed=12)
    assert res["verdict"] == "no_gap" and res["named"] == []
    assert res["summary"].startswith("no significant gap")


def test_an_effect_outside_the_library_is_unexplained_and_located(tmp_path):
    res = diagnosed(tmp_path, "bone_void:length_m=0.0015,depth_m=0.0025", seed=13)
    assert res["verdict"] == "unexplained" and res["named"] == []
    assert (res["location"]["channel"], res["location"]["stage"]) == ("fz_n", "stable")
    assert res["summary"] == "unexplained — located at fz_n, stable"


def test_diagnose_cli_writes_json_report_and_figures_on_all_cores(tmp_path):
    from drillgym.eval.cli import main

    make_reality("wobbly_runout:runout_m=4e-5", 4, 14, tmp_path / "logs")
    out = tmp_path / "out"
    argv = ["diagnose", "--real", str(tmp_path / "logs"), "--out", str(out), "--workers", "2"]
    assert main([*argv, "--candidates", "tool_runout,ft_drift", "--no-progress"]) == 0
    res = json.loads((out / "diagnosis.json").read_text())
    assert res["verdict"] in ("explained", "no_gap", "unexplained") and "where" in res
    assert res["named"] == ["tool_runout"]
    assert res["timing"]["workers"] == 2
    report = (out / "report.md").read_text()
    assert "gap_map.png" in report and (out / "gap_map.png").stat().st_size > 1000
    assert "Few episodes" in report  # 4 episodes: 2 calibration, 2 held-out
    assert (out / "overlays.png").is_file() and (out / "spectra.png").is_file()


def test_too_few_episodes_is_a_clear_error(tmp_path):
    make_reality("none", 2, 0, tmp_path / "logs")
    eps, _ = load_episodes(tmp_path / "logs")
    with pytest.raises(ValueError, match="at least 4"):
        diagnose(eps, DiagnoseOptions(workers=1, progress=False))


def test_benchmark_cases_cover_the_acceptance():
    cases = full_cases()
    singles = [c for c in cases if c.kind == "single"]
    assert {c.truth[0] for c in singles} == {
        "ft_drift", "latency", "joint_friction", "kinematic_offset", "tool_length",
        "density_gradient", "thermal_softening", "skid_friction", "tool_runout", "tracker_latency",
        "ft_episode_drift", "spindle_sag", "ft_resonance", "joint_backlash",
    }  # fmt: skip
    from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES

    assert {c.truth[0] for c in singles} == set(DIAGNOSIS_CANDIDATES)  # every default candidate has its reality
    assert all(sum(c.truth == s.truth for c in singles) >= 2 for s in singles)  # two magnitudes each
    assert any(c.kind == "pair" for c in cases) and any(c.kind == "clean" for c in cases)
    outside = [c for c in cases if c.kind == "outside"]
    assert outside and all(c.truth == [] and c.expected_location for c in outside)
    assert len(quick_cases()) <= 3


def test_benchmark_scoring():
    single = Case("x", "single", "ft_warmup:fz_n=1", 0)
    res = {
        "verdict": "explained",
        "named": ["ft_drift"],
        "location": None,
        "effects": [{"name": "ft_drift", "effects": ["ft_drift"], "shrink": 0.8}],
        "significance": {"gap": 3.0, "null": 0.5},
        "timing": {"total_s": 1.0},
    }
    row = score_case(single, res)
    assert row["correct"] and row["true_effect_shrink"] == 0.8
    outside = Case("o", "outside", "bone_void:length_m=0.001", 0)
    res_o = {
        **res,
        "verdict": "unexplained",
        "named": [],
        "location": {"channel": "fz_n", "stage": "stable"},
        "effects": [],
    }
    assert score_case(outside, res_o)["correct"]
    res_wrong = {**res_o, "location": {"channel": "q1_rad", "stage": "stable"}}
    assert not score_case(outside, res_wrong)["correct"]
    summary = summarise([row, score_case(outside, res_o)])
    assert summary["figures"]["top1_accuracy_single"] == 1.0 and summary["passed"]["top1_accuracy_single"]


def test_benchmark_scores_a_named_effects_parameters_against_the_realitys_own_where_written_down():
    case = Case("t", "single", "tracker_smoothing:tau_s=0.06", 0)
    assert case.truth_values == {"tracker_latency": {"latency_s": 0.06}}
    assert Case("d", "single", "density_layer:hardening=0.2", 0).truth_values == {}  # forms share no parameter

    def result(low, high):
        effect = {
            "name": "tracker_latency",
            "effects": ["tracker_latency"],
            "named": True,
            "shrink": 0.9,
            "params": {"tracker_latency": {"latency_s": 0.0604}},
            "param_intervals": {"tracker_latency": {"latency_s": {"low": low, "high": high}}},
        }
        return {
            "verdict": "explained",
            "named": ["tracker_latency"],
            "location": None,
            "effects": [effect],
            "significance": {"gap": 3.0, "null": 0.5},
            "timing": {"total_s": 1.0},
        }

    inside, outside = score_case(case, result(0.0593, 0.0612)), score_case(case, result(0.0601, 0.0612))
    assert inside["params"] == [
        {
            "effect": "tracker_latency",
            "param": "latency_s",
            "truth": 0.06,
            "fit": 0.0604,
            "low": 0.0593,
            "high": 0.0612,
            "covered": True,
        }
    ]
    assert outside["params"][0]["covered"] is False
    figures = summarise([inside, outside])["figures"]
    assert figures["interval_coverage"] == 0.5 and figures["parameters_scored"] == 2
    unnamed = score_case(case, {**result(0.0, 1.0), "named": [], "verdict": "unexplained", "effects": []})
    assert unnamed["params"] == []


@pytest.mark.expensive
def test_bench_diagnosis_quick_names_the_drift_stays_quiet_on_clean_data_and_locates_the_void(tmp_path):
    """Each row of --quick as docs/diagnosis.md states it: the strong F/T warm-up named as ft_drift (its own candidate)
    with the true effect's held-out shrink ≥ 95 % (measured 99.4 %; the docs' median is 99 %: 95 % still fails a
    candidate that stopped explaining the drift), clean data ``no_gap`` with nothing named, and the void outside the
    library ``unexplained``, located at fz_n in the stable stage with most (> 50 %) of the excess (measured 84 %)."""
    from drillgym.eval.cli import main

    assert main(["bench-diagnosis", "--quick", "--out", str(tmp_path), "--workers", "2", "--no-progress"]) == 0
    bench = json.loads((tmp_path / "bench.json").read_text())
    rows = {r["case"]: r for r in bench["rows"]}
    assert bench["summary"]["cases"] == 3 and set(rows) == {"ft_warmup-strong", "clean-0", "outside-0"}
    drift, clean, void = rows["ft_warmup-strong"], rows["clean-0"], rows["outside-0"]
    assert (drift["kind"], drift["truth"], drift["verdict"], drift["named"]) == (
        "single",
        ["ft_drift"],
        "explained",
        ["ft_drift"],
    )
    assert drift["correct"] and drift["top1_ranked"] and drift["top_single"] == "ft_drift"
    assert drift["true_effect_shrink"] >= 0.95 and drift["location"] is None
    assert (clean["kind"], clean["verdict"], clean["named"], clean["location"]) == ("clean", "no_gap", [], None)
    assert clean["correct"]
    assert (void["kind"], void["truth"], void["verdict"], void["named"]) == ("outside", [], "unexplained", [])
    assert (void["location"]["channel"], void["location"]["stage"]) == ("fz_n", "stable")
    assert void["location"]["share"] > 0.5 and void["located"] and void["correct"]
    assert not any(r.get("error") for r in rows.values())
    figures = bench["summary"]["figures"]
    assert figures["top1_accuracy_single"] == 1.0 and figures["clean_no_effect_named"] == 1.0
    assert figures["outside_unexplained_and_located"] == 1.0 and figures["wrong_effect_named_rate"] == 0.0
    for case, row in rows.items():  # each case's diagnosis.json says the same as its row
        diagnosis = json.loads((tmp_path / "cases" / case / "diagnosis.json").read_text())
        assert (diagnosis["verdict"], diagnosis["named"]) == (row["verdict"], row["named"])
    assert (tmp_path / "bench.md").is_file()


@pytest.mark.parametrize("command", ["diagnose", "make-reality", "bench-diagnosis", "import-rtde"])
def test_new_commands_have_help(command, capsys):
    from drillgym.eval.cli import main

    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0 and "--out" in capsys.readouterr().out


def test_bench_diagnosis_refuses_unknown_case_names(tmp_path, capsys):
    from drillgym.eval.cli import main

    assert main(["bench-diagnosis", "--only", "pair-1,pair-99", "--out", str(tmp_path), "--no-progress"]) == 2
    assert "pair-99" in capsys.readouterr().err and not (tmp_path / "bench.json").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--candidates", "ft_drift,warp_drive"], "warp_drive"),
        (["--quick", "--opt-in"], "--quick"),
        (["--seed-offsets", "0,1000,0"], "repeats"),
        (["--seed-offsets", "0,1k"], "integers"),
        (["--seed-offsets", "0,1000", "--seed-offset", "5"], "not both"),
    ],
)
def test_bench_diagnosis_refuses_unknown_candidates_and_opt_in_quick_runs(tmp_path, capsys, args, message):
    from drillgym.eval.cli import main

    assert main(["bench-diagnosis", *args, "--out", str(tmp_path), "--no-progress"]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "bench.json").exists()


def test_opt_in_cases_are_the_later_realities_of_opt_in_candidates_and_every_case_keeps_its_seed():
    from drillgym.eval.diagnosis.bench.cases import LATER_SINGLES, SINGLES, opt_in_candidates

    default, with_opt_in = full_cases(), full_cases(opt_in=True)
    assert set(opt_in_candidates()) == {"ft_contact_bias", "registration", "ft_gain", "kinematic_offset_trend"}
    assert len(with_opt_in) == len(default) + 2 * 4  # ft_load_bias, bone_registration, ft_lateral_gain, joint_drift
    seeds = {c.name: c.seed for c in with_opt_in}
    assert all(seeds[c.name] == c.seed for c in default)
    assert len(set(seeds.values())) == len(seeds)
    # a later reality of a default candidate is a default case, at the seed it has in the opt-in run
    for name in ("mount_resonance", "gear_backlash"):
        assert seeds[f"{name}-strong"] == 100 + 2 * list(SINGLES | LATER_SINGLES).index(name) + 1
        assert f"{name}-strong" in {c.name for c in default}


def test_an_ft_calibration_error_is_named_with_intervals_holding_its_gain_and_cross_talk_when_ft_gain_is_a_candidate(
    tmp_path,
):
    # Fx and Fy read 1.2 times the force and Fx 2 % of the thrust besides: the calibration matrix's x row off.
    res = diagnosed(tmp_path, "ft_lateral_gain:gain=0.2,crosstalk=0.02", 2, 12, ("ft_drift", "ft_gain"))
    assert res["named"] == ["ft_gain"] and res["off_point_guard"] is None
    named = next(e for e in res["effects"] if e["named"])
    intervals = named["param_intervals"]["ft_gain"]
    for param, truth, width in (("fxy_gain", 0.2, 0.05), ("fx_from_fz", 0.02, 0.005)):
        ci = intervals[param]
        assert ci["low"] <= truth <= ci["high"] and ci["high"] - ci["low"] < width and not ci["contains_off"]
    assert intervals["fy_from_fz"]["contains_off"] and intervals["fz_gain"]["contains_off"]  # not in the reality


def test_a_smoothing_tracker_is_named_as_a_late_tracker_with_its_lag_when_tracker_latency_is_a_candidate(tmp_path):
    # The reality is a first-order pose filter (time constant 60 ms), the candidate a pure delay: at a steady
    # speed the filter lags by its time constant, and that is the delay the fit should find.
    make_reality("tracker_smoothing:tau_s=0.06", 12, 11, tmp_path / "logs")
    eps, _ = load_episodes(tmp_path / "logs")
    candidates = ("ft_drift", "latency", "joint_friction", "tracker_latency")
    res = diagnose(eps, DiagnoseOptions(workers=1, candidates=candidates, progress=False))
    assert res["named"] == ["tracker_latency"]
    named = next(e for e in res["effects"] if e["named"])
    assert named["shrink"] > 0.8
    ci = named["param_intervals"]["tracker_latency"]["latency_s"]
    assert 0.055 <= ci["low"] <= ci["high"] <= 0.065 and not ci["contains_off"]


def test_a_registration_error_is_named_alone_not_with_a_stick_out_error_that_moves_the_touch_alike(tmp_path):
    # The bone 0.6 mm further along the axis and tilted 0.08 rad: a stick-out error also moves where the drill
    # first touches, but the registration alone (started from the contact shifts) explains it; the stick-out on
    # top of it is not named.
    res = diagnosed(tmp_path, "bone_registration:ez_m=6e-4,tilt_rad=0.08", 11, 12, ("tool_length", "registration"))
    assert res["verdict"] == "explained" and res["named"] == ["registration"]
    named = next(e for e in res["effects"] if e["named"])
    assert named["shrink"] > 0.95
    assert abs(named["params"]["registration"]["surface_dz_m"] - 6e-4) < 5e-5
    tilt = named["param_intervals"]["registration"]["slope_error_rad"]
    assert tilt["low"] <= 0.08 <= tilt["high"] and not tilt["contains_off"]


def test_a_mount_with_a_bending_and_an_axial_mode_is_named_a_resonance_with_both_frequencies(tmp_path):
    res = diagnosed(
        tmp_path, "mount_resonance:freq_xy_hz=15,freq_z_hz=30,damping=0.05", 11, 12, ("ft_drift", "ft_resonance")
    )
    assert res["verdict"] == "explained" and res["named"] == ["ft_resonance"]
    named = next(e for e in res["effects"] if e["named"])
    assert named["shrink"] > 0.9
    params = named["params"]["ft_resonance"]
    assert abs(params["freq_lateral_hz"] - 15.0) < 0.5 and abs(params["freq_axial_hz"] - 30.0) < 1.0
