"""drillgym environments: the simulated UR5 bone-drilling cell (and, later, the real one).

``gym.make("drillgym/UR5BoneDrill-v1", **scenario)`` builds the simulated cell; ``ENV_IDS`` lists every
registered id. ``gym.make_vec(SIM_ENV_ID, num_envs=N, vectorization_mode="vector_entry_point", **scenario)``
builds N episodes stepped in lock-step (:class:`drillgym.envs.batched.BatchedDrillEnv`).
"""

from gymnasium.envs.registration import register, registry

from drillgym.envs.constants import MAX_EPISODE_STEPS
from drillgym.envs.scenario import Scenario

SIM_ENV_ID = "drillgym/UR5BoneDrill-v1"
"""The simulated cell (the only place the id is written)."""
REAL_ENV_ID = "drillgym/UR5BoneDrillReal-v1"
"""The real-cell backend."""

ENV_IDS = [SIM_ENV_ID]

if ENV_IDS[0] not in registry:
    register(
        id=ENV_IDS[0],
        entry_point="drillgym.envs.checker:make_sim_env",  # the env in Gymnasium's passive checker, mended
        vector_entry_point="drillgym.envs.batched:BatchedDrillEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
        disable_env_checker=True,  # make_sim_env adds the checker itself (drillgym.envs.checker says why)
    )

REAL_ENV_IDS = [REAL_ENV_ID]
"""The real-cell backend (needs a robot or the emulator: ``robot_host=...``); not in ``ENV_IDS``."""

if REAL_ENV_IDS[0] not in registry:
    register(
        id=REAL_ENV_IDS[0],
        entry_point="drillgym.envs.real.real_env:UR5BoneDrillRealEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
        disable_env_checker=True,
    )

__all__ = ["ENV_IDS", "REAL_ENV_ID", "REAL_ENV_IDS", "SIM_ENV_ID", "Scenario"]
