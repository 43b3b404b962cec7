"""drillgym environments: the simulated UR5 bone-drilling cell (and, later, the real one).

``gym.make("drillgym/UR5BoneDrill-v0", **scenario)`` builds the simulated cell; ``ENV_IDS`` lists every
registered id.
"""

from gymnasium.envs.registration import register, registry

from drillgym.envs.constants import MAX_EPISODE_STEPS
from drillgym.envs.scenario import Scenario

ENV_IDS = ["drillgym/UR5BoneDrill-v0"]

if ENV_IDS[0] not in registry:
    register(
        id=ENV_IDS[0],
        entry_point="drillgym.envs.drill_env:UR5BoneDrillEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )

REAL_ENV_IDS = ["drillgym/UR5BoneDrillReal-v0"]
"""The real-cell backend (needs a robot or the emulator: ``robot_host=...``); not in ``ENV_IDS``."""

if REAL_ENV_IDS[0] not in registry:
    register(
        id=REAL_ENV_IDS[0],
        entry_point="drillgym.envs.real.real_env:UR5BoneDrillRealEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
        disable_env_checker=True,
    )

__all__ = ["ENV_IDS", "REAL_ENV_IDS", "Scenario"]
