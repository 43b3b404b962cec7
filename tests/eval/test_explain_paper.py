"""drillgym explain-paper: the held-out KP 4 numbers never enter a fit; fits, intervals and the choice."""

import json

import numpy as np
import pytest

import drillgym.eval.explain.predict as predict_mod
import drillgym.eval.explain.simulate as simulate_mod
from drillgym.eval.cli import main
from drillgym.eval.explain import pipeline as explain_pipeline
from drillgym.eval.explain.candidates import CANDIDATES, candidate
from drillgym.eval.explain.fit import fit_candidate, profile_interval
from drillgym.eval.explain.observations import FOLDS, METRICS, RUNS, calibration_targets, held_out_targets, sigma
from drillgym.eval.reproduce import paper


def fake_simulate(cand, value, runs, seeds):
    """A cheap stand-in for the simulator: each candidate weakens the compensator by its own curve."""
    share = 0.0 if cand is None else (value - cand.low) / (cand.high - cand.low)
    strength = {c.name: 0.6 + 0.4 * i / len(CANDIDATES) for i, c in enumerate(CANDIDATES)}
    k = 0.0 if cand is None else strength[cand.name] * share
    base = {
        "none": [0.71, 1.3, 0.98, 0.78],
        "kp1": [0.2 + 0.6 * k, 1.2, 0.3, 0.24],
        "kp4": [0.15 + 0.3 * k, 1.2 + k, 0.2, 0.2],
    }
    out = {"model_peak_n": 1.2}
    for run in runs:
        out[run] = {m: [v + 0.001 * s for s in seeds] for m, v in zip(METRICS, base[run], strict=True)}
    return out


@pytest.fixture
def fake_sim(monkeypatch):
    monkeypatch.setattr(simulate_mod, "simulate", fake_simulate)
    monkeypatch.setattr(predict_mod, "simulate", fake_simulate)
    monkeypatch.setattr(simulate_mod, "close", lambda: None)


SETTINGS = {"fit_seeds": 2, "predict_seeds": 2, "grid_points": 5, "refine_evals": 3}
NAMES = ["latency.extra_latency_s", "servo_deadband.band_m", "controller.ki"]


def _fits(doc):
    return {c["name"]: (c["params"], c["chi2"], c["fitted_on"]) for c in doc["candidates"]}


def test_poisoned_held_out_numbers_change_no_fit_and_no_choice(fake_sim, monkeypatch):
    seen_targets = []
    real_fit = predict_mod.fit_candidate

    def spy(cand, targets, *args):
        seen_targets.append(dict(targets))
        return real_fit(cand, targets, *args)

    monkeypatch.setattr(predict_mod, "fit_candidate", spy)
    clean = explain_pipeline.explain(NAMES, SETTINGS, workers=1)
    for key in ("deviation_mean_mm", "lateral_force_max_n", "lateral_force_stable_n", "hole_offset_mm"):
        monkeypatch.setitem(paper.LI2023_COMPENSATED, key, 1e3)  # KP 4 numbers poisoned
    poisoned = explain_pipeline.explain(NAMES, SETTINGS, workers=1)
    assert _fits(poisoned) == _fits(clean)
    assert poisoned["chosen"] == clean["chosen"] and clean["chosen"] is not None
    assert all(run != "kp4" for t in seen_targets for run, _ in t)
    # the poison did reach the scoring of the predictions
    rel = [c["prediction"]["deviation_mean_mm"]["rel_err"] for c in poisoned["candidates"]]
    assert all(r < -0.99 for r in rel)


def test_a_fit_refuses_held_out_numbers():
    targets = {**calibration_targets(), ("kp4", "deviation_mean_mm"): 0.305}
    with pytest.raises(ValueError, match="calibration runs"):
        fit_candidate(CANDIDATES[0], targets, {}, lambda x: {}, 3, 0)


def test_calibration_targets_hold_none_and_kp1_only_and_kp4_is_held_out():
    keys = set(calibration_targets())
    assert {run for run, _ in keys} == {"none", "kp1"}
    assert len(keys) == 5
    assert held_out_targets() == {
        "deviation_mean_mm": 0.305,
        "lateral_force_max_n": 0.7,
        "lateral_force_stable_n": 0.3,
        "hole_offset_mm": 0.2,
    }


