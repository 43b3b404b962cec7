"""Residual RL with stable-baselines3 on top of a classical compensator: one training run.

``drillgym train`` (:mod:`drillgym.eval.cli.train`) runs it from the command line.

SB3 machinery throughout: ``make_vec_env`` (SubprocVecEnv), ``VecNormalize`` (saved with the model),
``EvalCallback`` (here also scoring the base controller), ``CheckpointCallback`` (with replay buffer
and normaliser, so a killed run resumes), TensorBoard logs and the progress bar.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path
from typing import Any

import yaml

from drillgym.envs.errors import UserError
from drillgym.envs.json_safe import json_safe
from drillgym.training.config import TrainConfig, load_config


def latest_checkpoint(folder: Path) -> tuple[Path, int] | None:
    """Newest ``rl_model_<steps>_steps.zip`` in ``folder`` and its step count."""
    best: tuple[Path, int] | None = None
    for p in folder.glob("rl_model_*_steps.zip"):
        m = re.fullmatch(r"rl_model_(\d+)_steps\.zip", p.name)
        if m and (best is None or int(m.group(1)) > best[1]):
            best = (p, int(m.group(1)))
    return best


RUN_ARTEFACTS = ("config.yaml", "checkpoints", "model.zip", "policy.zip", "best")
"""What marks a folder as holding a training run."""
RUN_FILES = (
    *RUN_ARTEFACTS,
    "candidates",
    "eval",
    "tb",
    "vecnormalize.pkl",
    "summary.json",
    "selection.csv",
    "selection.json",
    "training_curves.png",
    "policy.json",
    "policy.vecnormalize.pkl",
)
"""Everything a run writes into its folder (``--overwrite`` removes these, nothing else)."""


def clear_run(out: Path) -> None:
    """Remove a previous run's files from ``out`` (``--overwrite``)."""
    for name in RUN_FILES:
        p = out / name
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()


def check_run_folder(out: Path, resume: bool, overwrite: bool) -> None:
    """Refuse to resume nothing or to overwrite a run by accident (``ValueError`` saying what to do)."""
    if resume and overwrite:
        raise UserError("--resume and --overwrite contradict each other")
    if resume and latest_checkpoint(out / "checkpoints") is None:
        raise UserError(f"nothing to resume in {out}: no checkpoints/rl_model_<steps>_steps.zip")
    held = [name for name in RUN_ARTEFACTS if (out / name).exists()]
    if not resume and not overwrite and held:
        raise UserError(
            f"{out} already holds a training run ({', '.join(held)}): --resume continues it, --overwrite starts over"
        )


def _export(
    out: Path, cfg: Any, model: Any, evaluation: Any, wall_s: float, export: Path | None, resumed_from: int | None
) -> None:
    """Write ``summary.json`` and the curves; bundle the selected model as ``out/policy.zip`` (and ``export``).

    ``wall_s`` is the run's training time over all its sessions (s); ``resumed_from`` the step count of the
    checkpoint this session resumed from (None for a run in one session).
    """
    from drillgym.training.plots import plot_curves

    summary = {
        "timesteps": int(model.num_timesteps),
        "wall_time_s": wall_s,
        "resumed_from_timesteps": resumed_from,
        "base_eval": evaluation.base,
        "curve": evaluation.curve,
        "best_policy_reward": float(evaluation.best_mean_reward),  # None (null) when no evaluation ran
    }
    episodes = "paper scenario" if cfg.eval_scenarios == "paper" else f"{cfg.eval_episodes} validation episodes"
    plot_curves(evaluation.curve, out / "training_curves.png", episodes)
    export_selected(out, cfg, summary, export)


def export_selected(out: Path, cfg: Any, summary: dict[str, Any], export: Path | None) -> None:
    """Bundle the model that ``cfg.model_selection`` picks as ``out/policy.zip`` (and ``export``).

    ``reward``: SB3's best-reward model with the observation normaliser it was evaluated with (the final
    model if there is none); ``deviation``: :func:`drillgym.training.selection.select`'s choice.
    """
    from drillgym.training.callbacks import BEST_NORMALIZER
    from drillgym.training.policy_bundle import save_bundle

    best_zip, best_norm = out / "best" / "best_model.zip", out / "best" / BEST_NORMALIZER
    source: Path
    norm: Path | None
    if cfg.model_selection == "deviation":
        from drillgym.training.selection import chosen_model, select

        print(f"selecting among the saved models of {out} on {cfg.eval_episodes} validation episodes:")
        selection = select(out, cfg)
        source, norm = chosen_model(out, selection)
        summary = {**summary, "selection": {k: selection[k] for k in ("chosen", "rule")}}
        print(f"selected: {selection['chosen']} ({selection['rule']})")
    elif best_zip.exists() and (best_norm.exists() or not cfg.normalize_obs):
        source, norm = best_zip, best_norm
    else:
        source, norm = out / "model.zip", out / "vecnormalize.pkl"
    (out / "summary.json").write_text(json.dumps(json_safe(summary), indent=2, allow_nan=False))
    save_bundle(source, norm, cfg, {"training": summary}, out / "policy.zip")
    if export is not None:
        save_bundle(source, norm, cfg, {"training": summary}, export)


def select_only(out: Path, config: Path | None = None, export: Path | None = None) -> Path:
    """Apply a configuration's model selection to the finished run in ``out`` and export its choice.

    Args:
        out: the run folder (it must hold ``summary.json``).
        config: the configuration whose ``model_selection`` applies (default: the run's own ``config.yaml``).
        export: also copy the chosen policy bundle here.

    Returns:
        The run's policy bundle (``out/policy.zip``).
    """
    summary_path = out / "summary.json"
    if not summary_path.exists():
        raise UserError(f"{out} holds no finished run (no summary.json)")
    cfg = load_config(config if config is not None else out / "config.yaml")
    (out / "config.yaml").write_text(yaml.safe_dump(cfg.to_dict(), sort_keys=False))
    summary = json.loads(summary_path.read_text())
    summary.pop("selection", None)
    export_selected(out, cfg, summary, export)
    return out / "policy.zip"


