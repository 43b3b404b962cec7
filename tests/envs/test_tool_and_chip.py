import math

import numpy as np
import pytest

from drillgym.envs.drilling import CantileverTool, DrillGeometry


def _beam_tip_deflection_numeric(force_n: float, length_m: float, ei: float, n: int = 4000) -> float:
    """Euler-Bernoulli cantilever: integrate curvature M(s)/EI twice (independent of 3EI/l^3)."""
    s = np.linspace(0.0, length_m, n)
    curvature = force_n * (length_m - s) / ei
    slope = np.concatenate([[0.0], np.cumsum(0.5 * (curvature[1:] + curvature[:-1]) * np.diff(s))])
    return float(np.sum(0.5 * (slope[1:] + slope[:-1]) * np.diff(s)))


@pytest.mark.parametrize("stickout_mm", [20.0, 36.0, 60.0])
def test_drill_lateral_deflection_matches_euler_bernoulli_beam(stickout_mm):
    tool = CantileverTool(diameter_m=1.5e-3, stickout_m=stickout_mm * 1e-3)
    force = 1.0
    d_eff = 0.85 * 1.5e-3
    ei = 210e9 * math.pi * d_eff**4 / 64
    expected = _beam_tip_deflection_numeric(force, stickout_mm * 1e-3, ei)
    got = tool.tip_deflection_m(np.array([force, 0.0, 0.0]))[0]
    assert got == pytest.approx(expected, rel=0.02)
    assert tool.lateral_stiffness_n_m == pytest.approx(3 * ei / (stickout_mm * 1e-3) ** 3, rel=1e-12)


def test_drill_stiffness_scales_with_inverse_cube_of_stickout():
    k30 = CantileverTool(stickout_m=0.030).lateral_stiffness_n_m
    k60 = CantileverTool(stickout_m=0.060).lateral_stiffness_n_m
    assert k30 / k60 == pytest.approx(8.0, rel=1e-9)


def test_drill_stiffness_magnitude_matches_handbook_range():
    # 1.5 mm drill, 30-40 mm stick-out: 0.95-5.5 N/mm for d_eff 0.8-0.9 D (cantilever handbook values)
    for length, lo, hi in ((0.030, 2.3, 5.5), (0.040, 0.95, 2.3)):
        k = CantileverTool(stickout_m=length).lateral_stiffness_n_m / 1e3
        assert lo <= k <= hi


def test_drill_axial_stiffness_is_ea_over_l():
    tool = CantileverTool(stickout_m=0.036)
    area = math.pi * (0.85 * 1.5e-3) ** 2 / 4
    assert tool.axial_stiffness_n_m == pytest.approx(210e9 * area / 0.036, rel=1e-12)


def test_chip_thickness_at_li_operating_point():
    g = DrillGeometry()
    # h = c / (N n) sin(kappa): 0.64 um at 0.5 mm/s, 1.29 um at 1 mm/s (20,000 rpm, 2 lips, 118 deg point)
    assert g.chip_thickness_m(0.5e-3, 20000) == pytest.approx(0.643e-6, rel=0.01)
    assert g.chip_thickness_m(1.0e-3, 20000) == pytest.approx(1.286e-6, rel=0.01)


def test_full_engagement_depth_is_radius_times_cot_kappa_plus_tan_beta():
    g = DrillGeometry()
    beta = math.radians(30)
    assert g.full_engagement_depth_m(beta) == pytest.approx(0.75e-3 * (1 / math.tan(math.radians(59)) + math.tan(beta)))


def test_drill_compliance_is_diagonal_with_the_lateral_and_axial_stiffnesses():
    """Tool frame (z along the drill): a tip force along x or y bends the drill, along z compresses it.

    Hand values for the default drill (D 1.5 mm, d_eff 0.85 D, l 36 mm, E 210 GPa): k_lat = 3EI/l³ and
    k_ax = EA/l; relative 1e-9 is float slack only.
    """
    d_eff, length, e = 0.85 * 1.5e-3, 0.036, 210e9
    k_lat = 3 * e * (math.pi * d_eff**4 / 64) / length**3
    k_ax = e * (math.pi * d_eff**2 / 4) / length
    c = CantileverTool().compliance_tool_m_n()
    np.testing.assert_allclose(c, np.diag([1 / k_lat, 1 / k_lat, 1 / k_ax]), rtol=1e-9, atol=0.0)
    deflection = CantileverTool().tip_deflection_m([1.0, -2.0, 3.0])  # a list is accepted as a vector
    np.testing.assert_allclose(deflection, [1.0 / k_lat, -2.0 / k_lat, 3.0 / k_ax], rtol=1e-9, atol=0.0)


def test_drill_shear_modulus_is_e_over_two_times_one_plus_nu():
    """G = E / (2 (1 + ν)): 210 GPa and ν 0.3 give 80.77 GPa (a handbook steel value); float slack only."""
    assert CantileverTool().shear_modulus_pa == pytest.approx(210e9 / 2.6, rel=1e-12)
    assert CantileverTool(poisson_ratio=0.5).shear_modulus_pa == pytest.approx(70e9, rel=1e-12)
