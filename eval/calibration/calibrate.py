"""Calibration of the entry mechanics on the uncompensated paper run, and what it predicts for li2023.

The tip balance (``docs/physics.md`` §4) has three structural constants: how much of the surface drop a
sideways tip sees (``skid_relief``), how hard it is to cut the side of the hole (``K_lat``), how fast
side guidance grows with the engaged lip share (``guidance_exponent``) and how much of it waits for the
hole's wall (``wall_guidance_floor``, ``wall_length_m``). For any choice of these,
:func:`calibrate_entry` fits the two scale unknowns, the lips' lateral (radial + tangential)
coefficients and the drill stick-out, to Li's uncompensated mean tip deviation and peak lateral force,
and reports the two remaining uncompensated numbers (stable-stage force, hole offset) as checks.
:func:`predict_li2023` then refits the controller's own force model to the calibrated uncompensated
F/T force, as Li fits his, and runs the compensator. Nothing here is fitted to a compensated result.

The shipped constants are one such calibration; ``drillgym calibrate`` reproduces it and screens
alternatives (``docs/physics.md`` §6).
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.optimize import least_squares

from drillgym.controllers.models import fit_model_peak_n
from drillgym.controllers.registry import make_controller
from drillgym.controllers.rollout import run_episode, run_episodes
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.cell_params import CellParams
from drillgym.envs.drilling.bone import BUFFALO_CORTICAL, CANCELLOUS_RATIO, BonePreset
from drillgym.envs.effects import build_effects
from drillgym.envs.effects.registry import runs_compiled
from drillgym.envs.errors import UserError
from drillgym.envs.metrics import FORCE_FILTER_SAMPLES, moving_average
from drillgym.envs.scenario import Scenario
from drillgym.eval.bench.summary import mean_ci
from drillgym.eval.reproduce.paper import LI2023_UNCOMPENSATED

CALIBRATED_METRICS = ("deviation_mean_mm", "lateral_force_max_n")
"""Fitted by the two scale unknowns."""
CHECKED_METRICS = ("lateral_force_stable_n", "hole_offset_mm")
"""Not fitted: what the calibrated structure predicts for the uncompensated run."""
METRICS = (*CALIBRATED_METRICS, *CHECKED_METRICS)
"""Every metric reported, for the uncompensated run and for each li2023 prediction."""
LI2023_CHECKS = ("deviation_reduction_ge_45pct", "kp1_reduces_less_than_kp4", "force_falls", "hole_offset_falls")
"""The issue's checks on a prediction, as named by :func:`passes_li2023_checks`."""


_SHIPPED = CellParams()


@dataclass(frozen=True)
class EntryStructure:
    """The structural constants of the tip balance (defaults: the shipped ones, :class:`drillgym.envs.cell_params.CellParams`)."""

    skid_relief: float = _SHIPPED.skid_relief
    """Share of the surface drop a sideways tip sees (1: all of it; < 0 turns the skid into a walk)."""
    lateral_cut_resistance_n: float = _SHIPPED.lateral_cut_resistance_n
    """K_lat (N): moving the tip sideways by Δp while advancing Δz takes K_lat · Δp / Δz."""
    guidance_exponent: float = _SHIPPED.guidance_exponent
    """Side guidance grows as (engaged lip share) ** this."""
    wall_guidance_floor: float = _SHIPPED.wall_guidance_floor
    """Share of full guidance before the hole has a wall (1: none of the wall model)."""
    wall_length_m: float = _SHIPPED.wall_length_m
    """Depth of full-diameter hole over which the wall's guidance builds up (m)."""


@dataclass
class EntryCalibration:
    """Fitted scales and the uncompensated metrics they give (seed ``seed``)."""

    structure: EntryStructure
    lateral_scale: float
    """Multiplier on the shipped radial and tangential coefficients of cortical bone."""
    stickout_mm: float
    metrics: dict[str, float]
    runs: int
    """Uncompensated runs the fit took."""
    converged: bool

    def row(self) -> dict[str, Any]:
        """Flat record for a CSV row."""
        return {
            **asdict(self.structure),
            "lateral_scale": self.lateral_scale,
            "stickout_mm": self.stickout_mm,
            "runs": self.runs,
            "converged": self.converged,
            **{f"none_{k}": v for k, v in self.metrics.items()},
        }


