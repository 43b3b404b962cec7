"""One Ray Tune trial: an SB3 residual-training run that reports its evaluations to Tune.

Each evaluation (``eval_freq`` agent steps; the same seeded paper-scenario episodes as ``drillgym
train``) reports the policy's mean tip deviation, :data:`METRIC` (mm, lower is better), with a
checkpoint: the model, its observation normaliser and the trial's configuration. The scheduler (ASHA)
compares trials on it and stops the poor ones early; a trial restarted after a failure resumes from
its latest checkpoint (without the replay buffer, which stays on the node).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import yaml
from stable_baselines3.common.callbacks import BaseCallback

from drillgym.training.callbacks import BaseComparisonEvalCallback
from drillgym.training.config import TrainConfig
from drillgym.training.env_factory import make_eval_vec_env, make_train_vec_env

METRIC = "eval_deviation_mm"
"""Reported metric: the policy's mean tip deviation over the evaluation episodes (mm; minimised)."""
TIME_ATTR = "timesteps"
"""Reported training progress (agent steps over all envs): ASHA's time axis."""


class TuneReportCallback(BaseCallback):
    """After each evaluation of ``evaluation`` (placed before it in the callback list), report to Tune."""

    def __init__(self, evaluation: BaseComparisonEvalCallback, cfg: TrainConfig) -> None:
        super().__init__()
        self.evaluation = evaluation
        self.cfg = cfg
        self._reported = 0

    def _on_step(self) -> bool:
        curve = self.evaluation.curve
        if len(curve) > self._reported:
            self._reported = len(curve)
            self.report(curve[-1])
        return True

    def report(self, row: dict[str, float]) -> None:
        """``tune.report`` the evaluation with a checkpoint (model.zip, vecnormalize.pkl, config.yaml)."""
        from ray import tune

        metrics = {
            METRIC: row["policy_deviation_mean_mm"],
            TIME_ATTR: int(self.num_timesteps),
            "eval_lateral_force_max_n": row["policy_lateral_force_max_n"],
            "eval_reward": row["policy_reward"],
            "base_deviation_mm": row["base_deviation_mean_mm"],
        }
        with tempfile.TemporaryDirectory(prefix="drillgym-ckpt-") as tmp:
            folder = Path(tmp)
            self.model.save(folder / "model.zip")
            normalizer = self.model.get_vec_normalize_env()
            if normalizer is not None:
                normalizer.save(str(folder / "vecnormalize.pkl"))
            (folder / "config.yaml").write_text(yaml.safe_dump(self.cfg.to_dict(), sort_keys=False))
            tune.report(metrics, checkpoint=tune.Checkpoint.from_directory(tmp))


def train_trial(config: dict[str, Any]) -> None:
    """Tune's function trainable: train ``TrainConfig(**config)``, reporting every evaluation."""
    import torch
    from ray import tune
    from stable_baselines3.common.vec_env import VecNormalize

    from drillgym.training.model import ALGO_CLASSES, build_model

    cfg = TrainConfig(**config)
    torch.set_num_threads(1)  # the trial's other CPUs run its SubprocVecEnv workers
    trial_dir = Path(tune.get_context().get_trial_dir())
    venv: Any = make_train_vec_env(cfg)
    resume = tune.get_checkpoint()
    with resume.as_directory() if resume is not None else tempfile.TemporaryDirectory() as ckpt:
        saved = Path(ckpt)
        if cfg.normalize_obs:
            if (saved / "vecnormalize.pkl").exists():
                venv = VecNormalize.load(str(saved / "vecnormalize.pkl"), venv)
            else:
                venv = VecNormalize(venv, norm_obs=True, norm_reward=False)
        if (saved / "model.zip").exists():
            model = ALGO_CLASSES[cfg.algo].load(saved / "model.zip", env=venv, device="cpu")
        else:
            model = build_model(cfg, venv, trial_dir / "tb")
    eval_env: Any = make_eval_vec_env(cfg)
    if cfg.normalize_obs:
        eval_env = VecNormalize(eval_env, norm_obs=True, norm_reward=False, training=False)
    evaluation = BaseComparisonEvalCallback(
        eval_env,
        int(venv.action_space.shape[0]),
        n_eval_episodes=cfg.eval_episodes,
        eval_freq=max(cfg.eval_freq // cfg.n_envs, 1),
        log_path=str(trial_dir / "eval"),
        deterministic=True,
        verbose=0,
    )
    try:
        model.learn(
            total_timesteps=max(cfg.total_timesteps - model.num_timesteps, 0),
            callback=[evaluation, TuneReportCallback(evaluation, cfg)],
            reset_num_timesteps=resume is None,
            tb_log_name="residual",
        )
    finally:
        venv.close()
        eval_env.close()
