"""Bone materials and named specimen presets.

Cutting coefficients follow the mechanistic split of Li et al. 2023 eq. 1 with edge (ploughing) terms:
an element of lip length ``db`` cutting a chip ``h`` feels ``dF = (K_c h + K_e) db`` in each of the
tangential, thrust and radial directions. At 20,000 rpm and 0.5 mm/s the chip is ~0.6 µm thick: the
edge terms carry half of the lip forces there (and the chisel's indentation is all edge), the chip
terms the other half, so forces grow with feed as Li's Fig. 10b shows. The specific cutting
pressures (2.5–6 GPa) are those of bone at sub-micron chips, where the size effect multiplies the
~0.3 GPa measured at tens of microns. The values of the default cortical bone are calibrated on Li's
uncompensated experiment (see ``docs/physics.md``); the other presets scale them by the relative
hardness reported for each tissue.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from drillgym.envs.errors import UserError


@dataclass(frozen=True)
class BoneMaterial:
    """Mechanistic cutting coefficients of one bone tissue.

    Cutting pressures in Pa (N per m² of chip section), edge coefficients in N per m of engaged edge.
    """

    k_tc_pa: float
    """Tangential cutting pressure K_tc (Pa)."""
    k_fc_pa: float
    """Thrust (feed-direction) cutting pressure K_fc (Pa)."""
    k_rc_pa: float
    """Radial cutting pressure K_rc (Pa); positive pushes the lip toward the drill axis."""
    k_te_n_m: float
    """Tangential edge coefficient K_te (N/m)."""
    k_fe_n_m: float
    """Thrust edge coefficient K_fe (N/m)."""
    k_re_n_m: float
    """Radial edge coefficient K_re (N/m)."""
    k_chisel_n_m: float
    """Thrust per metre of engaged chisel edge, which indents rather than cuts (N/m)."""

    def scaled(self, factor: float) -> BoneMaterial:
        """All coefficients multiplied by ``factor`` (density / hardness scaling)."""
        return BoneMaterial(
            k_tc_pa=self.k_tc_pa * factor,
            k_fc_pa=self.k_fc_pa * factor,
            k_rc_pa=self.k_rc_pa * factor,
            k_te_n_m=self.k_te_n_m * factor,
            k_fe_n_m=self.k_fe_n_m * factor,
            k_re_n_m=self.k_re_n_m * factor,
            k_chisel_n_m=self.k_chisel_n_m * factor,
        )


@dataclass(frozen=True)
class BonePreset:
    """A layered specimen: cortical shell over cancellous core."""

    name: str
    cortical: BoneMaterial
    cancellous: BoneMaterial
    description: str

    def scaled(self, factor: float) -> BonePreset:
        """Both layers' coefficients multiplied by ``factor`` (density scaling)."""
        if factor == 1.0:
            return self
        return replace(self, cortical=self.cortical.scaled(factor), cancellous=self.cancellous.scaled(factor))


# Calibrated on Li 2023's uncompensated run (buffalo cortical bone, 1.5 mm drill, 20,000 rpm,
# 0.5 mm/s, beta 30 deg): see docs/physics.md for the fit and its plausibility checks.
BUFFALO_CORTICAL = BoneMaterial(
    k_tc_pa=1.18e9,
    k_fc_pa=2.46e9,
    k_rc_pa=2.87e9,
    k_te_n_m=0.759e3,
    k_fe_n_m=1.58e3,
    k_re_n_m=1.85e3,
    k_chisel_n_m=10e3,
)
"""Cortical buffalo bone, calibrated (Li 2023's specimen)."""

CANCELLOUS_RATIO = 0.15
"""Cancellous / cortical force ratio: Lee et al. 2012 report 1–1.5 N cancellous thrust vs ~10 N cortical."""


def _preset(name: str, hardness: float, cancellous_ratio: float, description: str) -> BonePreset:
    cortical = BUFFALO_CORTICAL.scaled(hardness)
    return BonePreset(name, cortical, cortical.scaled(cancellous_ratio), description)


BONE_PRESETS: dict[str, BonePreset] = {
    p.name: p
    for p in (
        _preset("buffalo_femur", 1.0, CANCELLOUS_RATIO, "Buffalo long bone, Li 2023's specimen (default)."),
        _preset("bovine_tibia", 0.9, CANCELLOUS_RATIO, "Bovine tibia cortex, slightly softer than buffalo."),
        _preset("human_femur", 1.15, 0.2, "Adult human femoral cortex, harder and denser cancellous core."),
        _preset("porcine_femur", 0.75, 0.12, "Porcine femur, thinner and softer cortex."),
        _preset("sawbones_20pcf", 0.6, 0.25, "Synthetic polyurethane block (20 pcf), uniform and soft."),
    )
}
"""Named specimens. Hardness factors are relative to buffalo cortex (literature thrust ratios)."""


def nominal_hardness(name: str) -> float:
    """Preset ``name``'s cortical hardness relative to buffalo cortex (-): what the plan's bone type tells a controller.

    Raises:
        ValueError: unknown name (the message lists the known ones).
    """
    return get_bone_preset(name).cortical.k_fc_pa / BUFFALO_CORTICAL.k_fc_pa


def get_bone_preset(name: str, density_scale: float = 1.0) -> BonePreset:
    """Look a preset up by name, optionally scaling both layers by ``density_scale``.

    Raises:
        ValueError: unknown name (the message lists the known ones).
    """
    if name not in BONE_PRESETS:
        raise UserError(f"bone={name!r} is not a known preset; allowed: {sorted(BONE_PRESETS)}")
    return BONE_PRESETS[name].scaled(density_scale)
