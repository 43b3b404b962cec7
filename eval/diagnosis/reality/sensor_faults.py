"""Reality: sensor faults outside the candidate library, whose gap has a shape no candidate has.

A noisier F/T (a damaged cable or a ground loop: broadband, before contact as much as during the cut, strongest on
the axial channel) and a torque-only calibration error (the forces read right). The diagnosis should leave both
``unexplained`` and locate them at the forces and at the torques; a candidate named for them has the gap's size
but not its shape (docs/diagnosis.md §3, the shape test).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from drillgym.envs.effects.base import EffectHost, Param
from drillgym.eval.diagnosis.channels import FORCE_CHANNELS, HF_CHANNELS, STAGES, TORQUE_CHANNELS
from drillgym.eval.diagnosis.reality.base import RealityEffect


class FTBroadbandNoise(RealityEffect):
    """Extra white noise on every F/T sample, axial ``sigma_n``, lateral ``lateral_share · sigma_n``.

    Unlike a once-per-revolution force (one frequency, lateral, only while cutting) it is flat across frequencies
    and present from the first sample; the torques get the forces' noise times 5 mm, as the sensor's own noise.
    """

    name = "ft_broadband_noise"
    summary = "F/T readings noisier than the sensor's specification, flat in frequency, strongest on Fz"
    explains = None
    location = (FORCE_CHANNELS + HF_CHANNELS, STAGES)
    params: ClassVar[tuple[Param, ...]] = (
        Param("sigma_n", 0.0, 2.0, 0.0, "extra noise SD on Fz per sample (N)"),
        Param("lateral_share", 0.0, 1.0, 0.4, "extra noise SD on Fx and Fy over that on Fz (-)"),
    )
    channels = frozenset({"force", "torque"})

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Add the noise (one draw per sample from this episode's stream)."""
        v = self.values
        sd = v["sigma_n"] * np.array([v["lateral_share"], v["lateral_share"], 1.0])
        out = np.array(wrenches, dtype=float)
        noise = self.rng.standard_normal((out.shape[0], 3)) * sd[None, :]
        out[:, :3] += noise
        out[:, 3:] += 0.005 * noise
        return out


class FTTorqueGain(RealityEffect):
    """A calibration error of the F/T's torque rows alone: ``T_read = (1 + gain) T`` (the forces read right).

    The candidate ``ft_gain`` scales forces only, so no candidate has this form; where the torque grows with the
    specimen's hardness as the thrust does, a per-specimen hardness fit can take part of it and move the gap onto
    the thrust, which the sensor reads correctly (the location check, docs/diagnosis.md §3).
    """

    name = "ft_torque_gain"
    summary = "F/T torques read with a wrong gain, forces right (a torque calibration error)"
    explains = None
    location = (TORQUE_CHANNELS, STAGES[1:])
    params: ClassVar[tuple[Param, ...]] = (Param("gain", -0.5, 0.5, 0.0, "relative gain error of Tx, Ty, Tz (-)"),)
    channels = frozenset({"torque"})

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Scale the torques."""
        out = np.array(wrenches, dtype=float)
        out[:, 3:] *= 1.0 + self.values["gain"]
        return out
