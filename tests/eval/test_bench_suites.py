import pandas as pd
import pytest

from drillgym.envs.effects import build_effects
from drillgym.envs.scenario import Scenario
from drillgym.eval.bench.suites import SUITES, TRAINING_BONES, TRAINING_RANGES, outside_training, suite_scenarios


def test_every_heldout_scenario_lies_outside_the_training_ranges_in_at_least_one_parameter():
    heldout = suite_scenarios("heldout")
    assert [s.name for s in heldout] == [
        "beta10",
        "beta40",
        "feed1.2",
        "human_femur",
        "sawbones",
        "stickout26",
        "stickout48",
        "thin_cortex",
    ]
    for sc in heldout:
        assert outside_training(sc.kwargs), f"{sc.name} lies inside the training ranges"


def test_the_paper_scenario_lies_inside_the_training_ranges():
    assert outside_training({}) == []
    assert set(TRAINING_RANGES) <= {f for f in Scenario.__dataclass_fields__}
    assert "buffalo_femur" in TRAINING_BONES


def test_sweep_is_the_beta_by_feed_grid_with_readable_names():
    sweep = suite_scenarios("sweep")
    assert len(sweep) == 20
    assert "b30_f0.50" in [s.name for s in sweep]
    assert {(s.kwargs["beta_deg"], s.kwargs["feed_mm_s"]) for s in sweep} == {
        (b, f) for b in (10.0, 20.0, 30.0, 40.0) for f in (0.25, 0.5, 0.75, 1.0, 1.25)
    }


@pytest.mark.parametrize("suite", list(SUITES))
def test_every_suite_scenario_is_a_valid_scenario_with_a_unique_name(suite):
    scenarios = suite_scenarios(suite)
    assert len({s.name for s in scenarios}) == len(scenarios)
    for sc in scenarios:
        Scenario.from_kwargs(**sc.kwargs)
        if sc.effects:
            assert build_effects(sc.effects)  # a valid spec that switches something on


def test_unknown_suite_lists_the_known_ones():
    with pytest.raises(ValueError, match="paper, sweep, heldout"):
        suite_scenarios("marathon")


def test_generalisation_plans_lie_strictly_inside_the_training_ranges_and_are_fixed():
    plans = suite_scenarios("generalisation")
    assert [p.name for p in plans] == [f"g{i:02d}" for i in range(1, 25)]
    assert plans == suite_scenarios("generalisation")  # a fixed stream: the same plans every time
    for p in plans:
        assert outside_training(p.kwargs) == [], p
        for name, (lo, hi) in TRAINING_RANGES.items():
            assert lo < p.kwargs[name] < hi, (p.name, name)  # never on an edge, where a table's anchors sit
    assert {p.kwargs["bone"] for p in plans} == set(TRAINING_BONES)
    assert len({tuple(sorted(p.kwargs.items())) for p in plans}) == 24


def test_no_generalisation_plan_is_a_validation_plan_the_learner_is_selected_on():
    from drillgym.training.domain_randomization import validation_scenarios

    validation = [{k: v for k, v in sc.items() if k in {*TRAINING_RANGES, "bone"}} for sc in validation_scenarios(200)]
    plans = [p.kwargs for p in suite_scenarios("generalisation")]
    assert not [p for p in plans if p in validation]


