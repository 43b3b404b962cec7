"""A second effect hidden behind a larger first one: credited where only its physics reaches; joint refit."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from diagnosis_stubs import stub_score

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, GROUP_OF, STAGES
from drillgym.eval.diagnosis.fit import READ_START_STEP, fit_model, local_search, refit_jointly, settle_from_reading
from drillgym.eval.diagnosis.gap import Terms
from drillgym.eval.diagnosis.pairs import (
    own_cells,
    pair_beats,
    second_contradicted,
    second_effect_evidence,
    second_on_own_cells,
)
from drillgym.eval.diagnosis.rank import ModelScore

EPISODES = 8
Q = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "q"]
FORCE = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "force"]
STABLE = STAGES.index("stable")


def _terms(extra: dict[tuple[int, int], float], rng: np.random.Generator) -> list[Terms]:
    """Per-episode terms: 1 per sample everywhere (the sim's own level) plus ``extra`` per sample in cells."""
    out = []
    for _ in range(EPISODES):
        n = np.full((len(STAGES), len(ALL_CHANNELS)), 10.0)
        s = n * rng.uniform(0.9, 1.1, n.shape)
        for (stage, c), v in extra.items():
            s[stage, c] += 10.0 * v * rng.uniform(0.8, 1.2)
        out.append(Terms(s, n, np.zeros_like(s)))
    return out


def _score(names: tuple[str, ...], terms: list[Terms], before: float, null_gap: float) -> ModelScore:
    j = np.array([t.j for t in terms])
    idx = np.random.default_rng(7).integers(0, EPISODES, size=(1000, EPISODES))
    return stub_score(names, before, j.sum() / sum(t.n for t in terms), null_gap, j[idx].sum(1), terms)


def test_own_cells_follow_the_declared_physics():
    skid_then_friction = own_cells("skid_friction", "joint_friction")
    assert skid_then_friction is not None
    assert skid_then_friction[:, Q].all()  # no bone effect moves the joint angles
    assert not skid_then_friction[STABLE, FORCE].any()  # both act on the force in the cut
    length_then_offset = own_cells("tool_length", "kinematic_offset")
    assert length_then_offset is not None
    tracker = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "tracker"]
    assert length_then_offset.sum() == len(tracker) and length_then_offset[0, tracker].all()  # tracker, approach
    for patch in (("density_gradient", "thermal_softening"), ("kinematic_offset", "tool_length")):
        mask = own_cells(*patch)
        assert mask is not None and not mask.any()
    assert own_cells("a", "b") is None


def test_a_hidden_second_effect_is_named_where_only_it_reaches():
    rng = np.random.default_rng(0)
    null = _terms({}, rng)
    big = {(STABLE, c): 200.0 for c in FORCE}  # the first effect's gap, mostly force
    hidden = {(s, c): 3.0 for s in range(len(STAGES)) for c in Q}  # the second's, on the joint angles
    before_terms = _terms({**big, **hidden}, rng)
    g0 = sum(t.j for t in null) / sum(t.n for t in null)
    before = sum(t.j for t in before_terms) / sum(t.n for t in before_terms)
    first = _score(("skid_friction",), _terms({(STABLE, c): 2.0 for c in FORCE} | hidden, rng), before, g0)
    # alone the friction model removes nothing (the fit alone is spoilt by the big gap it cannot touch)
    alone = _score(("joint_friction",), before_terms, before, g0)
    pair = _score(("skid_friction", "joint_friction"), _terms({(STABLE, c): 2.0 for c in FORCE}, rng), before, g0)
    assert second_on_own_cells(pair, first, null)
    assert pair_beats(pair, first, first, alone, g0, null)
    assert not pair_beats(pair, first, first, alone, g0)  # without the cells: "little alone"
    evidence = second_effect_evidence(pair, first, alone, null)
    assert evidence["second"] == "joint_friction" and evidence["own_cells"] and not evidence["alone"]
    assert evidence["own_groups"] == ["q", "tracker"]  # q throughout, the tracker before contact
    assert evidence["own_gap_first"] > evidence["own_gap_pair"] >= 0.9 * evidence["own_gap_null"]
    # a patch on the first effect's form removes the same share, but on cells the first reaches too
    patch = _score(("skid_friction", "density_gradient"), _terms(hidden, rng), before, g0)
    patch_alone = _score(("density_gradient",), before_terms, before, g0)
    assert not second_on_own_cells(patch, first, null)
    assert not pair_beats(patch, first, first, patch_alone, g0, null)


