"""The withheld-effect benchmark's cases.

Every reality effect at two magnitudes, pairs, clean data and an effect outside the candidate library.

Each case is a reality spec (:mod:`drillgym.eval.diagnosis.reality`); the diagnosis never sees it, only the
logs, and its candidate library (:mod:`drillgym.envs.effects`) holds separately written models of the same
physics (and none of the out-of-library effect).
"""

from __future__ import annotations

from dataclasses import dataclass

from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES
from drillgym.eval.diagnosis.reality.generate import build_reality


@dataclass(frozen=True)
class Case:
    """One benchmark case."""

    name: str
    kind: str
    """``single``, ``pair``, ``clean`` or ``outside`` (the effect is not in the library)."""
    spec: str
    """Reality spec (``"none"`` for clean data)."""
    seed: int

    @property
    def truth(self) -> list[str]:
        """The candidate names that model the switched-on effects (empty for clean / outside)."""
        return [e.explains for e in build_reality(self.spec) if e.explains]

    @property
    def truth_values(self) -> dict[str, dict[str, float]]:
        """Candidate name -> the parameters standing for its reality's own (``RealityEffect.candidate_values``)."""
        out: dict[str, dict[str, float]] = {}
        for e in build_reality(self.spec):
            values = e.candidate_values()
            if e.explains and values is not None:
                out[e.explains] = values
        return out

    @property
    def expected_location(self) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
        """Channels and stages where an outside effect's gap should be found."""
        for e in build_reality(self.spec):
            if e.location is not None:
                return e.location
        return None


SINGLES: dict[str, tuple[str, str]] = {
    "ft_warmup": ("ft_warmup:fz_n=2.5,fx_n=1.2", "ft_warmup:fz_n=5.0,fx_n=-2.5,fy_n=1.5"),
    "jittered_latency": ("jittered_latency:mean_s=0.03,jitter_s=0.01", "jittered_latency:mean_s=0.08,jitter_s=0.02"),
    "stribeck_friction": (
        "stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4",
        "stribeck_friction:static_rad=5e-4,coulomb_rad=3e-4,viscous_s=0.01",
    ),
    "joint_offsets": ("joint_offsets:dq1_rad=5e-4", "joint_offsets:dq0_rad=1e-3,dq2_rad=-1e-3"),
    "chuck_tool_length": (
        "chuck_tool_length:dl_m=0.002,chuck_rad_per_nm=0.02",
        "chuck_tool_length:dl_m=-0.004,chuck_rad_per_nm=0.05",
    ),
    "density_layer": ("density_layer:hardening=0.2", "density_layer:hardening=0.5,depth_m=0.002"),
    "heat_softening": ("heat_softening:softening_per_k=0.002", "heat_softening:softening_per_k=0.005"),
    "entry_friction": ("entry_friction:mu=0.2", "entry_friction:mu=0.6"),
    "wobbly_runout": ("wobbly_runout:runout_m=2e-5", "wobbly_runout:runout_m=4e-5"),
    "tracker_smoothing": ("tracker_smoothing:tau_s=0.06", "tracker_smoothing:tau_s=0.15"),
    "episode_warmup": ("episode_warmup:spread_n=2.5", "episode_warmup:fz_n=3,spread_n=5"),
    "spindle_motor": ("spindle_motor:sag_per_nm=100", "spindle_motor:sag_per_nm=250,time_constant_s=0.5"),
}
"""Reality effect -> (moderate, strong) spec, the benchmark's first realities (a new reality goes last, so the
earlier cases keep their seeds)."""
LATER_SINGLES: dict[str, tuple[str, str]] = {
    "ft_load_bias": ("ft_load_bias:bx_n=0.6,bz_n=-0.8", "ft_load_bias:bx_n=-1.5,by_n=1.0,bz_n=2.0"),
    "bone_registration": ("bone_registration:ex_m=1e-3", "bone_registration:ez_m=6e-4,tilt_rad=0.08"),
    "mount_resonance": (
        "mount_resonance:freq_xy_hz=25,freq_z_hz=25,damping=0.08",
        "mount_resonance:freq_xy_hz=15,freq_z_hz=30,damping=0.05",
    ),
    "gear_backlash": (
        "gear_backlash:play0_rad=2e-4,play1_rad=2e-4,play2_rad=2e-4",
        "gear_backlash:play0_rad=2e-4,play1_rad=5e-4,play2_rad=3e-4",
    ),
    "ft_lateral_gain": ("ft_lateral_gain:gain=0.15,crosstalk=0.005", "ft_lateral_gain:gain=-0.3,crosstalk=0.01"),
    "joint_drift": (
        "joint_drift:dq1_per_hole_rad=1e-4",
        "joint_drift:dq1_first_rad=-5e-4,dq0_per_hole_rad=1e-4,dq2_per_hole_rad=-1.5e-4",
    ),
}
"""The realities of the wider library's candidates, after :data:`SINGLES` (their seeds follow SINGLES' and stay
the same in every run). One whose candidate is a default one (``mount_resonance``: ``ft_resonance``;
``gear_backlash``: ``joint_backlash``) is a default case; the others (their candidates ``ft_contact_bias``,
``registration`` and ``ft_gain`` are opt-in) run with ``bench-diagnosis --opt-in``, which adds their candidates."""


