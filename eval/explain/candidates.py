"""Candidate explanations of Li's compensated runs: one unmodelled effect or controller-model error each.

A candidate has one parameter (SI), a range searched by the fit, the physically plausible part of that
range, and what it changes: an effect switched on in the cell (:mod:`drillgym.envs.effects`, every run) or
an override of li2023's own settings (the compensated runs only: an error of the controller's models or an
unreported gain of Li's). One parameter each keeps the fit well posed on five calibration numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

from drillgym.envs.effects.registry import EFFECTS
from drillgym.envs.errors import UserError


@dataclass(frozen=True)
class Candidate:
    """One explanation with one fitted parameter."""

    name: str
    param: str
    """Parameter name with its unit suffix."""
    low: float
    high: float
    """Range the fit searches."""
    plausible: tuple[float, float]
    """Physically plausible part of the range (a fit outside it, or pinned at a searched bound, is reported)."""
    reason: str
    effect: str = ""
    """Effect name (:data:`drillgym.envs.effects.registry.EFFECTS`); empty for a controller candidate."""
    controller_field: str = ""
    """li2023 config field set to the parameter (a controller candidate)."""
    scale_of_model_peak: bool = False
    """The parameter multiplies li2023's fitted model peak instead of replacing a field."""

    def effects_spec(self, value: float) -> str:
        """The effect spec of the cell at ``value`` ("" for a controller candidate)."""
        return f"{self.effect}:{self.param}={value!r}" if self.effect else ""

    def controller_overrides(self, value: float, model_peak_n: float) -> dict[str, float]:
        """li2023 overrides at ``value``, given the model peak fitted to this cell's uncompensated run."""
        if self.scale_of_model_peak:
            return {"model_peak_force_n": model_peak_n * value}
        out = {"model_peak_force_n": model_peak_n}
        if self.controller_field:
            out[self.controller_field] = value
        return out


def _effect(name: str, param: str, reason: str) -> Candidate:
    p = next(q for q in EFFECTS[name].params if q.name == param)
    return Candidate(f"{name}.{param}", param, p.low, p.high, (p.low, p.high), reason, effect=name)


CANDIDATES: tuple[Candidate, ...] = (
    _effect("latency", "extra_latency_s", "the real pipeline delays each corrected point (network, URScript, filter)"),
    _effect("servo_deadband", "band_m", "the UR5 loses sub-millimetre lateral corrections in a play / deadband"),
    _effect("joint_friction", "coulomb_rad", "joint friction: the servo lags its target against Coulomb friction"),
    _effect("joint_friction", "viscous_s", "joint friction: a viscous servo lag on every motion"),
    _effect("ft_drift", "fx_rate_n_s", "the F/T zero drifts; the online loop corrects the drift as if it were force"),
    _effect("thermal_softening", "softening", "the bone softens as it heats: the later force is smaller"),
    _effect("tool_length", "dl_m", "the drill sticks out more or less than the controller's model says"),
    _effect("skid_friction", "mu", "friction of the entering point on the slope holds it against the skid"),
    Candidate(
        "controller.drill_diameter_ratio",
        "tool_effective_diameter_ratio",
        0.6,
        1.2,
        (0.7, 1.0),
        "li2023's drill model (bending diameter over nominal) is wrong: its offline shift and its deflection "
        "estimate scale with ratio^-4; a fluted drill bends like 0.8-0.9 D, 1.0 is the nominal-rod mistake",
        controller_field="tool_effective_diameter_ratio",
    ),
    Candidate(
        "controller.force_model_gain",
        "model_peak_gain",
        0.25,
        2.5,
        (0.5, 2.0),
        "li2023's force model is off by a factor (Li fitted it to his own trial holes; a drill held on the axis "
        "meets ~1.2 x the free run's force)",
        scale_of_model_peak=True,
    ),
    Candidate(
        "controller.ki",
        "ki",
        0.0,
        2.0,
        (0.0, 2.0),
        "Li reports no KI: his gain on the accumulated deviation may differ from li2023's 0.25",
        controller_field="ki",
    ),
)
"""Every candidate ``drillgym explain-paper`` fits (``--quick`` fits a subset)."""

QUICK = ("joint_friction.coulomb_rad", "latency.extra_latency_s", "controller.force_model_gain")
"""The quick run's candidates."""


def candidate(name: str) -> Candidate:
    """The candidate called ``name`` (raises ``LookupError`` listing them)."""
    for c in CANDIDATES:
        if c.name == name:
            return c
    raise UserError(f"unknown candidate {name!r}; choose from {', '.join(c.name for c in CANDIDATES)}")
