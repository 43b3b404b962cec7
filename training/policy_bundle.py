"""A trained residual policy as files: ``NAME.zip`` (SB3 model), ``NAME.vecnormalize.pkl``, ``NAME.json``.

The JSON holds the training configuration (base controller, residual scale) and the training summary;
the benchmark and the real-robot runner load the bundle through :func:`load_bundle`.
"""

from __future__ import annotations

import json
import pickle
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.running_mean_std import RunningMeanStd

from drillgym.envs.errors import read_json
from drillgym.training.config import TrainConfig
from drillgym.training.model import ALGO_CLASSES

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

    model: BaseAlgorithm
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
    model = ALGO_CLASSES[cfg.algo].load(zip_path, device="cpu")
    normalizer = None
    if pkl_path.exists():
        with open(pkl_path, "rb") as f:
            vn = pickle.load(f)
        normalizer = ObsNormalizer(vn.obs_rms, float(vn.clip_obs), float(vn.epsilon))
    return PolicyBundle(model, normalizer, cfg, meta)