def _candidate(specs: tuple[str, str]) -> str | None:
    """The candidate that models a reality's cases (None for an effect outside the library)."""
    return next((e.explains for e in build_reality(specs[0]) if e.explains), None)


PAIRS: tuple[str, ...] = (
    "jittered_latency:mean_s=0.08,jitter_s=0.02+heat_softening:softening_per_k=0.002",
    "joint_offsets:dq1_rad=2.5e-4+density_layer:hardening=0.5,depth_m=0.002",
    "ft_warmup:fz_n=10,fx_n=5+wobbly_runout:runout_m=2e-5",
    "entry_friction:mu=0.2+stribeck_friction:static_rad=2e-4,coulomb_rad=1.5e-4",
    "chuck_tool_length:dl_m=0.002,chuck_rad_per_nm=0.02+joint_offsets:dq0_rad=1e-3,dq2_rad=-1e-3",
)
"""Two effects at once, at sizes whose single-effect gaps (gap over the simulator's own level, measured
on the single cases) lie within a factor of about 3 of each other, so that neither hides the other."""
OUTSIDE: tuple[str, ...] = (
    "bone_void:length_m=0.001",
    "bone_void:length_m=0.0015,depth_m=0.003,residual=0.2",
    "ft_broadband_noise:sigma_n=0.06",
    "ft_broadband_noise:sigma_n=0.15,lateral_share=0.2",
    "ft_torque_gain:gain=0.2",
    "ft_torque_gain:gain=-0.3",
)
"""Effects outside the candidate library (new ones go last, so the earlier cases keep their seeds): a void in the
bone, a noisier F/T (broadband, before contact too, strongest on Fz) and a torque-only calibration error, each at
two magnitudes. The sensor faults have a shape no candidate has (docs/diagnosis.md §3, the shape test)."""
CLEAN_TRIALS = 6


def opt_in_candidates() -> tuple[str, ...]:
    """The opt-in candidates that model :data:`LATER_SINGLES`' realities."""
    names = (_candidate(specs) for specs in LATER_SINGLES.values())
    return tuple(dict.fromkeys(n for n in names if n is not None and n not in DIAGNOSIS_CANDIDATES))


def full_cases(opt_in: bool = False) -> list[Case]:
    """Every case of the full benchmark (with ``opt_in`` also the realities of the opt-in candidates)."""
    optional = set(opt_in_candidates())
    cases: list[Case] = []
    for position, (name, specs) in enumerate((SINGLES | LATER_SINGLES).items()):
        if not opt_in and _candidate(specs) in optional:
            continue
        for k, spec in enumerate(specs):  # seeds by the reality's place in the tables, whichever run
            cases.append(Case(f"{name}-{('moderate', 'strong')[k]}", "single", spec, 100 + 2 * position + k))
    for k, spec in enumerate(PAIRS):
        cases.append(Case(f"pair-{k}", "pair", spec, 200 + k))
    for k in range(CLEAN_TRIALS):
        cases.append(Case(f"clean-{k}", "clean", "none", 300 + k))
    for k, spec in enumerate(OUTSIDE):
        cases.append(Case(f"outside-{k}", "outside", spec, 400 + k))
    return cases


QUICK_CANDIDATES = ("ft_drift", "tool_runout", "latency")
"""Candidates of ``--quick`` (test-sized): the cheap sensor-side ones and one replayed."""


def quick_cases() -> list[Case]:
    """A test-sized benchmark: one effect, clean data, the outside effect."""
    return [
        Case("ft_warmup-strong", "single", SINGLES["ft_warmup"][1], 101),
        Case("clean-0", "clean", "none", 300),
        Case("outside-0", "outside", OUTSIDE[0], 400),
    ]
