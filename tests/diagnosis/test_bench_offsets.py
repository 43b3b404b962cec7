"""The benchmark over several seed offsets: every offset's cases run on their own seeds, then counted together."""

import json

from drillgym.eval.diagnosis.bench.cases import Case
from drillgym.eval.diagnosis.bench.offsets import counts, false_attributions, run_offsets
from drillgym.eval.diagnosis.bench.run import error_row


def _case(name: str, kind: str, spec: str, seed: int) -> Case:
    return Case(name=name, kind=kind, spec=spec, seed=seed)


def _row(case: Case, named: list[str], correct: bool) -> dict:
    return {**error_row(case, ""), "named": named, "correct": correct}


def test_every_offset_runs_its_cases_on_shifted_seeds_and_the_pooled_counts_add_them_up(tmp_path):
    cases = [
        _case("one", "single", "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4", 10),
        _case("quiet", "clean", "none", 20),
        _case("both", "pair", "jittered_latency:mean_s=0.08,jitter_s=0.02+heat_softening:softening_per_k=0.002", 30),
    ]
    seen: dict[str, list[int]] = {}

    def run(cs, out):  # offset 0: all right; offset 1000: the clean case names friction, the pair only one effect
        seen[out.name] = [c.seed for c in cs]
        shifted = cs[0].seed != 10
        rows = [
            _row(cs[0], ["joint_friction"], True),
            _row(cs[1], ["joint_friction"] if shifted else [], not shifted),
            _row(cs[2], ["latency"] if shifted else ["latency", "thermal_softening"], not shifted),
        ]
        return {"rows": rows, "summary": {"wall_s": 1.0}}

    pooled = run_offsets(cases, [0, 1000], tmp_path, run)
    assert seen == {"offset-0": [10, 20, 30], "offset-1000": [1010, 1020, 1030]}
    assert pooled["offsets"]["0"]["clean"] == {"right": 1, "cases": 1}
    assert pooled["offsets"]["1000"]["false_attributions"] == ["quiet"]
    assert pooled["pooled"]["single"] == {"right": 2, "cases": 2}
    assert pooled["pooled"]["pair"] == {"right": 1, "cases": 2}
    assert pooled["pooled"]["false_attributions"] == ["quiet (offset 1000)"]  # naming one of two is no false one
    assert json.loads((tmp_path / "bench.json").read_text())["pooled"]["clean"] == {"right": 1, "cases": 2}
    md = (tmp_path / "bench.md").read_text()
    assert (
        "| pair | 1/1 (100.0 %) | 0/1 (0.0 %) | 1/2 (50.0 %) | ≥ 90 % | False |" in md and "quiet (offset 1000)" in md
    )
    assert pooled["met"] == {
        "single": True,
        "pair": False,
        "clean": False,
        "outside": None,
        "false_attributions": False,
    }


def test_a_false_attribution_is_named_physics_outside_the_truth_whatever_the_form():
    rows = [
        {"case": "drift", "kind": "single", "truth": ["ft_drift"], "named": ["ft_episode_drift"]},  # same physics
        {"case": "void", "kind": "outside", "truth": [], "named": ["density_gradient"]},
        {"case": "miss", "kind": "single", "truth": ["latency"], "named": []},
    ]
    assert false_attributions(rows) == ["void"]
    assert counts([{**r, "correct": False} for r in rows])["outside"] == {"right": 0, "cases": 1}


def test_the_benchmarks_summary_holds_a_wrong_effect_named_to_none():
    from drillgym.eval.diagnosis.bench.run import summarise

    single = _case("one", "single", "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4", 10)
    right = summarise([_row(single, ["joint_friction"], True)])
    wrong = summarise([_row(single, ["density_gradient"], False)])
    assert right["passed"]["wrong_effect_named_rate"] and not wrong["passed"]["wrong_effect_named_rate"]
    assert wrong["acceptance_at_most"] == {"wrong_effect_named_rate": 0.0}


def test_a_false_attribution_that_listed_the_true_physics_as_not_ruled_out_says_so(tmp_path):
    from drillgym.eval.diagnosis.bench.run import summarise, truth_not_ruled_out

    alternatives = [{"name": "thermal_softening", "effects": ["thermal_softening"], "p_better": 0.06}]
    assert truth_not_ruled_out(["thermal_softening"], alternatives)
    assert not truth_not_ruled_out(["latency", "thermal_softening"], alternatives)  # half the truth is not it
    assert not truth_not_ruled_out([], alternatives)  # an outside effect has no physics in the library
    heat = _case("heat", "single", "heat_softening:softening_per_k=0.002", 10)
    layer = _case("layer", "single", "density_layer:hardening=0.2", 20)
    rows = [
        {**_row(heat, ["density_gradient"], False), "truth_not_ruled_out": True},
        {**_row(layer, ["thermal_softening"], False), "truth_not_ruled_out": False},
    ]
    assert false_attributions(rows) == ["heat (truth not ruled out)", "layer"]
    assert summarise(rows)["figures"]["wrong_effect_named_truth_not_ruled_out"] == 1

    def run(cs, out):
        return {"rows": [{**rows[0], "case": cs[0].name}], "summary": {"wall_s": 1.0}}

    pooled = run_offsets([heat], [0], tmp_path, run)
    assert pooled["pooled"]["false_attributions"] == ["heat (offset 0, truth not ruled out)"]
    assert (
        "In 1 of 1 the diagnosis listed a model of the true physics as not ruled out"
        in (tmp_path / "bench.md").read_text()
    )
