"""The gap's location read before and after the per-specimen hardness fit (issue 45, item 2).

Hand-built terms on one stage: the specimen's response ``D(a)`` is linear in the hardness offset ``a`` (σ_k) on the
thrust ``fz_n`` and the torque ``tz_nm``, unit variances; the real episode is wrong on the torque alone. The profile's
``a`` minimises ``nb (a d_f)² + nb (g − a d_t)² + a²`` (``g``: the torque gap), a formula the test evaluates itself.
"""

import numpy as np
import pytest

from drillgym.eval.diagnosis.channels import LF_CHANNELS, STAGES
from drillgym.eval.diagnosis.context import DiagnosisData
from drillgym.eval.diagnosis.features import Features, make_blocks
from drillgym.eval.diagnosis.gap import PROFILE_GRID, EpisodeNull, gap_terms
from drillgym.eval.diagnosis.location import location_check
from drillgym.eval.diagnosis.verdict import summary

NB = 5
FZ, TZ = LF_CHANNELS.index("fz_n"), LF_CHANNELS.index("tz_nm")
STABLE = STAGES.index("stable")


def _episode(d_thrust, d_torque, torque_gap):
    blocks = make_blocks(np.full(NB * 10, STABLE))
    nf = len(LF_CHANNELS)
    sim = Features(lf=np.zeros((NB, nf)), hf=np.full((len(STAGES), 3), 0.01))
    real_lf = np.zeros((NB, nf))
    real_lf[:, TZ] = torque_gap
    real = Features(lf=real_lf, hf=sim.hf.copy())
    resp = np.zeros((PROFILE_GRID.size, NB, nf))
    resp[:, :, FZ] = PROFILE_GRID[:, None] * d_thrust
    resp[:, :, TZ] = PROFILE_GRID[:, None] * d_torque
    null = EpisodeNull(
        var=np.ones((NB, nf)),
        resp=resp,
        hf_noise=np.zeros((len(STAGES), 3)),
        hf_logvar=np.ones((len(STAGES), 3)),
        hf_sens=np.zeros((len(STAGES), 3)),
    )
    return real, sim, blocks, null


def test_the_profiled_hardness_is_the_least_squares_offset_and_the_raw_gap_keeps_the_preset_specimen():
    real, sim, blocks, null = _episode(d_thrust=1.0, d_torque=2.0, torque_gap=2.0)
    a_star = NB * 2.0 * 2.0 / (NB * (1.0 + 4.0) + 1.0)  # d/da [nb a² + nb (2 − 2a)² + a²] = 0
    fitted = gap_terms(real, sim, blocks, null)
    # the grid step is 0.25 σ_k and the cost is exactly quadratic: the parabola step lands on the minimum
    assert fitted.hardness == pytest.approx(a_star, abs=1e-9)
    assert fitted.cell_sum[STABLE, FZ] == pytest.approx(NB * a_star**2, rel=1e-9)
    assert fitted.cell_sum[STABLE, TZ] == pytest.approx(NB * (2.0 - 2.0 * a_star) ** 2, rel=1e-9)
    assert fitted.prior_sum == pytest.approx(a_star**2) and fitted.prior_n == 1.0
    raw = gap_terms(real, sim, blocks, null, profile=False)
    assert raw.hardness == 0.0 and raw.prior_sum == 0.0 and raw.prior_n == 0.0
    assert raw.cell_sum[STABLE, FZ] == 0.0 and raw.cell_sum[STABLE, TZ] == pytest.approx(NB * 4.0)


def _data(d_thrust, d_torque, torque_gap):
    real, sim, blocks, null = _episode(d_thrust, d_torque, torque_gap)
    data = DiagnosisData(episodes=[], cal=[], ho=[])
    zero = gap_terms(sim, sim, blocks, null)  # a null replay with no gap at all
    data.baseline_terms, data.null_terms = [gap_terms(real, sim, blocks, null)], [zero]
    data.raw_terms = [gap_terms(real, sim, blocks, null, profile=False)]
    data.null_raw_terms = [gap_terms(sim, sim, blocks, null, profile=False)]
    return data


def test_a_torque_gap_the_specimen_fit_moves_to_the_thrust_is_reported_at_both():
    """d_t = 2 d_f: after the fit the thrust holds nb a*² = 2.96 against the torque's 1.07 (the formula above)."""
    check = location_check(_data(d_thrust=1.0, d_torque=2.0, torque_gap=2.0))
    assert check["raw"][0]["channel"] == "tz_nm" and check["raw"][0]["share"] == pytest.approx(1.0)
    assert check["after_specimen_fit"][0]["channel"] == "fz_n"
    assert not check["agree"] and "tz_nm, stable (100 %)" in check["note"] and "fz_n, stable" in check["note"]
    location = {"channel": "fz_n", "stage": "stable", "share": check["after_specimen_fit"][0]["share"]}
    line = summary("unexplained", None, location, [], [], None, check["raw"][0])
    assert line == "unexplained — located at fz_n, stable (before the per-specimen hardness fit: tz_nm, stable)"


def test_a_torque_gap_the_specimen_barely_moves_stays_at_the_torque_and_the_summary_says_nothing_more():
    """d_t = d_f / 4: the fit takes little of the gap (a* = nb g d_t / (nb (d_f² + d_t²) + 1) ≈ 0.43) and leaves
    the torque on top."""
    check = location_check(_data(d_thrust=1.0, d_torque=0.25, torque_gap=2.0))
    assert check["after_specimen_fit"][0]["channel"] == "tz_nm" == check["raw"][0]["channel"]
    assert check["agree"] and check["note"] is None
    location = {"channel": "tz_nm", "stage": "stable", "share": 1.0}
    assert (
        summary("unexplained", None, location, [], [], None, check["raw"][0])
        == "unexplained — located at tz_nm, stable"
    )
