"""SB3 models whose residual starts at exactly zero, so training starts at the base controller."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from gymnasium import spaces
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from drillgym.training.config import TrainConfig


class _CriticWarmup:
    """Critic warm-up for off-policy algorithms.

    The actor (and SAC's entropy coefficient) do not learn for the first ``actor_warmup_steps``
    (learning rate 0), so the residual stays exactly zero while the critic learns the base controller's
    values (the burn-in of Silver et al. 2018, residual policy learning).
    """

    actor_warmup_steps: int = 0
    num_timesteps: int

    def _frozen_optimizers(self) -> list[torch.optim.Optimizer]:
        raise NotImplementedError

    def _update_learning_rate(self, optimizers: Any) -> None:
        super()._update_learning_rate(optimizers)  # type: ignore[misc]
        if self.num_timesteps < self.actor_warmup_steps:
            for opt in self._frozen_optimizers():
                for group in opt.param_groups:
                    group["lr"] = 0.0


class ResidualSAC(_CriticWarmup, SAC):
    """SAC with an optional critic warm-up (:class:`_CriticWarmup`)."""

    def __init__(self, *args: Any, actor_warmup_steps: int = 0, **kwargs: Any) -> None:
        self.actor_warmup_steps = int(actor_warmup_steps)
        super().__init__(*args, **kwargs)

    def _frozen_optimizers(self) -> list[torch.optim.Optimizer]:
        return [self.actor.optimizer] + ([self.ent_coef_optimizer] if self.ent_coef_optimizer else [])


class ResidualTD3(_CriticWarmup, TD3):
    """TD3 with an optional critic warm-up (:class:`_CriticWarmup`)."""

    def __init__(self, *args: Any, actor_warmup_steps: int = 0, **kwargs: Any) -> None:
        self.actor_warmup_steps = int(actor_warmup_steps)
        super().__init__(*args, **kwargs)

    def _frozen_optimizers(self) -> list[torch.optim.Optimizer]:
        return [self.actor.optimizer]


ALGO_CLASSES: dict[str, type[BaseAlgorithm]] = {"sac": ResidualSAC, "td3": ResidualTD3, "ppo": PPO}


def build_model(cfg: TrainConfig, env: VecEnv, tensorboard_log: Path | None = None) -> BaseAlgorithm:
    """A fresh model for ``cfg`` with its action output zero-initialised (see :func:`zero_init_residual`)."""
    policy = "MultiInputPolicy" if isinstance(env.observation_space, spaces.Dict) else "MlpPolicy"
    common: dict[str, Any] = {
        "seed": cfg.seed,
        "verbose": 0,
        "tensorboard_log": str(tensorboard_log) if tensorboard_log else None,
    }
    if cfg.algo == "sac":
        target_entropy: float | str = cfg.target_entropy
        model: BaseAlgorithm = ResidualSAC(
            policy,
            env,
            actor_warmup_steps=cfg.actor_warmup_steps,
            learning_rate=cfg.learning_rate,
            buffer_size=cfg.buffer_size,
            learning_starts=cfg.learning_starts,
            batch_size=cfg.batch_size,
            gamma=cfg.gamma,
            train_freq=cfg.train_freq,
            gradient_steps=cfg.gradient_steps,
            ent_coef=cfg.ent_coef,
            target_entropy=target_entropy,
            policy_kwargs={"net_arch": list(cfg.net_arch)},
            **common,
        )
    elif cfg.algo == "td3":
        model = ResidualTD3(
            policy,
            env,
            actor_warmup_steps=cfg.actor_warmup_steps,
            learning_rate=cfg.learning_rate,
            buffer_size=cfg.buffer_size,
            learning_starts=cfg.learning_starts,
            batch_size=cfg.batch_size,
            gamma=cfg.gamma,
            train_freq=cfg.train_freq,
            gradient_steps=cfg.gradient_steps,
            policy_kwargs={"net_arch": list(cfg.net_arch)},
            **common,
        )
    else:
        model = PPO(
            policy,
            env,
            learning_rate=cfg.learning_rate,
            n_steps=cfg.n_steps,
            batch_size=min(cfg.batch_size, cfg.n_steps * cfg.n_envs),
            gamma=cfg.gamma,
            policy_kwargs={"net_arch": list(cfg.net_arch), "log_std_init": cfg.log_std_init},
            **common,
        )
    zero_init_residual(model, cfg.log_std_init)
    return model


@torch.no_grad()
def zero_init_residual(model: BaseAlgorithm, log_std_init: float) -> None:
    """Zero the layer that outputs the action mean; set the initial exploration noise.

    SAC: ``actor.mu`` (mean, pre-tanh) zero, ``actor.log_std`` bias = ``log_std_init``. TD3: the last
    Linear of ``actor.mu`` zero (tanh(0) = 0), copied to the target actor. PPO: ``action_net`` zero.
    The deterministic action is then exactly 0: the residual policy *is* the base controller.
    """
    if isinstance(model, SAC):
        mu, log_std = model.actor.mu, model.actor.log_std
        assert isinstance(mu, torch.nn.Linear) and isinstance(log_std, torch.nn.Linear)
        mu.weight.zero_()
        mu.bias.zero_()
        log_std.weight.zero_()
        log_std.bias.fill_(log_std_init)
    elif isinstance(model, TD3):
        last = [m for m in model.actor.mu.modules() if isinstance(m, torch.nn.Linear)][-1]
        last.weight.zero_()
        last.bias.zero_()
        model.actor_target.load_state_dict(model.actor.state_dict())
    elif isinstance(model, PPO):
        net = model.policy.action_net
        assert isinstance(net, torch.nn.Linear)
        net.weight.zero_()
        net.bias.zero_()
    else:  # pragma: no cover
        raise TypeError(f"no residual initialisation for {type(model).__name__}")