def test_the_robustness_suite_is_the_paper_plan_in_each_cell_and_the_generalisation_plans_in_drawn_cells():
    from drillgym.eval.bench.suites import JUDGE_ONLY_SUITES, ROBUSTNESS_CELLS, ROBUSTNESS_DRAWS

    scenarios = suite_scenarios("robustness")
    plans = [f"g{i:02d}_drawn" for i in range(1, 25)]
    assert [s.name for s in scenarios] == [*(f"paper_{c}" for c in ROBUSTNESS_CELLS), "paper_drawn", *plans]
    assert all(s.effects for s in scenarios)
    assert all(s.kwargs == {} for s in scenarios if s.name.startswith("paper_"))
    general = {s.name: s.kwargs for s in suite_scenarios("generalisation")}
    for s in scenarios[len(ROBUSTNESS_CELLS) + 1 :]:  # the generalisation plans, in the drawn cell
        assert s.kwargs == general[s.name.removesuffix("_drawn")] and s.draws == ROBUSTNESS_DRAWS
    singles = [s for s in scenarios if s.name.startswith("paper_") and s.name not in ("paper_all", "paper_drawn")]
    combined = {type(e).name for e in build_effects(ROBUSTNESS_CELLS["all"])}
    assert combined == {type(build_effects(s.effects)[0]).name for s in singles}
    assert "robustness" in JUDGE_ONLY_SUITES  # no tuner may see it


def test_the_drawn_cell_draws_every_effect_within_its_range_per_episode_the_same_for_every_controller():
    from drillgym.eval.bench.episode import grid_jobs
    from drillgym.eval.bench.suites import ROBUSTNESS_CELLS, ROBUSTNESS_DRAWS
    from drillgym.training.cell import TrainingCell

    jobs = [j for j in grid_jobs(["robustness"], ["none", "li2023"], 30) if j.scenario == "paper_drawn"]
    by_seed: dict[int, set[str]] = {}
    for job in jobs:
        by_seed.setdefault(job.seed, set()).add(job.effects)
    assert all(len(specs) == 1 for specs in by_seed.values())  # paired: one cell per seed for every controller
    drawn = [TrainingCell(next(iter(specs))).values for specs in by_seed.values()]
    assert len({str(d) for d in drawn}) == 30  # a new cell each episode
    assert {*drawn[0]} == {*TrainingCell(ROBUSTNESS_CELLS["all"]).values}  # every effect of the all cell
    for key, lo, hi in ROBUSTNESS_DRAWS:
        effect, param = key.split(".")
        values = [d[effect][param] for d in drawn]
        assert lo <= min(values) and max(values) <= hi and max(values) - min(values) > 0.5 * (hi - lo)


def test_a_scenarios_effects_reach_its_episodes_after_the_cells(tmp_path):
    from drillgym.eval.cli import main

    out = tmp_path / "bench"
    argv = ["bench", "--suite", "robustness", "--controllers", "none", "--seeds", "1", "--no-logs"]
    assert main([*argv, "--cell", "li2023-lab", "--out", str(out)]) == 0
    episodes = pd.read_csv(out / "episodes.csv").set_index("scenario")
    assert len(episodes) == len(suite_scenarios("robustness")) and episodes["error"].isna().all()
    ideal = episodes.loc["paper_tool_long", "deviation_mean_mm"]
    assert episodes.loc["paper_tool_short", "deviation_mean_mm"] != ideal  # each scenario its own cell


def test_a_cell_is_a_named_cell_or_an_effect_spec_and_a_spec_runs_as_that_cell(tmp_path):
    from drillgym.envs.effects.cells import CELLS, cell_effects_spec
    from drillgym.envs.errors import UserError
    from drillgym.eval.cli import main

    spec = CELLS["li2023-lab"]
    assert cell_effects_spec("li2023-lab") == spec and cell_effects_spec(spec) == spec
    with pytest.raises(UserError, match=r"unknown cell 'li2023_lab'.*effect spec"):
        cell_effects_spec("li2023_lab")
    argv = ["bench", "--suite", "paper", "--controllers", "none", "--seeds", "2", "--no-logs"]
    assert main([*argv, "--cell", "li2023-lab", "--out", str(tmp_path / "named")]) == 0
    assert main([*argv, "--cell", spec, "--out", str(tmp_path / "spec")]) == 0
    named, given = (pd.read_csv(tmp_path / d / "episodes.csv") for d in ("named", "spec"))
    assert named["deviation_mean_mm"].tolist() == given["deviation_mean_mm"].tolist()