def train(cfg: TrainConfig, out: Path, resume: bool = False, export: Path | None = None) -> Path:
    """Train ``cfg`` into ``out`` (or resume its newest checkpoint), export the chosen policy bundle, plot the curves.

    Args:
        cfg: the resolved configuration (``out/config.yaml`` is written from it).
        out: the run folder (check it first with :func:`check_run_folder`).
        resume: continue from the newest checkpoint in ``out/checkpoints``.
        export: also copy the policy bundle here (``NAME.zip``).

    Returns:
        The run's policy bundle (``out/policy.zip``).
    """
    from stable_baselines3.common.vec_env import VecNormalize

    from drillgym.training.callbacks import (
        CURVE_FILE,
        BaseComparisonEvalCallback,
        TimedCheckpointCallback,
        checkpoint_wall_time_s,
        read_best_reward,
        read_curve,
    )
    from drillgym.training.env_factory import make_eval_vec_env, make_train_vec_env
    from drillgym.training.model import ALGO_CLASSES, build_model

    out.mkdir(parents=True, exist_ok=True)
    (out / "config.yaml").write_text(yaml.safe_dump(cfg.to_dict(), sort_keys=False))
    ckpt_dir = out / "checkpoints"
    ckpt = latest_checkpoint(ckpt_dir) if resume else None
    # A resumed run carries what its checkpoint had reached: the evaluations up to it (later ones belong to the
    # interrupted session's steps, which are trained again), the best model's reward and the training time.
    previous_curve = [r for r in read_curve(out / "eval" / CURVE_FILE) if r["timesteps"] <= ckpt[1]] if ckpt else []
    previous_best = read_best_reward(out / "best") if ckpt else -math.inf
    elapsed_before_s = (checkpoint_wall_time_s(ckpt_dir, ckpt[1]) or 0.0) if ckpt else 0.0

    venv = make_train_vec_env(cfg)
    if cfg.normalize_obs:
        if ckpt is not None and (ckpt_dir / f"rl_model_vecnormalize_{ckpt[1]}_steps.pkl").exists():
            venv = VecNormalize.load(str(ckpt_dir / f"rl_model_vecnormalize_{ckpt[1]}_steps.pkl"), venv)
        else:
            venv = VecNormalize(venv, norm_obs=True, norm_reward=False)
    eval_env = make_eval_vec_env(cfg)
    if cfg.normalize_obs:
        eval_env = VecNormalize(eval_env, norm_obs=True, norm_reward=False, training=False)

    if ckpt is not None:
        model = ALGO_CLASSES[cfg.algo].load(ckpt[0], env=venv, tensorboard_log=str(out / "tb"), device="cpu")
        buffer = ckpt_dir / f"rl_model_replay_buffer_{ckpt[1]}_steps.pkl"
        if buffer.exists() and hasattr(model, "load_replay_buffer"):
            model.load_replay_buffer(buffer)
        print(f"resuming from {ckpt[0].name} ({model.num_timesteps} steps done)")
    else:
        model = build_model(cfg, venv, out / "tb")
    action_dim = int(venv.action_space.shape[0])  # type: ignore[index]
    every = max(cfg.n_envs, 1)
    checkpoint = TimedCheckpointCallback(
        save_freq=max(cfg.checkpoint_freq // every, 1),
        save_path=str(ckpt_dir),
        name_prefix="rl_model",
        save_replay_buffer=cfg.algo != "ppo",
        save_vecnormalize=cfg.normalize_obs,
        elapsed_before_s=elapsed_before_s,
    )
    evaluation = BaseComparisonEvalCallback(
        eval_env,
        action_dim,
        previous_curve=previous_curve,
        previous_best_reward=previous_best,
        n_eval_episodes=cfg.eval_episodes,
        eval_freq=max(cfg.eval_freq // every, 1),
        best_model_save_path=str(out / "best"),
        log_path=str(out / "eval"),
        deterministic=True,
    )
    start_steps = model.num_timesteps
    remaining = max(cfg.total_timesteps - model.num_timesteps, 0)
    model.learn(
        total_timesteps=remaining,
        callback=[checkpoint, evaluation],
        progress_bar=True,
        tb_log_name="residual",
        reset_num_timesteps=ckpt is None,
    )
    wall_s = checkpoint.elapsed_s()
    model.save(out / "model.zip")
    if cfg.normalize_obs:
        venv.save(str(out / "vecnormalize.pkl"))  # type: ignore[attr-defined]
    _export(out, cfg, model, evaluation, wall_s, export, ckpt[1] if ckpt else None)
    venv.close()
    eval_env.close()
    session = wall_s - elapsed_before_s
    resumed = f" (this session: {model.num_timesteps - start_steps} steps in {session / 60:.1f} min)" if ckpt else ""
    print(
        f"trained {model.num_timesteps} steps in {wall_s / 60:.1f} min{resumed}; "
        f"policy: {(out / 'policy.zip').resolve()}"
    )
    if evaluation.curve:
        last = evaluation.curve[-1]
        print(
            f"last evaluation: deviation {last['policy_deviation_mean_mm']:.3f} mm "
            f"vs base {last['base_deviation_mean_mm']:.3f} mm"
        )
    return out / "policy.zip"
