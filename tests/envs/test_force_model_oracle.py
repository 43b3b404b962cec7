"""The force model against independent oracles (:mod:`drillgym.envs.drilling.force_model`).

The oracles come from docs/physics.md §1, not from the module: a lip point at radius r and angle φ is in bone
when ``e = d − r (cot κ − cos φ tan β) > 0``, the cycle average is ``N/(2π) ∫ dF dφ``, and an element of lip
length ``db = dr / sin κ`` gets ``(K_r) db`` toward the axis, ``(K_t) db`` against the lip velocity, ``(K_f) db``
of thrust, the chisel ``K_ch db`` of thrust only. At radius r the engaged arc is ``|φ| < α(r)`` with
``cos α = (cot κ − d/r) / tan β``, so the lateral force is ``−N/(2π) ∫ K 2 sin α db`` along x (radial part) and y
(tangential part), integrated here with SciPy's adaptive quadrature instead of the module's 24 × 120 grid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from drillgym.envs.drilling import DrillGeometry, EngagementTable, ForceModel, engaged_corner_fraction, get_bone_preset
from drillgym.envs.drilling.force_model import stage_bounds, stage_from_depth

GEOM = DrillGeometry()
BONE = get_bone_preset("buffalo_femur")
R = 0.75e-3  # m, half of Li's 1.5 mm drill
W = 0.18 * R  # chisel half-length (web ratio 0.18)
KAPPA = math.radians(59.0)  # half of the 118° point
COT, SIN = 1.0 / math.tan(KAPPA), math.sin(KAPPA)
BETA = math.radians(30.0)
N_LIPS = 2


def _corner_fraction_by_sampling(depth_m: float, beta_rad: float, n: int = 200_000) -> float:
    """Share of ``n`` equally spaced angles at which the lip corner (r = R) is in bone (e > 0)."""
    phi = (np.arange(n) + 0.5) * 2.0 * math.pi / n
    e = depth_m - R * (COT - np.cos(phi) * math.tan(abs(beta_rad)))
    return float(np.mean(e > 0.0))


# --------------------------------------------------------------------------------- the lip corner and the stages


@pytest.mark.parametrize("beta_deg", [30.0, -30.0, 10.0, 45.0])
@pytest.mark.parametrize("depth_mm", [-0.5, 0.0, 0.02, 0.1, 0.3, 0.45, 0.6, 0.8, 0.95, 1.5])
def test_the_corner_fraction_is_the_share_of_a_revolution_the_corner_spends_in_bone(beta_deg, depth_mm):
    """Against 200,000 sampled angles: the sampling resolves the fraction to 1/200,000, so 1e-4 is ample."""
    beta = math.radians(beta_deg)
    expected = _corner_fraction_by_sampling(depth_mm * 1e-3, beta)
    assert engaged_corner_fraction(depth_mm * 1e-3, GEOM, beta) == pytest.approx(expected, abs=1e-4)


def test_the_corner_fraction_is_zero_when_the_corner_first_touches_one_half_at_r_cot_kappa_and_one_when_full():
    """Hand values (β 30°): the corner touches at R (cot κ − tan β), is in for half a turn at R cot κ, always from
    R (cot κ + tan β); each compared to 1e-9, float slack of one acos."""
    tan_b = math.tan(BETA)
    for depth, expected in ((R * (COT - tan_b), 0.0), (R * COT, 0.5), (R * (COT + tan_b), 1.0)):
        assert engaged_corner_fraction(depth, GEOM, BETA) == pytest.approx(expected, abs=1e-9)


def test_on_a_flat_surface_the_whole_corner_circle_enters_bone_at_once_at_r_cot_kappa():
    """β = 0: every angle reaches the surface together when the tip is R cot κ deep; from there on (the
    surface itself included) the fraction is 1, just above 0."""
    depth = GEOM.radius_m * GEOM.cot_kappa
    assert engaged_corner_fraction(depth, GEOM, 0.0) == 1.0
    assert engaged_corner_fraction(math.nextafter(depth, 0.0), GEOM, 0.0) == 0.0
    assert engaged_corner_fraction(1e-3, GEOM, 1e-13) == 1.0  # a tilt below 1e-12 rad counts as flat
    assert engaged_corner_fraction(0.4e-3, GEOM, 1e-13) == 0.0
    assert engaged_corner_fraction(depth, GEOM, 1e-12) == 0.5  # from tan β = 1e-12 on it is tilted: half a turn


def _first_depth_where(fraction_reaches: float, beta_rad: float) -> float:
    """Bisection on the sampled corner fraction: the smallest depth (m) where it exceeds ``fraction_reaches``."""
    lo, hi = -2e-3, 2e-3
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _corner_fraction_by_sampling(mid, beta_rad, 20_000) > fraction_reaches:
            hi = mid
        else:
            lo = mid
    return hi


@pytest.mark.parametrize("beta_deg", [30.0, -30.0, 45.0])
def test_stage_bounds_are_where_the_corner_fraction_leaves_zero_passes_one_half_and_reaches_one(beta_deg):
    """Li's stages from the geometry (docs/physics.md §1): stage 2 begins when the corner first enters bone,
    3 at half a revolution, 4 at a full one; stage 1 (first touch) when any lip point enters bone, i.e. the
    tip itself (depth 0) or, when tan β > cot κ, the corner at φ = 0 first. Found by bisection on sampled
    angles (20,000: a fraction step of 5e-5 over a slope of ~1/R, i.e. < 0.1 µm), hence abs 0.2 µm."""
    beta = math.radians(beta_deg)
    touch, corner_in, half, full = stage_bounds(GEOM, beta)
    assert corner_in == pytest.approx(_first_depth_where(0.0, beta), abs=2e-7)
    assert half == pytest.approx(_first_depth_where(0.5 - 1e-9, beta), abs=2e-7)
    assert full == pytest.approx(_first_depth_where(1.0 - 1e-9, beta), abs=2e-7)
    assert touch == pytest.approx(min(0.0, corner_in), abs=1e-15)


def test_stage_bounds_in_micrometres_for_the_paper_drill_at_30_and_45_degrees():
    """Hand values: R = 0.75 mm, cot 59° = 0.6008606, tan 30° = 0.5773503, tan 45° = 1, written to the nm (abs
    1e-3 µm: the rounding of the hand values)."""
    assert np.array(stage_bounds(GEOM, BETA)) * 1e6 == pytest.approx([0.0, 17.633, 450.645, 883.658], abs=1e-3)
    assert np.array(stage_bounds(GEOM, math.radians(45))) * 1e6 == pytest.approx(
        [-299.355, -299.355, 450.645, 1200.645], abs=1e-3
    )


@pytest.mark.parametrize(
    ("depth_um", "stage"),
    [
        (-1.0, 0),
        (0.0, 0),
        (0.001, 1),
        (17.0, 1),
        (17.633, 1),
        (18.0, 2),
        (450.0, 2),
        (450.645, 3),
        (883.0, 3),
        (883.658, 4),
    ],
)
def test_the_stage_of_a_depth_at_30_degrees(depth_um, stage):
    """Bounds 0, 17.633, 450.645, 883.658 µm (previous test); at a bound: stages 0 and 1 end on it, 2 and 3 before
    it. A depth given at a bound (to 1 nm) is replaced by the bound itself, so it lands exactly on it."""
    bounds = stage_bounds(GEOM, BETA)
    depth = next((b for b in bounds if abs(b * 1e6 - depth_um) < 1e-3), depth_um * 1e-6)
    assert stage_from_depth(depth, GEOM, BETA) == stage


# --------------------------------------------------------------------------------- the cycle-averaged table


def _alpha(r: float, depth_m: float, beta_rad: float) -> float:
    c = (COT - depth_m / r) / math.tan(beta_rad)
    return 0.0 if c >= 1.0 else (math.pi if c <= -1.0 else math.acos(c))


def _closed_form(depth_m: float, beta_rad: float, material) -> np.ndarray:
    """(F_x, F_y, F_z, M_z) edge and per-chip rows by quadrature of docs/physics.md §1 (one material)."""

    def quad(f, a: float, b: float) -> float:
        return integrate.quad(f, a, b, limit=400)[0] / SIN

    s = quad(lambda r: 2.0 * math.sin(_alpha(r, depth_m, beta_rad)), W, R)  # ∫ 2 sin α db over the lips
    arc = quad(lambda r: 2.0 * _alpha(r, depth_m, beta_rad), W, R)  # ∫ 2 α db, engaged lip measure
    arc_r = quad(lambda r: 2.0 * _alpha(r, depth_m, beta_rad) * r, W, R)  # its first moment (torque arm)
    chisel = quad(lambda r: 2.0 * _alpha(r, depth_m, beta_rad), 0.0, W)
    c = -N_LIPS / (2.0 * math.pi)
    m = material
    edge = c * np.array(
        [m.k_re_n_m * s, m.k_te_n_m * s, m.k_fe_n_m * arc + m.k_chisel_n_m * chisel, m.k_te_n_m * arc_r]
    )
    chip = c * np.array([m.k_rc_pa * s, m.k_tc_pa * s, m.k_fc_pa * arc, m.k_tc_pa * arc_r])
    return np.stack([edge, chip])


@pytest.fixture
def table_30() -> EngagementTable:
    """Built per test (~0.1 s), not per module: mutation testing maps a test to the functions it calls itself."""
    return EngagementTable.build(GEOM, BONE, BETA, 8e-3, 8e-3)


def _at(tab: EngagementTable, depth_m: float) -> np.ndarray:
    return np.stack([[np.interp(depth_m, tab.depth_m, t[:, j]) for j in range(4)] for t in (tab.edge, tab.per_chip)])


@pytest.mark.parametrize("depth_mm", [0.05, 0.1, 0.15, 0.2, 0.3, 0.45, 0.6])
def test_the_entry_forces_are_the_closed_form_cycle_average(table_30, depth_mm):
    """Stages 1-3 at β 30°, in cortical bone. Tolerances are the module's discretisation error (24 radii x 120
    angles against adaptive quadrature), measured at these depths: lateral ≤ 2.4 %, thrust ≤ 4.6 % (its chisel
    ends at an element's midpoint: 4 of 24 elements, 0.167 R, for w = 0.18 R), torque ≤ 1.4 %; allowed 3, 6 and
    2.5 %. The lateral force's direction is exact: F_y / F_x = K_t / K_r for both rows (same arc integral)."""
    depth = depth_mm * 1e-3
    got, want = _at(table_30, depth), _closed_form(depth, BETA, BONE.cortical)
    for row in (0, 1):
        assert got[row, :2] == pytest.approx(want[row, :2], rel=0.03)
        assert got[row, 2] == pytest.approx(want[row, 2], rel=0.06)
        assert got[row, 3] == pytest.approx(want[row, 3], rel=0.025)
    m = BONE.cortical
    assert got[0, 1] / got[0, 0] == pytest.approx(m.k_te_n_m / m.k_re_n_m, rel=1e-9)
    assert got[1, 1] / got[1, 0] == pytest.approx(m.k_tc_pa / m.k_rc_pa, rel=1e-9)
    assert got[0, 0] < 0.0 and got[0, 1] < 0.0  # downhill (−x) and −y


def test_a_fully_engaged_drill_has_the_closed_form_thrust_and_torque_and_no_lateral_force(table_30):
    """Stage 4 (1 to 8 mm, all cortical): F_z = −N (K_fe L_lip + K_ch L_chisel), M_z = −N K_te (R² − w²) / (2 sin κ),
    per chip the same with K_fc, K_tc. Same discretisation tolerances as the entry (thrust 6 %, torque 2.5 %)."""
    m = BONE.cortical
    lip, chisel, moment = (R - W) / SIN, W / SIN, (R**2 - W**2) / (2.0 * SIN)
    for depth in (1e-3, 4e-3, 8e-3):
        got = _at(table_30, depth)
        assert np.all(np.abs(got[:, :2]) <= 1e-9 * np.abs(got[:, 2:3]))  # balanced: rounding only
        assert got[0, 2] == pytest.approx(-N_LIPS * (m.k_fe_n_m * lip + m.k_chisel_n_m * chisel), rel=0.06)
        assert got[1, 2] == pytest.approx(-N_LIPS * m.k_fc_pa * lip, rel=0.06)
        assert got[0, 3] == pytest.approx(-N_LIPS * m.k_te_n_m * moment, rel=0.025)
        assert got[1, 3] == pytest.approx(-N_LIPS * m.k_tc_pa * moment, rel=0.025)
    assert np.interp(4e-3, table_30.depth_m, table_30.engaged_fraction) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("depth_mm", [0.1, 0.2, 0.45, 0.8])
def test_the_engaged_fraction_is_the_share_of_lip_length_in_bone_over_a_revolution(table_30, depth_mm):
    """∫ 2α db / (2π (R − w)/sin κ) by quadrature; measured discretisation error ≤ 2 %, allowed 2.5 %."""
    depth = depth_mm * 1e-3
    arc = integrate.quad(lambda r: 2.0 * _alpha(r, depth, BETA), W, R, limit=400)[0]
    expected = arc / (2.0 * math.pi * (R - W))
    assert np.interp(depth, table_30.depth_m, table_30.engaged_fraction) == pytest.approx(expected, rel=0.025)


def test_the_cortical_layer_ends_at_its_thickness_over_cos_beta_along_the_axis():
    """A 2 mm cortex at β 30° is 2.309 mm thick along the drill. Just above that depth every engaged point is
    still cortical (no point is deeper than the tip); 1 mm below it, past R (cot κ + tan β) = 0.88 mm, all is
    cancellous. Closed-form thrust per material at full engagement, 6 % as above."""
    tab = EngagementTable.build(GEOM, BONE, BETA, 2e-3, 5e-3)
    layer = 2e-3 / math.cos(BETA)
    lip, chisel = (R - W) / SIN, W / SIN
    for depth, m in ((layer - 0.05e-3, BONE.cortical), (layer + 1e-3, BONE.cancellous)):
        thrust = np.interp(depth, tab.depth_m, tab.edge[:, 2])
        assert thrust == pytest.approx(-N_LIPS * (m.k_fe_n_m * lip + m.k_chisel_n_m * chisel), rel=0.06), depth


def test_where_only_the_chisel_has_reached_bone_there_is_thrust_but_no_chip_term(table_30):
    """At β 30° the lips (r ≥ w = 0.135 mm) first touch at w (cot κ − tan β) = 3.17 µm of depth; above it only the
    chisel (r < w) is in bone, and it indents (docs/physics.md §1): thrust K_ch db, nothing per metre of chip."""
    first_lip = W * (COT - math.tan(BETA))
    chisel_only = (table_30.depth_m > 0.0) & (table_30.depth_m < first_lip)
    assert chisel_only.any()
    assert np.all(table_30.per_chip[chisel_only] == 0.0)
    assert np.all(table_30.edge[chisel_only, 2] < 0.0) and np.all(table_30.edge[chisel_only, :2] == 0.0)


def test_across_the_layer_boundary_the_thrust_and_torque_lie_between_the_two_materials():
    """Fully engaged with the cortical/cancellous boundary crossing the lips (2 mm cortex, tip 0.4 mm past it
    along the axis): every element is one material or the other, so thrust and torque lie strictly between the
    all-cancellous (1 mm further) and all-cortical (0.05 mm before) values."""
    tab = EngagementTable.build(GEOM, BONE, BETA, 2e-3, 5e-3)
    layer = 2e-3 / math.cos(BETA)
    for col in (2, 3):
        cortical, mixed, cancellous = (
            np.interp(d, tab.depth_m, tab.edge[:, col]) for d in (layer - 0.05e-3, layer + 0.4e-3, layer + 1e-3)
        )
        assert cortical < mixed < cancellous < 0.0, (col, cortical, mixed, cancellous)


def test_the_depth_grid_spans_first_touch_to_the_deepest_point_and_resolves_the_entry_and_the_layer():
    """docs/physics.md §1: a grid fine through the entry and through the cortical/cancellous boundary. It starts
    at first touch (less 1 µm at most) and ends at the asked depth; the entry (touch to the full-engagement
    depth, 0.884 mm at β 30°) gets a step of at most 4 µm (240 points over 0.9 mm), 0.884 mm either side of the
    layer boundary at most 8 µm (240 points over 1.8 mm), elsewhere at most 8 mm / 59."""
    tab = EngagementTable.build(GEOM, BONE, BETA, 2e-3, 8e-3)
    grid = tab.depth_m
    full = R * (COT + math.tan(BETA))
    assert -1e-6 <= grid[0] <= 0.0 and grid[-1] == 8e-3
    assert np.all(np.diff(grid) > 0.0)
    layer = 2e-3 / math.cos(BETA)
    for lo, hi, step in ((0.0, full, 4e-6), (layer - full, layer + full, 8e-6)):
        inside = grid[(grid >= lo) & (grid <= hi)]
        assert inside[0] - lo <= step and hi - inside[-1] <= step and np.diff(inside).max() <= step, (lo, hi)
    assert np.diff(grid).max() <= 8e-3 / 59 + 1e-12
    steep = EngagementTable.build(GEOM, BONE, math.radians(45), 8e-3, 8e-3).depth_m  # first touch before depth 0
    assert steep[0] == pytest.approx(R * (COT - 1.0) - 1e-6, abs=1e-12)
    near_end = EngagementTable.build(GEOM, BONE, BETA, 6.5e-3, 8e-3).depth_m  # layer at 7.5 mm, refined to 8.4 mm
    assert near_end[-1] == 8e-3 and np.diff(near_end[near_end > 7.5e-3]).max() <= 8e-6
    thin = EngagementTable.build(GEOM, BONE, BETA, 0.5e-3, 8e-3).depth_m  # layer at 0.58 mm, refined from -0.3 mm
    assert thin[0] == -1e-6 and np.diff(thin[thin < 1.4e-3]).max() <= 8e-6


# --------------------------------------------------------------------------------- the run-time interpolation


def _hand_table() -> EngagementTable:
    """Three depths 0, 1, 3 m with hand-picked rows (F_x, F_y, F_z, M_z)."""
    edge = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 3.0, 4.0], [3.0, 2.0, 1.0, 0.0]])
    per_chip = np.array([[10.0, 0.0, 0.0, 0.0], [0.0, 10.0, 0.0, 0.0], [0.0, 0.0, 10.0, 0.0]])
    return EngagementTable(np.array([0.0, 1.0, 3.0]), edge, per_chip, np.array([0.0, 0.5, 1.0]))


