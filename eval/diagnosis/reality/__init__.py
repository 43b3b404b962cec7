"""The reality generator: the simulator with effects the diagnosing simulator was not told about.

Its effects are written apart from the candidate library (:mod:`drillgym.envs.effects`) and in other forms;
``make_reality`` logs episodes as a real cell would (``source: "real"``, nothing privileged).
"""

from drillgym.eval.diagnosis.reality.base import RealityEffect
from drillgym.eval.diagnosis.reality.generate import build_reality, make_reality, write_truth
from drillgym.eval.diagnosis.reality.library import REALITY_EFFECTS

__all__ = ["REALITY_EFFECTS", "RealityEffect", "build_reality", "make_reality", "write_truth"]
