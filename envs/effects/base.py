"""The hook interface between the simulated cell and an unmodelled effect.

An :class:`Effect` is a small extension of the simulator with named physical parameters (SI units, a
documented range, a default that switches it off). The env calls its hooks at a few fixed points of
an agent step; every hook defaults to "no change", and an env without effects never calls any, so
the default simulation is untouched (bit for bit) and pays nothing for the hooks.

Hook points, in the order of one agent step (50 ms, 5 F/T samples):

* ``attach(env)``: at ``reset``, after the cell and sensors are reset (change the tool, the bone
  profile, the side guidance of the tip balance; see :meth:`drillgym.envs.cell.SimCell.clear_effects`).
* ``command_delay_s(env, delay_s)``: when a command is queued; returns its latency (s).
* ``begin_step(env)``: before the samples of the step (set the specimen's force scale, servo offsets).
* ``servo_offset_task_m``: an attribute (3,) or None read after ``begin_step``: a shift of the
  servo-held tip that the encoders see (the motor lags its target), task frame (m).
* ``delay_target(t_s, target)``: per sample, the servo target (task frame, m) the servo really gets.
* ``sensor_wrenches(env, wrenches, t_s)``: the true wrenches of the step's samples (5, 6) (N, N·m,
  sensor frame) before the F/T noise and resolution.

The hooks see the env through :class:`EffectHost`: the cell's physics and the episode's path, pending
commands, recorded samples and specimen, nothing else of the env.

Offsets the encoders do *not* see (the tool or the arm is not where the controller's model puts it)
go on the cell: :attr:`drillgym.envs.cell.SimCell.geometry_offset_task_m` and ``marker_offset_base_m``.

A sensor-only effect (``sensor_only = True``) changes readings, not physics; it also implements
:meth:`Effect.apply_to_trace`, the same change applied to a recorded trace, which lets a fit skip
the re-simulation.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.record_fields import Field

if TYPE_CHECKING:
    from drillgym.envs.cell import SimCell
    from drillgym.envs.sample_record import SampleRecord
    from drillgym.envs.scenario import Scenario
    from drillgym.envs.task import DrillPath

CHANNEL_GROUPS = ("force", "torque", "tracker", "q", "tcp")
"""What an effect can change: F/T force, F/T torque, tracker marker, RTDE joint angles, RTDE TCP."""


class EffectHost(Protocol):
    """What an effect's hooks may read and change of the simulated episode (the env implements it).

    Attributes:
        cell: the physics (tip balance ``cell.solver``, last sample ``cell.sample``, the effect state of
            :meth:`drillgym.envs.cell.SimCell.clear_effects`, the specimen's ``cell.specimen_hardness``).
        scenario: the episode's scenario.
        path: the nominal path (depth ``path.s_m``, ``path.speed_m_s(feed_scale)``).
        recorder: the samples recorded so far (``recorder.tip_task_m``, ...).
        feed_scale: the feed override in force (-).
        correction_base_m: the correction the servo holds now (m, base frame).
        pending: commands not yet applied: ``(apply time s, correction m base, feed scale)``, oldest first.
    """

    cell: SimCell
    scenario: Scenario
    path: DrillPath
    recorder: SampleRecord
    feed_scale: float
    correction_base_m: np.ndarray
    pending: deque[tuple[float, np.ndarray, float]]


@dataclass(frozen=True)
class Param:
    """One physical parameter of an effect."""

    name: str
    """Name with its unit (``_s``, ``_m``, ``_n_s``, ``_rad``, ``_per_m``; no suffix: dimensionless)."""
    low: float
    """Lowest physically plausible value."""
    high: float
    """Highest physically plausible value."""
    default: float = 0.0
    """The value that switches the effect off."""
    description: str = ""


@dataclass
class TraceView:
    """A recorded episode as a sensor-only effect sees it (arrays are per F/T sample, modified in place).

    Attributes:
        t_s: sample times since reset (s), (n,).
        force_n: F/T force readings (N, sensor frame), (n, 3).
        torque_nm: F/T torque readings (N·m, sensor frame, about the sensor origin), (n, 3).
        engaged_share: share of the lips' length in bone, in [0, 1], (n,).
        sensor_arm_m: F/T sensor origin to drill tip along the tool axis (m).
        spindle_rpm: spindle speed (rpm).
        tracker_m: tracker readings (m, any fixed frame), (n, 3), one per F/T sample (the agent step's reading,
            held over its samples; NaN where the tracker was not tracking); None where the trace has none.
    """

    t_s: np.ndarray
    force_n: np.ndarray
    torque_nm: np.ndarray
    engaged_share: np.ndarray
    sensor_arm_m: float
    spindle_rpm: float
    tracker_m: np.ndarray | None = None


class Effect:
    """Base class of an unmodelled effect: parameters, validation and no-op hooks."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    """One line: what is physically going on."""
    params: ClassVar[tuple[Param, ...]] = ()
    channels: ClassVar[frozenset[str]] = frozenset()
    """Channel groups (:data:`CHANNEL_GROUPS`) the physics says this effect changes; the others stay put."""
    channels_before_contact: ClassVar[frozenset[str]] = frozenset()
    """The groups it changes before the drill touches the bone (most effects act only through the cut)."""
    sensor_only: ClassVar[bool] = False
    per_episode: ClassVar[bool] = False
    """True if the diagnosis fits this effect's parameters per episode around a shared mean (a random effect,
    :mod:`drillgym.eval.diagnosis.random_effects`); only sensor-only effects, whose fit needs no replay."""
    variant_of: ClassVar[str | None] = None
    """The effect whose physics this one models in another way (a per-episode form of a shared one): naming
    either is naming the same physics."""
    in_series: ClassVar[bool] = False
    """True for a form whose parameters drift over a series of holes (:mod:`drillgym.envs.effects.trends`): its
    :attr:`series_position` is set before each episode by whoever replays the series (the diagnosis, in the order
    of the logs)."""
    compiled: ClassVar[bool] = False
    """True if the compiled step (:mod:`drillgym.envs.step_kernel`) runs this effect: it changes only what the
    kernel reads at ``reset`` (the tool's compliance and sensor arm, the geometry and marker offsets, the
    force table's depth profile, the entry guidance), or its step hook has a kernel counterpart, beside it in its
    module, with the fields below. An env with only such effects steps compiled. Declared by the class itself: a
    subclass that does not declare it again is stepped in Python."""
    kernel_params: ClassVar[tuple[Field, ...]] = ()
    """The parameters a compiled effect's kernel hook reads (fields of the episode's ``params`` record,
    :mod:`drillgym.envs.episode_state`; zero while the effect is off), written by :meth:`set_kernel_params`."""
    kernel_state: ClassVar[tuple[Field, ...]] = ()
    """The state a compiled effect's kernel hook keeps (fields of the episode's ``state`` record)."""
    servo_offset_task_m: np.ndarray | None = None
    series_position: float = 0.0
    """This episode's place in its series of holes, 0 (first) to 1 (last); read by :attr:`in_series` forms."""

    def __init__(self, **values: float) -> None:
        """Set parameters by name (unset ones keep their default, i.e. off); out-of-range values raise."""
        known = {p.name: p for p in self.params}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise UserError(f"{self.name}: unknown parameter(s) {unknown}; parameters: {sorted(known)}")
        self.values: dict[str, float] = {}
        for p in self.params:
            v = float(values.get(p.name, p.default))
            if not math.isfinite(v) or not p.low <= v <= p.high:
                raise UserError(f"{self.name}: {p.name}={v!r} is outside [{p.low:g}, {p.high:g}]")
            self.values[p.name] = v
        self.servo_offset_task_m = None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v:.4g}" for k, v in self.values.items())
        return f"{type(self).__name__}({args})"

    # ------------------------------------------------------------------ hooks (no-ops)
    def attach(self, env: EffectHost) -> None:
        """At reset, after the cell and the sensors are reset."""

    def command_delay_s(self, env: EffectHost, delay_s: float) -> float:
        """Latency (s) of the command being queued; ``delay_s`` is the cell's nominal one."""
        return delay_s

    def begin_step(self, env: EffectHost) -> None:
        """Before the samples of an agent step."""

    def delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        """The servo target (m, task frame) the servo really follows at sample time ``t_s`` (s)."""
        return target

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """True wrenches (5, 6) (N, N·m, sensor frame) at the sample times ``t_s`` (s), before noise."""
        return wrenches

    def tracker_marker_base_m(self, env: EffectHost, marker_base_m: np.ndarray, stamp_s: float) -> np.ndarray:
        """The marker position (m, base frame) the tracker reports for its sample stamped ``stamp_s`` (s), before noise."""
        return marker_base_m

    # ------------------------------------------------------------------ the compiled step (no-ops)
    def set_kernel_params(self, p: np.void) -> None:
        """Write this effect's :attr:`kernel_params` into an episode's ``params`` record (at reset)."""

    def load_kernel_state(self, s: np.void) -> None:
        """Copy this effect's Python state into the episode's ``state`` record (at the first compiled step)."""

    def store_kernel_state(self, s: np.void) -> None:
        """Copy the record's :attr:`kernel_state` back into this effect's Python state (after each compiled step)."""

    def apply_to_trace(self, trace: TraceView) -> None:
        """Sensor-only effects: the same change on a recorded trace (in place)."""
        raise NotImplementedError(f"{self.name} changes physics; it must be simulated")

    @classmethod
    def initial_guess(cls, evidence: dict[str, Any]) -> dict[str, float] | None:
        """Parameters read directly off the data, where the physics allows (a starting point for a fit).

        ``evidence`` (:func:`drillgym.eval.diagnosis.evidence.evidence`) holds ``tracker_offset_task_m`` (mean
        real-minus-sim tracker position before contact, m, task frame), ``R_base_task`` (3x3), ``excess_peaks_hz``
        (the frequency where the force residuals' power most exceeds the simulator's own, Hz, or None: over all
        force axes ``all``, the ``lateral`` ones and the ``axial`` one), ``contact_shift_m`` and ``beta_rad`` (per
        episode: how much further the real drill was commanded than its replay's when it first touched, m, and
        the planned surface inclination, rad). None: no direct reading.
        """
        return None