def test_no_credit_where_the_first_effect_leaves_no_gap():
    rng = np.random.default_rng(1)
    null = _terms({}, rng)
    before_terms = _terms({(STABLE, c): 200.0 for c in FORCE}, rng)
    g0 = sum(t.j for t in null) / sum(t.n for t in null)
    before = sum(t.j for t in before_terms) / sum(t.n for t in before_terms)
    first = _score(("skid_friction",), _terms({(STABLE, c): 2.0 for c in FORCE}, rng), before, g0)
    pair = _score(("skid_friction", "joint_friction"), _terms({}, rng), before, g0)
    assert not second_on_own_cells(pair, first, null)  # the joint angles were already at the sim's level


def test_a_second_effect_that_explains_alone_but_worsens_where_only_it_acts_is_not_named():
    # An F/T drift fitted on top of a density model bends the force along the hole, and on its own it
    # explains part of the density's gap (a drift in time looks like a gradient in depth), but it also
    # predicts a drift before contact that the data do not show.
    rng = np.random.default_rng(2)
    null = _terms({}, rng)
    approach = STAGES.index("approach")
    fz = ALL_CHANNELS.index("fz_n")
    before_terms = _terms({(STABLE, c): 20.0 for c in FORCE}, rng)
    g0 = sum(t.j for t in null) / sum(t.n for t in null)
    before = sum(t.j for t in before_terms) / sum(t.n for t in before_terms)
    first = _score(("density_gradient",), _terms({(STABLE, c): 4.0 for c in FORCE}, rng), before, g0)
    drift_alone = _score(("ft_drift",), _terms({(STABLE, c): 12.0 for c in FORCE}, rng), before, g0)
    pair = _score(("density_gradient", "ft_drift"), _terms({(approach, fz): 2.0}, rng), before, g0)
    assert second_contradicted(pair, first, null)
    assert pair_beats(pair, first, first, drift_alone, g0)  # judged on the totals alone it would pass
    assert not pair_beats(pair, first, first, drift_alone, g0, null)
    honest = _score(("density_gradient", "ft_drift"), _terms({}, rng), before, g0)
    assert not second_contradicted(honest, first, null)
    assert pair_beats(honest, first, first, drift_alone, g0, null)


class _QuadraticEvaluator:
    """A stand-in evaluator: the misfit of a tool length and a kinematic offset that are partly confounded.

    Both move the tip along base z at the bench's poses; only the offset moves the marker. The forward fit
    lets the length absorb the offset's share, the joint fit separates them.
    """

    def __init__(self) -> None:
        self.data = SimpleNamespace(cal=[0], ho=[1], null_terms=[_flat(1.0), _flat(1.0)])
        self.replays = 0

    def mean_term(self, spec, indices) -> float:
        p = {name: dict(values) for name, values in spec}
        dl = p.get("tool_length", {}).get("dl_m", 0.0)
        dz = p.get("kinematic_offset", {}).get("dz_base_m", 0.0)
        self.replays += 1
        return 1.0 + 1e8 * ((dl + dz) - 0.0015) ** 2 + 1e8 * (dz + 0.0005) ** 2

    def terms(self, spec, indices, profile=True):
        return [_flat(self.mean_term(spec, indices))]

    def terms_each(self, spec, indices, profiles=(True, False)):
        return tuple(self.terms(spec, indices) for _ in profiles)


def _flat(level: float) -> Terms:
    shape = (len(STAGES), len(ALL_CHANNELS))
    return Terms(np.full(shape, level), np.ones(shape), np.zeros(shape))


