"""The real UR5 drilling cell behind the simulated env's API, and the emulator that tests it.

``gym.make("drillgym/UR5BoneDrillReal-v1", robot_host=..., ft_sensor=..., tracker=..., **scenario)`` connects
to a UR CB3 through ``ur_rtde`` (pinned 1.6.5), an ATI Net F/T (RDT over UDP) and an optional tracker.
See :class:`drillgym.envs.real.real_env.UR5BoneDrillRealEnv` and ``docs/deployment.md``.
"""

from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.netft import NetFTCalibration

__all__ = ["NetFTCalibration", "SafetyLimits", "ServoParams"]
