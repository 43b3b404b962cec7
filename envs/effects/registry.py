"""The candidate library by name, and effect specs: ``NAME[:PARAM=VALUE,...][+NAME...]``."""

from __future__ import annotations

from collections.abc import Iterable

from drillgym.envs.effects.backlash import JointBacklash
from drillgym.envs.effects.base import Effect, EffectStack
from drillgym.envs.effects.bone import DensityGradient, SkidFriction, ThermalSoftening
from drillgym.envs.effects.joints import JointFriction, KinematicOffset
from drillgym.envs.effects.registration import Registration
from drillgym.envs.effects.resonance import FTResonance
from drillgym.envs.effects.sensor import FTContactBias, FTDrift, FTEpisodeDrift, FTGain, ToolRunout
from drillgym.envs.effects.servo import ServoDeadband
from drillgym.envs.effects.spindle import SpindleSag
from drillgym.envs.effects.timing import Latency
from drillgym.envs.effects.tool import ToolLength
from drillgym.envs.effects.tracker import TrackerLatency
from drillgym.envs.effects.trends import KinematicOffsetTrend
from drillgym.envs.errors import UserError
from drillgym.envs.key_values import convert, split_items, split_named

EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        FTDrift,
        FTEpisodeDrift,  # early: the longest sensor-side fit, so it does not start last on its worker
        Latency,
        JointFriction,
        KinematicOffset,
        ToolLength,
        DensityGradient,
        ThermalSoftening,
        SkidFriction,
        SpindleSag,
        ToolRunout,
        Registration,
        ServoDeadband,
        FTGain,
        FTContactBias,
        TrackerLatency,
        FTResonance,
        JointBacklash,
        KinematicOffsetTrend,
    )
}
"""The unmodelled effects of the library, by name (``build_effects``, ``make-reality``, cells)."""

OPT_IN_CANDIDATES = ("servo_deadband", "ft_gain", "ft_contact_bias", "registration", "kinematic_offset_trend")
"""In the library, but tried only when asked for (``diagnose --candidates``); measured on ``bench-diagnosis --opt-in``
(``docs/diagnosis.md`` §6). ``servo_deadband`` (added for ``drillgym explain-paper``): the withheld-effect benchmark
has not been run with it. ``ft_gain``, ``ft_contact_bias``: each named its own reality, but also served as a second
effect patching a bone model's force level (and ``ft_gain``'s cross-talk from the thrust took a thrust-loaded bias).
``registration``: named its reality (both forms) and nothing else, but its fits add 4–6 s to a 12-episode diagnosis
of 19 s (each surface angle rebuilds the episodes' force tables). ``kinematic_offset_trend``: named its strong
drifting reality on three seed offsets, but not the moderate one (and once with a bone effect as a second effect),
took the static offsets' place in 5 of 12 static cases (right physics, a drift where there is none), and a
12-episode diagnosis with it took 33–39 s (its pairs carry six parameters), above the 30 s budget."""
DIAGNOSIS_CANDIDATES: tuple[str, ...] = tuple(name for name in EFFECTS if name not in OPT_IN_CANDIDATES)
"""The candidates ``drillgym diagnose`` and ``bench-diagnosis`` try by default."""


def physics_of(name: str) -> str:
    """The physics a candidate names: itself, or the effect it is a variant of (``ft_episode_drift`` -> ``ft_drift``)."""
    cls = EFFECTS.get(name)
    return name if cls is None or cls.variant_of is None else cls.variant_of


def physics_set(names: Iterable[str]) -> frozenset[str]:
    """The physics a model of effects ``names`` names (:func:`physics_of` of each): what tells two models' physics apart."""
    return frozenset(physics_of(n) for n in names)


def parse_candidates(text: str) -> tuple[str, ...]:
    """A comma-separated list of candidate names (``diagnose --candidates``); ``ValueError`` names unknown ones."""
    candidates = tuple(c.strip() for c in text.split(",") if c.strip())
    unknown = sorted(set(candidates) - set(EFFECTS))
    if unknown:
        raise UserError(f"unknown candidate effect(s) {unknown}; choose from {sorted(EFFECTS)}")
    return candidates


def parse_effect_spec(spec: str) -> list[tuple[str, dict[str, float]]]:
    """Split ``"a:x=1,y=2+b"`` into ``[("a", {"x": 1.0, "y": 2.0}), ("b", {})]``.

    Raises:
        ValueError: an empty name or a malformed ``PARAM=VALUE``.
    """
    out: list[tuple[str, dict[str, float]]] = []
    for part in spec.split("+"):
        name, rest = split_named(part)
        if not name:
            raise UserError(f"effect spec {spec!r}: empty effect name")
        what = f"effect spec {spec!r}"
        values: dict[str, float] = {}
        for key, raw in split_items(rest, what).items():
            try:
                values[key] = convert(key, raw, float)
            except ValueError as e:
                raise UserError(f"{what}: {e}") from e
        out.append((name, values))
    return out


def build_effects(spec: str, library: dict[str, type[Effect]] | None = None) -> list[Effect]:
    """Effects from a spec, looked up in ``library`` (default: the candidate library :data:`EFFECTS`)."""
    lib = EFFECTS if library is None else library
    effects = []
    for name, values in parse_effect_spec(spec):
        if name not in lib:
            raise UserError(f"unknown effect {name!r}; choose from {sorted(lib)}")
        effects.append(lib[name](**values))
    return effects


def runs_compiled(spec: str) -> bool:
    """Whether a cell with the effects of ``spec`` steps compiled (none, or compiled ones only): the batched engine runs it."""
    return not spec or EffectStack(build_effects(spec)).compiled
