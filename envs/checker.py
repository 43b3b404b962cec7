"""What ``gym.make("drillgym/UR5BoneDrill-v1")`` builds: the sim env inside Gymnasium's passive checker, mended.

Gymnasium's :class:`~gymnasium.wrappers.PassiveEnvChecker` (1.4) marks its first ``reset`` as checked before
calling it and keeps that reset's data for the first ``step``'s data-reuse check. When that first reset raises
(a bad ``reset(options=...)`` value), a corrected ``reset`` and the first ``step`` then fail inside the checker
(``TypeError: cannot unpack non-iterable NoneType object``). :class:`ResetSafeEnvChecker` checks the next
reset instead. The id is registered with ``disable_env_checker=True`` and this entry point adds the mended
checker, so the wrapper stack is Gymnasium's usual one (``TimeLimit(OrderEnforcing(checker(env)))``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import EnvSpec
from gymnasium.wrappers import PassiveEnvChecker

from drillgym.envs.drill_env import UR5BoneDrillEnv


class ResetSafeEnvChecker(PassiveEnvChecker):
    """Gymnasium's passive checker whose first ``reset`` counts as checked only once it has returned."""

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset through Gymnasium's checker; a first reset that raises leaves the next one to be checked."""
        first = not self.checked_reset
        try:
            return super().reset(seed=seed, options=options)
        except BaseException:
            if first:
                self.checked_reset = False
            raise

    @property
    def spec(self) -> EnvSpec | None:  # type: ignore[override]  # a property, as in Gymnasium's wrappers
        """The env's spec as registered (``disable_env_checker=True``): ``gym.make(env.spec)`` rebuilds this stack."""
        return self.env.spec


def make_sim_env(**kwargs: Any) -> gym.Env:
    """The registered entry point: :class:`~drillgym.envs.drill_env.UR5BoneDrillEnv` (``kwargs``) in the mended checker."""
    return ResetSafeEnvChecker(UR5BoneDrillEnv(**kwargs))


make_sim_env.metadata = UR5BoneDrillEnv.metadata  # type: ignore[attr-defined]  # gym.make reads the render modes here
