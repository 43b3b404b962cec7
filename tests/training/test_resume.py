"""A resumed training run carries its evaluations, its best model's reward and its training time."""

import json
import math
from pathlib import Path

import pytest

from drillgym.training.callbacks import read_curve
from drillgym.training.config import load_config
from drillgym.training.train import json_safe, train

SMOKE = Path(__file__).resolve().parents[2] / "training" / "configs" / "smoke.yaml"


def _strict(text: str) -> dict:
    def refuse(name: str) -> float:
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def test_json_safe_writes_nan_and_infinity_as_null():
    assert json_safe({"a": [math.nan, 1.0], "b": -math.inf, "c": {"d": math.inf, "e": 2}}) == {
        "a": [None, 1.0],
        "b": None,
        "c": {"d": None, "e": 2},
    }


@pytest.mark.expensive
def test_a_resumed_run_keeps_the_curve_best_reward_and_time_of_its_first_part(tmp_path):
    whole, split = tmp_path / "whole", tmp_path / "split"
    train(load_config(SMOKE, {"total_timesteps": 600}), whole)
    train(load_config(SMOKE, {"total_timesteps": 300}), split)  # a checkpoint and an evaluation at 300 steps
    first = _strict((split / "summary.json").read_text())
    train(load_config(SMOKE, {"total_timesteps": 600}), split, resume=True)

    summary = _strict((split / "summary.json").read_text())
    reference = _strict((whole / "summary.json").read_text())
    assert summary["timesteps"] == reference["timesteps"] == 600
    assert summary["resumed_from_timesteps"] == 300 and reference["resumed_from_timesteps"] is None
    assert [r["timesteps"] for r in summary["curve"]] == [r["timesteps"] for r in reference["curve"]] == [300, 600]
    assert summary["curve"][0] == first["curve"][0] == reference["curve"][0]  # the first part's row, kept
    assert read_curve(split / "eval" / "curve.csv")[0]["policy_reward"] == pytest.approx(
        first["curve"][0]["policy_reward"]
    )
    assert len(read_curve(split / "eval" / "curve.csv")) == 2
    assert summary["best_policy_reward"] >= first["best_policy_reward"]  # never replaced by a worse model
    assert summary["best_policy_reward"] == max(r["policy_reward"] for r in summary["curve"])
    assert summary["wall_time_s"] > first["wall_time_s"]  # both sessions' time
    assert (split / "training_curves.png").stat().st_size > 0
