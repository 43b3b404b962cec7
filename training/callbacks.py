"""SB3 callbacks: evaluation against the base controller, and the training-curve record."""

from __future__ import annotations

import csv
import json
import math
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecEnvWrapper

CURVE_COLUMNS = (
    "timesteps",
    "policy_reward",
    "policy_deviation_mean_mm",
    "policy_lateral_force_max_n",
    "base_reward",
    "base_deviation_mean_mm",
    "base_lateral_force_max_n",
)

BEST_NORMALIZER = "vecnormalize.pkl"
"""Saved beside ``best_model.zip`` whenever a new best model is saved."""
BEST_RECORD = "best.json"
"""Saved beside ``best_model.zip`` whenever a new best model is saved: its ``policy_reward`` and ``timesteps``."""
CURVE_FILE = "curve.csv"
"""The evaluations of a run (``CURVE_COLUMNS``), in its folder."""


def read_curve(path: Path) -> list[dict[str, float]]:
    """The rows of a run's ``curve.csv`` (every column a float; NaN where a metric was missing); [] if none."""
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return [
            {k: float(row[k]) if row.get(k) not in (None, "") else math.nan for k in CURVE_COLUMNS}
            for row in csv.DictReader(f)
        ]


def read_best_reward(best_dir: Path) -> float:
    """The mean validation reward of the saved ``best_model.zip`` in ``best_dir`` (-inf if none was recorded)."""
    record = best_dir / BEST_RECORD
    if not record.exists():
        return -math.inf
    value = json.loads(record.read_text()).get("policy_reward")
    return float(value) if value is not None else -math.inf


def vectorised_alike(a: VecEnv, b: VecEnv) -> bool:
    """Whether ``a`` and ``b`` have the same VecEnv wrappers (outermost first) over a DummyVecEnv or SubprocVecEnv."""

    def layers(v: VecEnv) -> tuple[list[type], type]:
        wrappers: list[type] = []
        while isinstance(v, VecEnvWrapper):
            wrappers.append(type(v))
            v = v.venv
        return wrappers, type(v)

    (wrap_a, base_a), (wrap_b, base_b) = layers(a), layers(b)
    return wrap_a == wrap_b and {base_a, base_b} <= {DummyVecEnv, SubprocVecEnv}


class ZeroResidual:
    """A 'policy' that always outputs a zero residual: the base controller alone."""

    def __init__(self, action_dim: int) -> None:
        self.action_dim = action_dim

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple:
        """Zeros for every env of the batch."""
        n = len(next(iter(observation.values()))) if isinstance(observation, dict) else len(observation)
        return np.zeros((n, self.action_dim), dtype=np.float32), state


