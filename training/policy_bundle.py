"""A trained residual policy as files: ``NAME.zip`` (SB3 model), ``NAME.vecnormalize.pkl``, ``NAME.json``.

The JSON holds the training configuration (base controller, residual scale) and the training summary;
the benchmark and the real-robot runner load the bundle through :func:`load_bundle`, which builds the saved
model's SB3 policy alone (:func:`load_policy`): what ``predict`` needs, without the algorithm's optimisers.
"""

from __future__ import annotations

import json
import pickle
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.save_util import load_from_zip_file

from drillgym.envs.errors import UserError, read_json
from drillgym.training.config import TrainConfig

POLICY_DIR = Path(__file__).resolve().parent / "policies"
"""The policies shipped with the package."""
NAMED_POLICIES = {"schedule_sac": "residual_schedule_sac.zip", "li2023_sac": "residual_li2023_sac.zip"}
"""Shipped policies by name (``residual:NAME``), from any working directory: ``schedule_sac``, the schedule
residual on ``li2023_tuned`` (``docs/training.md``); ``li2023_sac``, the earlier step-level residual on ``li2023``."""
SHIPPED = "schedule_sac"
"""The headline shipped policy: ``residual:shipped``."""


def resolve_policy(text: str) -> Path:
    """A policy name (``shipped`` or one of :data:`NAMED_POLICIES`) or a path -> the bundle's ``.zip`` path."""
    name = SHIPPED if text == "shipped" else text
    if name in NAMED_POLICIES:
        return POLICY_DIR / NAMED_POLICIES[name]
    return Path(text)


@dataclass
class ObsNormalizer:
    """VecNormalize's observation statistics, applied outside a VecEnv (per Dict key)."""

    obs_rms: dict[str, RunningMeanStd]
    clip_obs: float
    epsilon: float

    def __call__(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Normalised copy of ``obs`` (keys without statistics pass through)."""
        out = {}
        for k, v in obs.items():
            rms = self.obs_rms.get(k)
            out[k] = (
                v
                if rms is None
                else np.clip((v - rms.mean) / np.sqrt(rms.var + self.epsilon), -self.clip_obs, self.clip_obs)
            )
        return {k: np.asarray(v, dtype=np.float32) for k, v in out.items()}


@dataclass
class PolicyBundle:
    """A loaded residual policy."""

    policy: BasePolicy
    """The saved model's SB3 policy (``predict`` as the model's own), in evaluation mode on the CPU."""
    normalizer: ObsNormalizer | None
    config: TrainConfig
    meta: dict[str, Any]


def bundle_paths(path: Path) -> tuple[Path, Path, Path]:
    """``(model.zip, vecnormalize.pkl, meta.json)`` of a bundle named by its zip path."""
    path = Path(path)
    stem = path.with_suffix("")
    return path, stem.with_suffix(".vecnormalize.pkl"), stem.with_suffix(".json")


def save_bundle(
    model_zip: Path, vecnormalize_pkl: Path | None, cfg: TrainConfig, meta: dict[str, Any], dest: Path
) -> None:
    """Copy a trained model and its normaliser next to a JSON of its config and summary."""
    zip_path, pkl_path, json_path = bundle_paths(dest)
    zip_path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(model_zip, zip_path)
    if vecnormalize_pkl is not None and Path(vecnormalize_pkl).exists():
        shutil.copyfile(vecnormalize_pkl, pkl_path)
    json_path.write_text(json.dumps({"config": cfg.to_dict(), **meta}, indent=2, default=float))


def load_bundle(path: Path | str) -> PolicyBundle:
    """Load a bundle; clear errors for a missing or mismatched file."""
    zip_path, pkl_path, json_path = bundle_paths(resolve_policy(str(path)))
    if not zip_path.exists():
        names = ", ".join(["shipped", *NAMED_POLICIES])
        raise FileNotFoundError(f"residual policy {zip_path} does not exist (shipped policies by name: {names})")
    if not json_path.exists():
        raise FileNotFoundError(f"residual policy {zip_path} has no {json_path.name} (config and summary) beside it")
    meta = read_json(json_path)
    cfg = TrainConfig(**meta["config"])
    policy = load_policy(zip_path)
    normalizer = None
    if pkl_path.exists():
        with open(pkl_path, "rb") as f:
            vn = pickle.load(f)
        normalizer = ObsNormalizer(vn.obs_rms, float(vn.clip_obs), float(vn.epsilon))
    return PolicyBundle(policy, normalizer, cfg, meta)


class _NoOptimizer:
    """Stands in for a policy's optimiser when it is built to predict only.

    An SB3 policy builds its optimisers in its constructor; the first torch optimiser of a process imports
    ``torch._dynamo`` (about 1.5 s), which inference never uses.
    """

    def __init__(self, params: Any, **kwargs: Any) -> None:
        del params, kwargs


def _no_schedule(progress_remaining: float) -> float:
    """The learning-rate schedule a policy built to predict only is given (never read)."""
    return 0.0


def load_policy(zip_path: Path) -> BasePolicy:
    """The SB3 policy of a model saved by ``model.save`` (SAC, TD3 or PPO), on the CPU, in evaluation mode.

    It is built as ``Algorithm.load`` builds it (the saved policy class, spaces and ``policy_kwargs``; PPO's
    ``use_sde`` as its algorithm passes it) and holds the saved weights, so its ``predict`` is the model's
    ``predict`` bit for bit (``tests/training/test_policy_bundle.py``); the optimisers, replay buffer and
    entropy coefficient are not built.
    """
    data, params, _ = load_from_zip_file(zip_path, device="cpu")
    if data is None or "policy" not in params:
        raise UserError(f"{zip_path} holds no SB3 policy (saved by model.save?)")
    kwargs = {k: v for k, v in data.get("policy_kwargs", {}).items() if k != "device"}
    kwargs["optimizer_class"] = _NoOptimizer
    policy_class = data["policy_class"]
    if issubclass(policy_class, ActorCriticPolicy):
        kwargs.setdefault("use_sde", bool(data.get("use_sde", False)))
    policy = policy_class(data["observation_space"], data["action_space"], _no_schedule, **kwargs)
    policy.load_state_dict(params["policy"])
    policy.set_training_mode(False)
    return policy