def test_the_fit_finds_a_known_parameter_and_its_profile_interval():
    cand = candidate("controller.ki")
    truth = 1.3
    targets = calibration_targets()

    def evaluate(x):  # KP 1 deviation linear in ki, Li's value reached at ki = truth
        li = targets[("kp1", "deviation_mean_mm")]
        out = {"none": {k: targets[("none", k)] for k in METRICS}, "kp1": {"deviation_mean_mm": li + 0.2 * (x - truth)}}
        return out

    fit = fit_candidate(cand, targets, {}, evaluate, grid_points=9, refine_evals=8)
    assert fit.value == pytest.approx(truth, abs=0.01)
    s = sigma("deviation_mean_mm", targets[("kp1", "deviation_mean_mm")], 0.0)
    half = s / 0.2  # χ² = ((0.2 (x - truth)) / s)² reaches 1 here
    assert fit.interval == pytest.approx((truth - half, truth + half), abs=0.02)
    assert fit.plausible and fit.n_params == 1 and len(fit.fitted_on) == 5


def test_profile_interval_ends_at_the_searched_bound_when_it_does_not_close():
    pts = [(0.0, 0.0), (0.5, 0.5), (1.0, 0.9)]
    assert profile_interval(pts, 0.0, 1.0) == (0.0, 1.0)
    assert profile_interval([(0.0, 4.0), (1.0, 0.0), (2.0, 4.0)], 0.0, 2.0) == pytest.approx((0.75, 1.25))


def test_a_fit_pinned_at_its_bound_is_reported_implausible():
    cand = candidate("latency.extra_latency_s")
    targets = calibration_targets()

    def evaluate(x):  # wants ever more latency
        return {"none": {k: targets[("none", k)] for k in METRICS}, "kp1": {"deviation_mean_mm": 0.2 + x}}

    fit = fit_candidate(cand, targets, {}, evaluate, grid_points=5, refine_evals=3)
    assert fit.value == pytest.approx(cand.high)
    assert not fit.plausible and "pinned" in fit.note


@pytest.mark.parametrize("held_out", FOLDS)
def test_each_fold_calibrates_on_the_other_two_runs_and_holds_out_its_own(held_out):
    keys = set(calibration_targets(held_out))
    assert {run for run, _ in keys} == set(RUNS) - {held_out}
    assert len(keys) == {"kp4": 5, "none": 5, "kp1": 8}[held_out]  # Li reports 4 numbers of none and KP 4, 1 of KP 1
    assert set(held_out_targets(held_out)) == ({"deviation_mean_mm"} if held_out == "kp1" else set(METRICS))
    leaking = {**calibration_targets(held_out), (held_out, "deviation_mean_mm"): 0.3}
    with pytest.raises(ValueError, match="calibration runs"):
        fit_candidate(CANDIDATES[0], leaking, {}, lambda x: {}, 3, 0, held_out)


def test_an_unknown_held_out_run_is_refused():
    with pytest.raises(ValueError, match="unknown held-out run 'kp2'"):
        calibration_targets("kp2")


@pytest.mark.parametrize(
    ("held_out", "poison"),
    [
        ("none", {"LI2023_UNCOMPENSATED": METRICS}),
        ("kp1", {"LI2023_COMPENSATED": ("deviation_mean_mm_kp1",)}),
    ],
)
def test_a_folds_poisoned_held_out_numbers_change_none_of_its_fits(fake_sim, monkeypatch, held_out, poison):
    """The cross-validation folds keep the primary fold's rule: what a fold holds out reaches its scoring only."""
    clean = explain_pipeline.explain(NAMES, SETTINGS, workers=1, held_out=held_out)
    for table, keys in poison.items():
        for key in keys:
            monkeypatch.setitem(getattr(paper, table), key, 1e3)
    poisoned = explain_pipeline.explain(NAMES, SETTINGS, workers=1, held_out=held_out)
    assert _fits(poisoned) == _fits(clean) and poisoned["chosen"] == clean["chosen"]
    assert all(not name.startswith(f"{held_out}.") for c in clean["candidates"] for name in c["fitted_on"])
    rel = [c["prediction"]["deviation_mean_mm"]["rel_err"] for c in poisoned["candidates"]]
    assert all(r < -0.99 for r in rel)  # the poison did reach the predictions' scoring