class BaseComparisonEvalCallback(EvalCallback):
    """SB3's EvalCallback that also scores the base controller and records the drilling metrics.

    The base is evaluated once (it does not learn) on the same seeded episodes; every evaluation of the
    policy then logs its reward, deviation and max lateral force beside the base's to TensorBoard
    (``eval/...``) and to ``curve.csv`` in ``log_path``.

    A resumed run passes the evaluations made before its checkpoint (``previous_curve``, kept at the head of
    ``curve.csv``) and the reward of the best model saved so far (``previous_best_reward``): a later
    evaluation replaces ``best_model.zip`` only if it beats that.
    """

    def __init__(
        self,
        eval_env: VecEnv,
        action_dim: int,
        previous_curve: Sequence[dict[str, float]] = (),
        previous_best_reward: float = -math.inf,
        **kwargs: Any,
    ) -> None:
        super().__init__(eval_env, **kwargs)
        self.action_dim = action_dim
        self._episode_metrics: list[dict[str, float]] = []
        self.base: dict[str, float] = {}
        self.curve: list[dict[str, float]] = [dict(r) for r in previous_curve]
        self.best_mean_reward = float(previous_best_reward)

    def _init_callback(self) -> None:
        with warnings.catch_warnings():
            if vectorised_alike(self.training_env, self.eval_env):
                # SB3 warns unless the training env is an instance of the eval env's class, to catch an eval env
                # wrapped otherwise (no VecNormalize, say). With several workers ours are a SubprocVecEnv and a
                # one-env DummyVecEnv, built by the same factories under the same wrappers: the vectoriser is
                # all that differs and it changes no observation, so that one warning is noise here.
                warnings.filterwarnings("ignore", message="Training and eval env are not of the same type")
            super()._init_callback()
        self._episode_metrics = []
        rewards, _ = evaluate_policy(
            ZeroResidual(self.action_dim),
            self.eval_env,
            n_eval_episodes=self.n_eval_episodes,
            deterministic=True,
            return_episode_rewards=True,
            callback=self._log_success_callback,
        )
        self.base = self._summary(rewards)

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_.get("done") and "metrics" in locals_["info"]:
            self._episode_metrics.append(locals_["info"]["metrics"])

    def _summary(self, rewards: Any) -> dict[str, float]:
        m = self._episode_metrics
        self._episode_metrics = []
        return {
            "reward": float(np.mean(rewards)),
            "deviation_mean_mm": float(np.mean([x["deviation_mean_mm"] for x in m])) if m else float("nan"),
            "lateral_force_max_n": float(np.mean([x["lateral_force_max_n"] for x in m])) if m else float("nan"),
        }

    def _on_step(self) -> bool:
        evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
        self._episode_metrics = []
        best_before = self.best_mean_reward
        keep_going = super()._on_step()
        normalizer = self.model.get_vec_normalize_env()
        if self.best_mean_reward > best_before and self.best_model_save_path is not None:
            best = Path(self.best_model_save_path)
            if normalizer is not None:  # the best model's observation statistics: the ones it was just evaluated with
                normalizer.save(str(best / BEST_NORMALIZER))
            record = {"policy_reward": float(self.best_mean_reward), "timesteps": int(self.num_timesteps)}
            (best / BEST_RECORD).write_text(json.dumps(record))
        if evaluating and self.evaluations_results:
            policy = self._summary(self.evaluations_results[-1])
            row = {
                "timesteps": float(self.num_timesteps),
                "policy_reward": policy["reward"],
                "policy_deviation_mean_mm": policy["deviation_mean_mm"],
                "policy_lateral_force_max_n": policy["lateral_force_max_n"],
                "base_reward": self.base["reward"],
                "base_deviation_mean_mm": self.base["deviation_mean_mm"],
                "base_lateral_force_max_n": self.base["lateral_force_max_n"],
            }
            self.curve.append(row)
            for key in (
                "policy_deviation_mean_mm",
                "base_deviation_mean_mm",
                "policy_lateral_force_max_n",
                "base_reward",
            ):
                self.logger.record(f"eval/{key}", row[key])
            if self.log_path is not None:
                self._write_curve(Path(self.log_path).parent / CURVE_FILE)
        return keep_going

    def _write_curve(self, path: Path) -> None:
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(CURVE_COLUMNS))
            w.writeheader()
            w.writerows(self.curve)


class TimedCheckpointCallback(CheckpointCallback):
    """SB3's ``CheckpointCallback`` that also saves the run's training time so far beside each checkpoint.

    ``rl_model_time_<steps>_steps.json`` holds ``wall_time_s``: the seconds spent training up to that
    checkpoint, over every session of the run (``elapsed_before_s`` is what the sessions before this one took
    up to the checkpoint it resumed from). A resumed run starts its clock from there.
    """

    def __init__(self, *args: Any, elapsed_before_s: float = 0.0, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.elapsed_before_s = float(elapsed_before_s)
        self._t0 = time.perf_counter()

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()

    def elapsed_s(self) -> float:
        """Training time of the run so far (s), this session's included."""
        return self.elapsed_before_s + time.perf_counter() - self._t0

    def _on_step(self) -> bool:
        keep_going = super()._on_step()
        if self.n_calls % self.save_freq == 0:
            Path(self._checkpoint_path("time_", extension="json")).write_text(
                json.dumps({"wall_time_s": self.elapsed_s(), "timesteps": int(self.num_timesteps)})
            )
        return keep_going


def checkpoint_wall_time_s(checkpoints: Path, steps: int) -> float | None:
    """Training time up to the checkpoint of ``steps`` (s), as :class:`TimedCheckpointCallback` saved it; None if absent."""
    record = checkpoints / f"rl_model_time_{steps}_steps.json"
    return float(json.loads(record.read_text())["wall_time_s"]) if record.exists() else None
