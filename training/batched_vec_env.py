"""Stable-Baselines3's ``VecEnv`` over a Gymnasium ``VectorEnv`` with same-step autoreset (the batched env).

SB3 does not take a ``gymnasium.vector.VectorEnv`` directly; as it asks of other vectorised simulators
(EnvPool, Isaac Gym), the simulator brings the adapter. :class:`BatchedVecEnv` turns
:class:`~drillgym.envs.batched.BatchedDrillEnv` (or any ``VectorEnv`` with ``AutoresetMode.SAME_STEP``)
into SB3's API: ``dones = terminated | truncated``, one info dict per episode with
``"terminal_observation"`` and ``"TimeLimit.truncated"`` where an episode ended (the ended episode's
``final_info`` entries, its metrics among them, merged in), and SB3's seeding (``seed(s)``: episode ``i``
gets ``s + i`` at the next ``reset``). Wrap it in SB3's own ``VecMonitor`` for episode returns and lengths::

    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import VecMonitor
    from drillgym.envs.batched import BatchedDrillEnv
    from drillgym.training.batched_vec_env import BatchedVecEnv

    env = VecMonitor(BatchedVecEnv(BatchedDrillEnv(16)))
    SAC("MultiInputPolicy", env).learn(10_000)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn


def episode_info(infos: dict[str, Any], i: int, num_envs: int) -> dict[str, Any]:
    """Episode ``i``'s entries of a vector env's info (Gymnasium's dict of arrays with ``_key`` masks).

    An entry whose mask is false for ``i`` is left out; arrays with one row per episode give row ``i``;
    nested dicts are split alike; anything else is shared by every episode.
    """
    out: dict[str, Any] = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos.get(f"_{key}")
        if mask is not None and not mask[i]:
            continue
        if isinstance(value, dict):
            out[key] = episode_info(value, i, num_envs)
        elif isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == num_envs:
            out[key] = value[i]
        else:
            out[key] = value
    return out


class BatchedVecEnv(VecEnv):
    """SB3 ``VecEnv`` of a same-step-autoreset ``gymnasium.vector.VectorEnv`` (one process, no copies of envs).

    Args:
        venv: the vector env, e.g. :class:`~drillgym.envs.batched.BatchedDrillEnv`.

    Raises:
        ValueError: the vector env does not reset ended episodes in the same step (SB3's convention).
    """

    def __init__(self, venv: VectorEnv) -> None:
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"BatchedVecEnv needs a vector env with AutoresetMode.SAME_STEP, got {mode!r}")
        self.venv = venv
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    # ------------------------------------------------------------------ SB3 API
    def reset(self) -> VecEnvObs:
        """Reset every episode (with the seeds of :meth:`seed`, if set); the observations."""
        if any(self._options):
            raise ValueError(f"{type(self.venv).__name__} takes no reset options, got {self._options}")
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        obs, infos = self.venv.reset(seed=cast(Any, seeds))  # Gymnasium's vector envs take one seed per episode
        self.reset_infos = [episode_info(infos, i, self.num_envs) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Remember the actions (N, action dim) for :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Step every episode; ended ones are reset and report their last observation and info."""
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        self._actions = None
        dones = np.logical_or(terminated, truncated)
        final_obs, final_info = infos.get("final_obs"), infos.get("final_info", {})
        out, n = [], self.num_envs
        for i in range(n):
            info = {k: v for k, v in episode_info(infos, i, n).items() if k not in ("final_obs", "final_info")}
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if dones[i]:
                assert final_obs is not None
                info.update(episode_info(final_info, i, n))
                info["terminal_observation"] = {k: v[i] for k, v in final_obs.items()}
            out.append(info)
        return obs, np.asarray(reward, dtype=np.float32), dones, out

    def close(self) -> None:
        """Close the vector env."""
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's attribute, once per selected episode (they share one env object)."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Not supported: the episodes share one vector env."""
        raise NotImplementedError(f"{type(self.venv).__name__}'s episodes share one env: set {attr_name} on it")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call the vector env's method once, for every selected episode (one result each)."""
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """False: the episodes are not single Gymnasium envs that could be wrapped."""
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """No images: the batched env does not render."""
        return [None for _ in range(self.num_envs)]