_STEP_HOOKS = ("command_delay_s", "begin_step", "delay_target", "sensor_wrenches", "tracker_marker_base_m")
"""The hooks the env calls during a step (the compiled step calls none: it has their counterparts)."""


def _overrides(effect: Effect, method: str) -> bool:
    return getattr(type(effect), method) is not getattr(Effect, method)


class EffectStack:
    """Several effects acting together; the env talks to this, one call per hook point."""

    def __init__(self, effects: Sequence[Effect]) -> None:
        self.effects = list(effects)
        for e in self.effects:
            if not isinstance(e, Effect):
                raise TypeError(f"{e!r} is not an envs.effects.Effect")
        self._delay = [e for e in self.effects if _overrides(e, "command_delay_s")]
        self._begin = [e for e in self.effects if _overrides(e, "begin_step")]
        self._target = [e for e in self.effects if _overrides(e, "delay_target")]
        self._sensor = [e for e in self.effects if _overrides(e, "sensor_wrenches")]
        self._tracker = [e for e in self.effects if _overrides(e, "tracker_marker_base_m")]
        self.target_hook: Callable[[float, tuple[float, float, float]], tuple[float, float, float]] | None = (
            self._delay_target if self._target else None
        )
        hooked = [type(e) for e in self.effects if any(_overrides(e, h) for h in _STEP_HOOKS)]
        self.compiled = len(set(hooked)) == len(hooked) and all(
            type(e).__dict__.get("compiled", False) for e in self.effects
        )
        """Whether the compiled step can run these effects: each declares :attr:`Effect.compiled`, and no two of
        one class have step hooks (the kernel holds one set of parameters per hook)."""

    def attach(self, env: EffectHost) -> None:
        """Attach every effect (the cell has just been cleared)."""
        for e in self.effects:
            e.servo_offset_task_m = None
            e.attach(env)

    def command_delay_s(self, env: EffectHost, delay_s: float) -> float:
        """Latency of a command after every effect."""
        for e in self._delay:
            delay_s = e.command_delay_s(env, delay_s)
        return delay_s

    def begin_step(self, env: EffectHost) -> None:
        """Run the effects' step-start hooks."""
        for e in self._begin:
            e.begin_step(env)

    def target_offset_task_m(self, geometry_offset_task_m: np.ndarray | None) -> tuple[float, float, float] | None:
        """Sum of the servo offsets and the cell's geometry offset (m, task frame), or None if none."""
        total = None if geometry_offset_task_m is None else np.asarray(geometry_offset_task_m, dtype=float)
        for e in self.effects:
            if e.servo_offset_task_m is not None:
                total = e.servo_offset_task_m if total is None else total + e.servo_offset_task_m
        if total is None:
            return None
        x, y, z = (float(v) for v in total)
        return x, y, z

    def _delay_target(self, t_s: float, target: tuple[float, float, float]) -> tuple[float, float, float]:
        for e in self._target:
            target = e.delay_target(t_s, target)
        return target

    def sensor_wrenches(self, env: EffectHost, wrenches: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """True wrenches after every sensor-side effect."""
        for e in self._sensor:
            wrenches = e.sensor_wrenches(env, wrenches, t_s)
        return wrenches

    def tracker_marker_base_m(self, env: EffectHost, marker_base_m: np.ndarray, stamp_s: float) -> np.ndarray:
        """The marker position the tracker reports after every tracker-side effect (m, base frame)."""
        for e in self._tracker:
            marker_base_m = e.tracker_marker_base_m(env, marker_base_m, stamp_s)
        return marker_base_m
