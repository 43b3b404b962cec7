"""drillgym: robot-assisted bone drilling with a UR5.

The one import name of the project. Its four parts are the repository's top-level folders:

* :mod:`drillgym.envs`: the Gymnasium environments (the simulated cell and the real-robot backend);
* :mod:`drillgym.controllers`: the papers' compensators and the controller registry;
* :mod:`drillgym.training`: residual RL on top of a compensator (Stable-Baselines3);
* :mod:`drillgym.eval`: benchmarks, reproduction, calibration, diagnosis and the ``drillgym`` command.

``import drillgym`` registers the environment ids (:data:`drillgym.envs.ENV_IDS`), so
``gym.make("drillgym:drillgym/UR5BoneDrill-v1")`` works without a separate import.
"""

from importlib.metadata import PackageNotFoundError, version

from drillgym import envs as envs

try:
    __version__ = version("drillgym")
except PackageNotFoundError:  # pragma: no cover - running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__", "envs"]
