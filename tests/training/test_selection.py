"""Model selection by the benchmark's own criteria on the validation episodes (training.selection)."""

import pytest

from drillgym.training.selection import MAX_TIME_RATIO, choose, judge

BASE = {
    "deviation_mean_mm": [0.10, 0.12, 0.08, 0.11],
    "lateral_force_max_n": [1.0, 1.1, 0.9, 1.0],
    "drill_time_s": [15.0] * 4,
}


def _policy(dev_shift, force_shift, time_scale=1.0):
    return {
        "deviation_mean_mm": [v + dev_shift + 0.001 * i for i, v in enumerate(BASE["deviation_mean_mm"])],
        "lateral_force_max_n": [v + force_shift + 0.01 * i for i, v in enumerate(BASE["lateral_force_max_n"])],
        "drill_time_s": [v * time_scale for v in BASE["drill_time_s"]],
    }


def test_a_lower_deviation_at_the_same_force_is_feasible_and_better():
    row = judge(_policy(-0.02, -0.015), BASE)
    assert row["better"] and row["feasible"]
    assert row["d_deviation_mm"] == pytest.approx(-0.02 + 0.0015)
    assert row["d_deviation_low"] < row["d_deviation_mm"] < row["d_deviation_high"] < 0


def test_a_significantly_higher_peak_force_or_a_much_longer_drill_is_infeasible():
    assert not judge(_policy(-0.02, +0.2), BASE)["feasible"]
    assert not judge(_policy(-0.02, -0.015, MAX_TIME_RATIO + 0.01), BASE)["feasible"]
    assert judge(_policy(-0.02, -0.015, MAX_TIME_RATIO - 0.01), BASE)["feasible"]


def _row(name, dev, feasible, better):
    return {"candidate": name, "deviation_mean_mm": dev, "feasible": feasible, "better": better}


def test_the_lowest_deviation_among_models_that_beat_the_base_is_chosen():
    rows = [_row("checkpoint_10000", 0.05, True, True), _row("checkpoint_20000", 0.04, False, True)]
    rows.append(_row("final", 0.045, True, True))
    assert choose(rows)[0] == "final"


def test_without_a_winner_the_feasible_lowest_deviation_then_the_final_model_is_chosen():
    rows = [_row("checkpoint_10000", 0.05, True, False), _row("final", 0.06, True, False)]
    name, rule = choose(rows)
    assert name == "checkpoint_10000" and "no saved model beat the base" in rule
    assert choose([_row("checkpoint_10000", 0.05, False, True), _row("final", 0.06, False, False)])[0] == "final"


@pytest.mark.expensive
def test_a_run_exports_the_selected_model_and_select_only_repeats_the_choice(tmp_path):
    import json
    import zipfile
    from pathlib import Path

    from drillgym.eval.cli import main

    smoke = (Path(__file__).resolve().parents[2] / "training" / "configs" / "smoke.yaml").read_text()
    cfg = tmp_path / "c.yaml"
    cfg.write_text(smoke + "eval_episodes: 2\neval_scenarios: validation\nmodel_selection: deviation\n")
    out = tmp_path / "run"
    assert main(["train", "--config", str(cfg), "--out", str(out)]) == 0
    first = json.loads((out / "selection.json").read_text())
    names = {r["candidate"] for r in first["candidates"]}
    assert names == {"checkpoint_300", "checkpoint_600", "final"} and first["chosen"] in names

    def weights(p):
        with zipfile.ZipFile(p) as z:
            return z.read("policy.pth")

    assert weights(out / "policy.zip") == weights(out / "candidates" / f"{first['chosen']}.zip")
    assert json.loads((out / "summary.json").read_text())["selection"]["chosen"] == first["chosen"]
    assert main(["train", "--out", str(out), "--select-only"]) == 0
    again = json.loads((out / "selection.json").read_text())
    assert again["chosen"] == first["chosen"] and again["candidates"] == first["candidates"]


def test_extra_paper_episodes_are_the_paper_scenario_on_their_own_seeds():
    from drillgym.envs.seeds import Purpose, episode_seed
    from drillgym.training.config import TrainConfig
    from drillgym.training.selection import PAPER_SELECTION_SEED, validation_episodes

    episodes = validation_episodes(TrainConfig(eval_episodes=3, selection_paper_episodes=2))
    assert len(episodes) == 5 and episodes[3:] == [
        ({}, episode_seed(Purpose.SELECT, PAPER_SELECTION_SEED + i)) for i in range(2)
    ]
    assert min(seed for _, seed in episodes) > 1000  # never the benchmark's seeds 0..N-1


def test_a_paper_episode_after_a_draw_is_scored_in_the_paper_scenario():
    from drillgym.controllers import make_controller
    from drillgym.training.config import TrainConfig
    from drillgym.training.selection import score

    cfg = TrainConfig()
    draw = {"beta_deg": 15.0, "feed_mm_s": 1.0, "stickout_mm": 30.0}
    after = score(lambda: make_controller("none"), cfg, [(draw, 1), ({}, 2)])
    alone = score(lambda: make_controller("none"), cfg, [({}, 2)])
    assert after["deviation_mean_mm"][1] == alone["deviation_mean_mm"][0]


def test_scoring_on_the_batched_engine_gives_the_single_envs_numbers():
    """The validation episodes run as one batch; each must score as the single env drills it after the cycle's reset."""
    import gymnasium as gym

    from drillgym.controllers import make_controller
    from drillgym.controllers.rollout import run_episode
    from drillgym.envs import SIM_ENV_ID
    from drillgym.training.config import TrainConfig
    from drillgym.training.domain_randomization import ScenarioCycle
    from drillgym.training.selection import score

    cfg = TrainConfig()
    episodes = [({"beta_deg": 15.0, "feed_mm_s": 1.0, "stickout_mm": 30.0}, 1), ({}, 2), ({"bone": "porcine_femur"}, 7)]
    batched = score(lambda: make_controller("li2023_tuned"), cfg, episodes)
    env = ScenarioCycle(gym.make(SIM_ENV_ID), [sc for sc, _ in episodes], [s for _, s in episodes])
    controller = make_controller("li2023_tuned")
    single = [run_episode(env, controller, seed=None, keep_trace=False).metrics for _ in episodes]
    env.close()
    for key, values in batched.items():
        assert values == [m[key] for m in single], key