def test_joint_refit_separates_what_forward_selection_confounds(monkeypatch):
    monkeypatch.setattr("drillgym.eval.diagnosis.fit._guess", lambda ev, names: None)  # no tracker data here
    ev = _QuadraticEvaluator()
    first = fit_model(ev, ("tool_length",))
    assert not first.error and abs(first.params[0]["dl_m"] - 0.0015) < 2e-4  # absorbs the offset's share
    forward = fit_model(ev, ("tool_length", "kinematic_offset"), [first.params[0], {}])
    joint = refit_jointly(ev, ("tool_length", "kinematic_offset"), [forward.params])
    assert not forward.error and not joint.error and joint.cal_objective < 0.5 * forward.cal_objective
    assert abs(joint.params[0]["dl_m"] - 0.002) < abs(forward.params[0]["dl_m"] - 0.002)
    assert joint.n_params == 4 and joint.ho_terms


class _RuggedEvaluator(_QuadraticEvaluator):
    """The misfit of a kinematic offset along base y: a narrow true valley beside a broad, shallower one.

    The true valley (bottom 1.0 at −0.45 mm, 0.1 mm wide) is where the tracker's reading points (−0.40 mm);
    outside it the misfit falls gently towards a broad valley at −1 mm (1.02). The tool length only adds a small
    bowl about 0.
    """

    def mean_term(self, spec, indices) -> float:
        p = {name: dict(values) for name, values in spec}
        dl_mm = 1e3 * p.get("tool_length", {}).get("dl_m", 0.0)
        dy_mm = 1e3 * p.get("kinematic_offset", {}).get("dy_base_m", 0.0)
        self.replays += 1
        well = 1.0 + 20.0 * (dy_mm + 0.45) ** 2 if abs(dy_mm + 0.45) < 0.1 else 1.02 + 0.01 * abs(dy_mm + 1.0)
        return well + 1e-3 * dl_mm**2


def _read_offset(ev, names):
    """The tracker's reading of the offset: 0.05 mm from the truth, inside its valley."""
    if list(names) == ["kinematic_offset"]:
        return [{"dx_base_m": 0.0, "dy_base_m": -4.0e-4, "dz_base_m": 0.0}]
    return None


def test_a_joint_refit_searches_from_the_datas_reading_in_fine_steps_and_stays_in_its_valley(monkeypatch):
    monkeypatch.setattr("drillgym.eval.diagnosis.fit._guess", _read_offset)
    names = ("tool_length", "kinematic_offset")
    start = [[{"dl_m": 0.0}, {"dx_base_m": 0.0, "dy_base_m": 0.0, "dz_base_m": 0.0}]]
    joint = refit_jointly(_RuggedEvaluator(), names, start)
    assert not joint.error
    assert abs(joint.params[1]["dy_base_m"] + 4.5e-4) < 3e-5 and joint.cal_objective < 1.005
    # A first step as coarse as a search from a grid point (a quarter of a mm here) leaves the reading's valley.
    monkeypatch.setattr("drillgym.eval.diagnosis.fit.READ_START_STEP", 1 / 16)
    coarse = refit_jointly(_RuggedEvaluator(), names, start)
    assert abs(coarse.params[1]["dy_base_m"] + 4.5e-4) > 1e-4 and coarse.cal_objective > 1.01


def _coupled_misfit(u: np.ndarray) -> float:
    """Sharp along z (a contact's timing), which a shift along y can half make up for; a little cost on y's shift.

    The answer is (0.5, 0.5, 0.5); along y alone the misfit falls until y = 0.3, where it stays above the answer's.
    """
    z_eff = u[2] + 0.05 * (u[1] - 0.5)
    return 100.0 * (z_eff - 0.5) ** 2 + 0.001 * abs(u[1] - 0.5) + 0.001 * abs(u[0] - 0.5)


def test_a_search_from_a_reading_takes_the_best_move_and_does_not_trade_the_sharp_parameter_for_a_shallow_one():
    reading = np.array([0.5, 0.5, 0.51])  # 0.01 off along the sharp parameter
    settled = settle_from_reading(_coupled_misfit, reading, 42)
    assert abs(settled[2] - 0.5) < 3e-3 and abs(settled[1] - 0.5) < 0.05 and _coupled_misfit(settled) < 5e-5
    # Moves taken as they are tried, in parameter order: y is followed out of the valley before z is tried.
    in_order = local_search(_coupled_misfit, reading, 42, initial_step=READ_START_STEP)
    assert in_order[2] == 0.51 and abs(in_order[1] - 0.5) > 0.1 and _coupled_misfit(in_order) > 1e-4