def bone_with_lateral_scale(scale: float) -> BonePreset:
    """The default specimen with its lips' radial and tangential coefficients multiplied by ``scale``."""
    if not (np.isfinite(scale) and scale > 0.0):
        raise ValueError(f"lateral scale must be positive and finite, got {scale}")
    b = BUFFALO_CORTICAL
    cortical = replace(
        b,
        k_rc_pa=b.k_rc_pa * scale,
        k_re_n_m=b.k_re_n_m * scale,
        k_tc_pa=b.k_tc_pa * scale,
        k_te_n_m=b.k_te_n_m * scale,
    )
    return BonePreset("buffalo_femur", cortical, cortical.scaled(CANCELLOUS_RATIO), "calibration candidate")


def env_kwargs(structure: EntryStructure, lateral_scale: float, stickout_mm: float) -> dict[str, Any]:
    """The env's arguments for the paper scenario with this structure and these scales."""
    return {
        "cell_params": CellParams(**asdict(structure)),
        "bone_material": bone_with_lateral_scale(lateral_scale),
        "stickout_mm": stickout_mm,
    }


def make_env(structure: EntryStructure, lateral_scale: float, stickout_mm: float, effects: str = "") -> Any:
    """The paper scenario with this structure and these scales (and the unmodelled effects of spec ``effects``)."""
    env = gym.make(SIM_ENV_ID, **env_kwargs(structure, lateral_scale, stickout_mm))
    if effects:
        env.unwrapped.set_effects(build_effects(effects))  # type: ignore[attr-defined]
    return env


def _uncompensated(env: Any, seed: int) -> Any:
    """One uncompensated episode: an :class:`drillgym.controllers.rollout.EpisodeResult` with the F/T trace."""
    return run_episode(env, None, seed=seed)


def calibrate_entry(
    structure: EntryStructure, seed: int = 0, max_runs: int = 40, rel_tol: float = 0.02, effects: str = ""
) -> EntryCalibration:
    """Fit the lateral scale and the stick-out to Li's uncompensated deviation and peak force.

    Least squares on the log-ratios of the two metrics to their targets (SciPy's trust-region solver,
    finite differences), in log scale and log stick-out (10-100 mm), from the shipped values.
    ``converged`` is whether both metrics end within ``rel_tol`` of their targets. ``effects``: an effect spec
    switched on in the cell (e.g. the Li cell's, :data:`drillgym.envs.effects.cells.CELLS`).

    Raises:
        ValueError: ``max_runs`` < 3 or ``rel_tol`` not positive.
    """
    if max_runs < 3 or not rel_tol > 0.0:
        raise UserError(f"max_runs={max_runs} must be >= 3 and rel_tol={rel_tol} > 0")
    targets = np.array([LI2023_UNCOMPENSATED[k] for k in CALIBRATED_METRICS])
    seen: dict[tuple[float, float], dict[str, float]] = {}

    def metrics_at(x: np.ndarray) -> dict[str, float]:
        key = (float(x[0]), float(x[1]))
        if key not in seen:
            env = make_env(structure, math.exp(key[0]), math.exp(key[1]), effects)
            try:
                m = _uncompensated(env, seed).metrics
            finally:
                env.close()
            seen[key] = {k: float(m[k]) for k in METRICS}
        return seen[key]

    def residual(x: np.ndarray) -> np.ndarray:
        m = metrics_at(x)
        got = np.array([max(m[k], 1e-6) for k in CALIBRATED_METRICS])
        return np.log(got / targets)

    x0 = np.array([0.0, math.log(Scenario().stickout_mm)])
    lo, hi = np.array([-5.0, math.log(10.0)]), np.array([5.0, math.log(100.0)])
    sol = least_squares(residual, x0, bounds=(lo, hi), diff_step=1e-2, max_nfev=max_runs, xtol=1e-4, ftol=1e-6)
    x = sol.x
    metrics = metrics_at(x)
    converged = bool(np.all(np.abs(np.exp(residual(x)) - 1.0) < rel_tol))
    return EntryCalibration(structure, math.exp(x[0]), math.exp(x[1]), metrics, len(seen), converged)


