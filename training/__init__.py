"""Residual RL (stable-baselines3) on top of the papers' compensators.

``drillgym train --config training/configs/residual_sac.yaml --out runs/NAME`` trains one;
``make_controller("residual:PATH")`` runs it like any controller.
"""

from drillgym.controllers.registry import register_loader
from drillgym.controllers.residual import combine
from drillgym.training.config import TrainConfig, load_config
from drillgym.training.residual_wrapper import ResidualWrapper

register_loader("residual", "drillgym.training.residual_policy:load_residual_controller")

__all__ = ["ResidualWrapper", "TrainConfig", "combine", "load_config"]
