"""Replay a real episode's commands in the simulator: the sim's answer to the same commands.

The scenario comes from the log's header; every agent step sends the logged command (correction and
feed override) open loop. By default the replay is *nominal*: no sensor noise and no specimen
variability (the sim's expectation); the null model switches them on (drawn from ``seed``) or sets the
specimen's hardness. Effects (:mod:`drillgym.envs.effects`) can be switched on for the replay.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.effects.base import Effect, TraceView
from drillgym.eval.diagnosis.channels import FORCE, LF_CHANNELS, TORQUE, TRACKER, Q
from drillgym.eval.diagnosis.episodes import EpisodeData


@dataclass
class SimTrace:
    """The simulated channels of one replay, row-aligned with the real episode.

    Attributes:
        lf: the channels of :data:`~drillgym.eval.diagnosis.channels.LF_CHANNELS` per sample, (n, 15); NaN on rows
            the replay did not reach (it ended earlier than the log).
        t_s: sample times (s), (n,).
        engaged_share: share of the lips in bone per sample (the replay's own state), (n,).
        sensor_arm_m: F/T origin to the drill tip (m).
        spindle_rpm: spindle speed (rpm).
    """

    lf: np.ndarray
    t_s: np.ndarray
    engaged_share: np.ndarray
    sensor_arm_m: float
    spindle_rpm: float

    def copy(self) -> SimTrace:
        """A deep copy (sensor-only effects modify traces in place)."""
        return SimTrace(self.lf.copy(), self.t_s, self.engaged_share, self.sensor_arm_m, self.spindle_rpm)

    def with_sensor_effects(self, effects: Sequence[Effect]) -> SimTrace:
        """A copy with sensor-only effects applied to its F/T and tracker channels."""
        out = self.copy()
        if effects:
            view = TraceView(
                t_s=self.t_s,
                force_n=out.lf[:, FORCE],
                torque_nm=out.lf[:, TORQUE],
                engaged_share=self.engaged_share,
                sensor_arm_m=self.sensor_arm_m,
                spindle_rpm=self.spindle_rpm,
                tracker_m=out.lf[:, TRACKER],
            )
            for e in effects:
                e.apply_to_trace(view)
            out.lf[:, FORCE] = view.force_n
            out.lf[:, TORQUE] = view.torque_nm
            out.lf[:, TRACKER] = view.tracker_m
        return out


class Replayer:
    """Runs replays in one process, keeping one env (rebuilt only when the scenario changes)."""

    def __init__(self) -> None:
        self.env: UR5BoneDrillEnv | None = None
        self._key = ""

    def run(
        self,
        ep: EpisodeData,
        effects: Sequence[Effect] = (),
        seed: int = 0,
        noise: bool = False,
        variability: bool = False,
        hardness: float = 1.0,
    ) -> SimTrace:
        """Replay ``ep``'s commands with ``effects`` on.

        Args:
            ep: the real episode.
            effects: effects switched on for the replay.
            seed: reset seed (draws the noise and the specimen when they are on).
            noise: sensor noise as in the episode's scenario (else none).
            variability: specimen hardness drawn as in the scenario (else the preset's).
            hardness: a fixed specimen hardness factor (multiplies the scenario's ``density_scale``).
        """
        scenario = dict(ep.scenario)
        if not noise:
            scenario.update(ft_noise_n=0.0, tracker_noise_mm=0.0)
        if not variability:
            scenario["bone_variability"] = 0.0
        if hardness != 1.0:
            scenario["density_scale"] = scenario.get("density_scale", 1.0) * hardness
        key = json.dumps(scenario, sort_keys=True)
        if self.env is None:
            self.env = UR5BoneDrillEnv(pybullet_world=False, **scenario)  # a replay renders nothing
            self._key = key
        env = self.env
        for e in effects:
            if e.in_series:  # a trend form takes this episode's place in the series
                e.series_position = ep.series_position
        env.set_effects(list(effects) or None)
        env.reset(seed=seed, options={"scenario": scenario} if key != self._key else None)
        self._key = key
        done, q, tracker, rec = env.replay_open_loop(ep.actions)
        m = min(len(rec["t_s"]), ep.n)
        reps = np.diff(np.concatenate([[0], np.arange(1, done + 1) * 5]))  # 5 samples per step
        q_rows = np.repeat(q[:done], reps, axis=0)[:m]
        cell = env.cell
        tr_rows = np.repeat(tracker[:done], reps, axis=0)[:m]
        tr_task = (tr_rows - cell.entry_base_m) @ cell.R_base_task
        if not env.scenario.tracker:
            tr_task[:] = np.nan
        lf = np.full((ep.n, len(LF_CHANNELS)), np.nan)
        lf[:m, FORCE] = rec["ft_force_n"][:m]
        lf[:m, TORQUE] = rec["ft_torque_nm"][:m]
        lf[:m, TRACKER] = tr_task
        lf[:m, Q] = q_rows
        tips = np.asarray(rec["tip_task_m"][:m], dtype=float).reshape(m, 3)
        share = np.zeros(ep.n)
        depth = tips[:, 2] + tips[:, 0] * cell.solver.tan_beta
        share[:m] = np.interp(depth, cell.table.depth_m, cell.table.engaged_fraction)
        t = ep.t_s.copy()
        t[:m] = rec["t_s"][:m]
        return SimTrace(lf, t, share, float(cell.sensor_arm_m), float(env.scenario.spindle_rpm))

    def close(self) -> None:
        """Release the env."""
        if self.env is not None:
            self.env.close()
            self.env = None


def seed_for(name: str, draw: int) -> int:
    """A reproducible seed for null draw ``draw`` of episode ``name``."""
    h = 0
    for ch in f"{name}#{draw}":
        h = (h * 131 + ord(ch)) % 2**31
    return int(h) if math.isfinite(h) else 0