def fit_controller_model_n(env: Any, trace: dict[str, np.ndarray]) -> float:
    """li2023's model peak (N) fitted to the filtered F/T force of an uncompensated ``trace`` of ``env``."""
    force = np.asarray(trace["ft_force_n"], dtype=float)
    filtered = moving_average(np.hypot(force[:, 0], force[:, 1]), FORCE_FILTER_SAMPLES)
    plan = env.unwrapped.plan
    return fit_model_peak_n(plan, np.asarray(trace["depth_cmd_m"]), filtered, env.unwrapped.scenario.entry_depth_m)


PREDICTED = {"kp4": "", "kp1": "kp=1.0,", "offline": "online=false,"}
"""The compensated runs predicted for each calibration: li2023 overrides (the fitted model peak is added)."""
PAIRED = (("kp4", "none"), ("kp1", "kp4"))
"""Paired differences (same seeds) reported with their 95 % CI: ``{a}_minus_{b}_{metric}_ci_low/high``."""


def predict_li2023(cal: EntryCalibration, seeds: range | list[int], effects: str = "") -> dict[str, float]:
    """Mean metrics over ``seeds`` of none and the :data:`PREDICTED` li2023 variants, plus the fitted model peak.

    li2023's model is fitted to the uncompensated run of the first seed. The li2023 variants run their seeds
    together on the batched engine where the effects are compiled (the same rows, bit for bit).
    """
    env = make_env(cal.structure, cal.lateral_scale, cal.stickout_mm, effects)
    kwargs = env_kwargs(cal.structure, cal.lateral_scale, cal.stickout_mm)
    batched = runs_compiled(effects)
    try:
        none = [_uncompensated(env, s) for s in seeds]
        peak = fit_controller_model_n(env, none[0].trace)
        results: dict[str, list[dict[str, Any]]] = {"none": [r.metrics for r in none]}
        for name, overrides in PREDICTED.items():
            spec = f"li2023:{overrides}model_peak_force_n={peak:.4f}"
            if batched:
                runs = run_episodes(functools.partial(make_controller, spec), list(seeds), kwargs, effects)
                results[name] = [r.row() for r in runs]
            else:
                results[name] = [run_episode(env, make_controller(spec), s, keep_trace=False).row() for s in seeds]
    finally:
        env.close()
    out: dict[str, float] = {"model_peak_n": peak}
    for name, rows in results.items():
        for k in METRICS:
            out[f"{name}_{k}"] = float(np.mean([r[k] for r in rows]))
    for a, b in PAIRED:
        for k in METRICS:
            diff = [ra[k] - rb[k] for ra, rb in zip(results[a], results[b], strict=True)]
            mean, lo, hi, n = mean_ci(diff)
            if n == 1:  # one seed (a quick screen): its difference stands for the interval
                lo = hi = mean
            out[f"{a}_minus_{b}_{k}_ci_low"], out[f"{a}_minus_{b}_{k}_ci_high"] = lo, hi
    return out


def passes_li2023_checks(pred: dict[str, float]) -> dict[str, bool]:
    """Issue-level checks on a prediction, as the benchmark judges them.

    Deviation down by ≥ 45 % (means); KP 1 deviating more than KP 4, the peak force and the hole offset
    falling, each with the 95 % CI of the paired difference excluding 0.
    """
    return {
        "deviation_reduction_ge_45pct": pred["kp4_deviation_mean_mm"] <= 0.55 * pred["none_deviation_mean_mm"],
        "kp1_reduces_less_than_kp4": pred["kp1_minus_kp4_deviation_mean_mm_ci_low"] > 0.0,
        "force_falls": pred["kp4_minus_none_lateral_force_max_n_ci_high"] < 0.0,
        "hole_offset_falls": pred["kp4_minus_none_hole_offset_mm_ci_high"] < 0.0,
    }