@pytest.mark.parametrize(
    ("depth", "chip", "row"),
    [
        (2.0, 0.5, [2.0, 4.5, 4.5, 2.0]),  # t = 1/2 between [1, 7, 3, 4] and [3, 2, 6, 0]
        (1.5, 0.0, [1.5, 2.0, 2.5, 3.0]),  # t = 1/4 between [1, 2, 3, 4] and [3, 2, 1, 0]
        (0.25, 1.0, [10.0 * 0.75 + 0.25, 0.25 * 12.0, 0.75, 1.0]),  # t = 1/4 between [10, 0, 0, 0] and [1, 12, 3, 4]
        (1.0, 2.0, [1.0, 22.0, 3.0, 4.0]),  # on a grid point: that row
        (0.0, 1.0, [10.0, 0.0, 0.0, 0.0]),  # the first depth
        (-5.0, 1.0, [10.0, 0.0, 0.0, 0.0]),  # before the grid: the first row
        (3.0, 0.1, [3.0, 2.0, 2.0, 0.0]),  # the last depth
        (9.0, 0.1, [3.0, 2.0, 2.0, 0.0]),  # past the grid: the last row
    ],
)
def test_the_wrench_interpolates_the_table_linearly_in_depth_and_adds_chip_times_the_chip_rows(depth, chip, row):
    """Hand-worked rows ``edge + chip · per_chip`` interpolated linearly, held constant beyond the ends;
    exact decimals, so 1e-12 is float slack only."""
    force, torque = ForceModel(_hand_table()).wrench(depth, chip)
    np.testing.assert_allclose(force, row[:3], rtol=1e-12, atol=1e-12)
    assert torque == pytest.approx(row[3], rel=1e-12, abs=1e-12) and type(torque) is float


def test_the_wrench_of_a_built_table_is_numpys_interpolation_of_its_rows(table_30):
    """Against ``np.interp`` (an independent implementation) at 400 random depths across and beyond the grid."""
    rng = np.random.default_rng(0)
    depths = np.concatenate([rng.uniform(-0.1e-3, 9e-3, 400), table_30.depth_m[[0, 1, 17, -2, -1]]])
    model = ForceModel(table_30)
    chip = 0.64e-6
    rows = table_30.edge + chip * table_30.per_chip
    for d in depths:
        force, torque = model.wrench(float(d), chip)
        want = [np.interp(d, table_30.depth_m, rows[:, j]) for j in range(4)]
        np.testing.assert_allclose([*force, torque], want, rtol=1e-9, atol=1e-15)