def test_explain_folds_reports_every_fold_with_the_primary_one_first(fake_sim):
    from drillgym.eval.explain.report import markdown

    doc = json.loads(json.dumps(explain_pipeline.explain_folds(NAMES, SETTINGS, workers=1)))
    assert doc["held_out_run"] == "kp4" and set(doc["folds"]) == {"none", "kp1"}
    for held_out, fold in [("kp4", doc), *doc["folds"].items()]:
        assert fold["li"][held_out]["role"] == "held_out"
        assert {run for run, v in fold["li"].items() if v["role"] == "calibration"} == set(RUNS) - {held_out}
        for c in fold["candidates"]:
            assert set(c["prediction"]) == set(held_out_targets(held_out))  # only what Li reports is scored
    # the primary fold is the same document explain() gives alone
    alone = json.loads(json.dumps(explain_pipeline.explain(NAMES, SETTINGS, workers=1)))
    assert _fits(alone) == _fits(doc) and alone["chosen"] == doc["chosen"]
    text = markdown(doc)
    assert "## Cross-validation: every run of Li's held out in turn" in text
    for title in (
        "(fit on none + KP 1, predict KP 4)",
        "(fit on KP 1 + KP 4, predict none)",
        "(fit on none + KP 4, predict KP 1)",
    ):
        assert title in text
    assert "KP 1 dev (mm)" in text  # the primary fold's table keeps its KP 1 column
    from drillgym.eval.explain.report import reproduction_section

    section = "\n".join(reproduction_section(doc))
    assert "### Cross-validation: every run of Li's held out in turn" in section and "| KP 1 |" in section
    kp1_first = doc["folds"]["kp1"]  # a document whose primary fold is not KP 4 (explain-paper --folds kp1)
    assert "--folds kp4" in "\n".join(reproduction_section(kp1_first))


@pytest.mark.parametrize(
    ("folds", "message"),
    [("kp2", "unknown run"), ("kp4,kp4", "twice"), (",", "empty")],
)
def test_bad_folds_are_refused_before_anything_runs(tmp_path, capsys, folds, message):
    out = tmp_path / "ex"
    assert main(["explain-paper", "--quick", "--folds", folds, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err and not out.exists()


def test_explain_paper_quick_on_the_simulator_writes_its_json(tmp_path):
    out = tmp_path / "ex"
    code = main(
        ["explain-paper", "--quick", "--candidates", "joint_friction.coulomb_rad", "--workers", "1", "--out", str(out)]
    )
    assert code == 0
    doc = json.loads((out / "explanation.json").read_text())
    assert set(doc["folds"]) == {"none", "kp1"}  # every fold by default
    for held_out, fold in doc["folds"].items():
        (c,) = fold["candidates"]
        assert c["fitted_on"] == sorted(f"{run}.{k}" for run, k in calibration_targets(held_out))
        assert set(c["prediction"]) == set(held_out_targets(held_out))
        assert all(np.isfinite(p["rel_err"]) for p in c["prediction"].values())
    (c,) = doc["candidates"]
    assert c["fitted_on"] == sorted(f"{run}.{k}" for run, k in calibration_targets())
    v = c["params"]["coulomb_rad"]
    assert v["interval"][0] <= v["value"] <= v["interval"][1]
    assert 0.0 < v["value"] <= 1e-3
    # a weaker compensator: KP 1 moves toward Li's 0.587 mm from the nominal cell's ~0.2 mm
    assert (
        c["calibration"]["kp1.deviation_mean_mm"]["sim"]
        > doc["nominal"]["calibration"]["kp1.deviation_mean_mm"]["sim"] + 0.1
    )
    pred = c["prediction"]["deviation_mean_mm"]
    assert pred["li"] == 0.305 and np.isfinite(pred["rel_err"])
    assert doc["chosen"] in (None, c["name"])


def test_the_reproduction_section_reports_fit_prediction_and_what_is_unexplained(fake_sim):
    from drillgym.eval.explain.report import reproduction_section

    assert "drillgym explain-paper" in "\n".join(reproduction_section(None))
    doc = json.loads(json.dumps(explain_pipeline.explain(NAMES, SETTINGS, workers=1)))  # as read from explanation.json
    text = "\n".join(reproduction_section(doc, "x/explanation.json"))
    assert f"**{doc['chosen']}**" in text and "Fitted:" in text
    for metric in METRICS:
        assert metric in text
    assert "What remains unexplained" in text
