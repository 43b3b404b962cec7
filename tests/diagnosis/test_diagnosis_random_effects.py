"""Random effects: a candidate fitted per episode around a shared mean, with a penalty that counts them."""

from __future__ import annotations

import numpy as np
import pytest

from drillgym.eval.diagnosis.bench.cases import Case
from drillgym.eval.diagnosis.bench.run import episode_checks, score_case, summarise
from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, diagnose
from drillgym.eval.diagnosis.episodes import load_episodes
from drillgym.eval.diagnosis.gap import Terms
from drillgym.eval.diagnosis.random_effects import _mean_spread, _shrunk_fit
from drillgym.eval.diagnosis.reality.generate import make_reality


def test_the_spread_is_the_scatter_of_the_estimates_beyond_their_own_uncertainty():
    rng = np.random.default_rng(0)
    n, tau, se = 4000, 0.05, 0.03
    theta = 0.4 + tau * rng.standard_normal((n, 1)) + se * rng.standard_normal((n, 1))
    curv = np.full((n, 1), 2.0 / se**2)  # J is -2 log-likelihood: variance = 2 / curvature
    mu, tau2 = _mean_spread(theta, curv)
    assert mu[0] == pytest.approx(0.4, abs=3 * 0.06 / np.sqrt(n))
    assert np.sqrt(tau2[0]) == pytest.approx(tau, rel=0.05)
    # No spread beyond the estimates' own noise: none is reported.
    _, tau2_none = _mean_spread(0.4 + se * rng.standard_normal((n, 1)), curv)
    assert np.sqrt(tau2_none[0]) < 0.01


def _quadratic_terms(c: float, a: float):
    """Terms whose J is ``c (u - a)² + 1``."""

    def terms(u: np.ndarray) -> Terms:
        t = Terms.zeros()
        t.cell_sum[0, 0] = c * (u[0] - a) ** 2 + 1.0
        t.cell_n[0, 0] = 1.0
        return t

    return terms


def test_an_episodes_parameter_is_shrunk_toward_the_mean_and_counted_by_its_degrees_of_freedom():
    c, a, mu, tau2 = 400.0, 0.7, 0.5, 0.01  # data curvature 2c = 800, prior precision (J units) 2 / tau2 = 200
    u, t, dof = _shrunk_fit(_quadratic_terms(c, a), np.array([a]), np.array([2 * c]), np.array([mu]), np.array([tau2]))
    expected = (c * a + mu / tau2) / (c + 1 / tau2)  # minimum of c (u - a)² + (u - mu)² / tau2
    assert u[0] == pytest.approx(expected, abs=2e-3)
    assert dof == pytest.approx(c / (c + 1 / tau2))  # ridge degrees of freedom: 0.8
    assert t.prior_sum == pytest.approx((u[0] - mu) ** 2 / tau2) and t.prior_n == 1.0
    # With no spread the parameter is held at the mean and counts nothing.
    u0, _, dof0 = _shrunk_fit(_quadratic_terms(c, a), np.array([a]), np.array([2 * c]), np.array([mu]), np.zeros(1))
    assert u0[0] == mu and dof0 == 0.0


@pytest.fixture(scope="module")
def episode_drift(tmp_path_factory):
    out = tmp_path_factory.mktemp("episode-drift")
    truth = make_reality("episode_warmup:spread_n=4", 12, 11, out / "logs")
    eps, skipped = load_episodes(out / "logs")
    assert not skipped
    res = diagnose(eps, DiagnoseOptions(workers=1, candidates=("ft_drift", "ft_episode_drift"), progress=False))
    return truth, res


def test_a_drift_whose_sign_differs_per_episode_is_named_as_one_with_each_episodes_rate(episode_drift):
    truth, res = episode_drift
    assert res["verdict"] == "explained" and res["named"] == ["ft_episode_drift"]
    by_name = {e["name"]: e for e in res["effects"]}
    assert by_name["ft_drift"]["shrink"] < 0.5  # one rate for all episodes averages the signs away
    named = by_name["ft_episode_drift"]
    assert named["shrink"] >= 0.9 and named["penalty_params"] > named["n_params"] == 6
    spread = named["param_intervals"]["ft_episode_drift"]
    assert all(not spread[f"f{a}_rate_n_s_spread"]["contains_off"] for a in "xyz")
    assert res["per_episode"] == named["per_episode"] and len(res["per_episode"]["episodes"]) == 12
    checks = episode_checks(res, truth["episodes"])
    assert [c["param"] for c in checks] == ["fx_rate_n_s", "fy_rate_n_s", "fz_rate_n_s"]
    for c in checks:  # each episode's rate, found to a small part of their spread
        assert c["n"] == 12 and c["rms_error"] < 0.2 * c["truth_spread"] and c["correlation"] > 0.95


def test_the_benchmark_counts_a_per_episode_drift_as_the_drift_it_is():
    res = {
        "verdict": "explained",
        "named": ["ft_episode_drift"],
        "location": None,
        "effects": [{"name": "ft_episode_drift", "effects": ["ft_episode_drift"], "shrink": 0.9}],
        "significance": {"gap": 3.0, "null": 0.5},
        "timing": {"total_s": 1.0},
    }
    shared = score_case(Case("w", "single", "ft_warmup:fz_n=1", 0), res)
    assert shared["correct"] and shared["top1_ranked"] and shared["per_episode_named"]
    wrong = score_case(Case("l", "single", "jittered_latency:mean_s=0.05", 0), res)
    assert not wrong["correct"]
    summary = summarise([shared, wrong])["figures"]
    assert summary["wrong_effect_named_rate"] == 0.5  # the drift is wrong for the latency only


def test_the_report_lists_each_episodes_own_parameters_and_the_spread(episode_drift):
    from drillgym.eval.diagnosis.report import per_episode_lines

    _, res = episode_drift
    text = "\n".join(per_episode_lines(res))
    assert "`ft_episode_drift` differs per episode" in text and "fx_rate_n_s_spread" not in text
    rows = [line for line in text.splitlines() if line.startswith("| episode_")]
    assert len(rows) == 12 and all(line.count("|") == 7 for line in rows)  # half, hardness and three rates
    fz = res["per_episode"]["episodes"]["episode_000"]["fz_rate_n_s"]
    assert any(line.startswith("| episode_000 |") and f"{fz:.3g}" in line for line in rows)
