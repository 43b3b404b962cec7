"""`drillgym train --sweep`: the spec is checked without Ray; a small sweep runs end to end with ASHA."""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.eval.cli import main
from drillgym.training.sweep import load_sweep

SWEEPS = Path(__file__).resolve().parents[2] / "training" / "sweeps"


@pytest.mark.parametrize("name", ["small", "residual_sac"])
def test_shipped_sweeps_load(name):
    spec = load_sweep(SWEEPS / f"{name}.yaml")
    assert spec.name == name and spec.search and spec.evaluations >= 3
    assert spec.grace_period < spec.base.total_timesteps


def test_small_sweep_has_at_least_four_trials_and_overrides_apply():
    spec = load_sweep(SWEEPS / "small.yaml", {"seed": 3})
    kind, values = spec.search["residual_scale"]
    assert kind == "grid" and spec.samples * len(values) >= 4
    assert spec.base.seed == 3 and spec.base.net_arch == [16]  # from the base config ../configs/smoke.yaml


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("search: {learning_rat: {choice: [0.1]}}", "learning_rat"),
        ("search: {total_timesteps: {choice: [10, 20]}}", "fixed for a sweep"),
        ("search: {gamma: {normal: [0.9, 0.1]}}", "expected one of"),
        ("search: {gamma: {uniform: [0.99, 0.9]}}", "low < high"),
        ("search: {learning_rate: {loguniform: [0, 0.1]}}", "> 0"),
        ("search: {algo: {choice: [sac, dqn]}}", "dqn"),
        ("search: {gamma: {choice: [0.9]}}\nschedulr: {}", "schedulr"),
        ("search: {gamma: {choice: [0.9]}}\nscheduler: {grace: 3}", "grace"),
        ("fixed: {total_timesteps: 100, eval_freq: 200}\nsearch: {gamma: {choice: [0.9]}}", "no evaluation"),
        ("search: {}", "non-empty"),
    ],
)
def test_bad_sweeps_are_rejected_with_a_clear_message(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_sweep(path)


def test_ray_flags_without_a_sweep_are_an_error(tmp_path, capsys):
    assert main(["train", "--ray", "--out", str(tmp_path / "run")]) == 2
    assert "--sweep" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.expensive
def test_small_sweep_runs_stops_a_trial_early_and_exports_the_best_policy(tmp_path, ray_local):
    out = tmp_path / "sweep"
    assert main(["train", "--sweep", str(SWEEPS / "small.yaml"), "--ray", "--out", str(out)]) == 0
    trials = pd.read_csv(out / "trials.csv")
    assert len(trials) == 4 and (trials["status"] != "error").all()
    assert (trials["status"] == "stopped early").sum() >= 1  # ASHA cut at least one trial
    assert (trials["status"] == "finished").sum() >= 1
    summary = json.loads((out / "sweep.json").read_text())
    best = summary["best"]
    assert best["eval_deviation_mm"] == pytest.approx(trials["best_eval_deviation_mm"].min())
    meta = json.loads((out / "policy.json").read_text())
    assert meta["sweep"]["best"]["trial_id"] == best["trial_id"]
    assert meta["config"]["residual_scale"] == best["config"]["residual_scale"]
    controller = make_controller(f"residual:{out / 'policy.zip'}")
    env = gym.make("drillgym/UR5BoneDrill-v1")
    obs, _ = env.reset(seed=0)
    controller.set_plan(env.unwrapped.plan)
    action, _ = controller.predict(obs, episode_start=np.array([True]))
    assert action.shape == (4,) and np.all(np.abs(action) <= 1.0)
    env.close()
