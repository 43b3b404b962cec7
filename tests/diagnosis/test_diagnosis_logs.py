"""Reading logs for the diagnosis: checks, documented repairs, stages, and the sim_ columns never used."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_diagnosis_helpers import sim_log

from drillgym.eval.diagnosis.channels import STAGES
from drillgym.eval.diagnosis.episodes import episode_from_log, load_episodes
from drillgym.eval.diagnosis.stages import stage_labels
from drillgym.eval.diagnosis.validate import MAX_REPAIR_SAMPLES, LogCheckError, check_log


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    d = tmp_path_factory.mktemp("logs")
    header, df = sim_log(d / "ep.parquet", controller="none", seed=2)
    return d, header, df


def test_a_sim_log_becomes_an_episode_without_its_sim_columns(log):
    _, header, df = log
    ep = episode_from_log("ep", header, df)
    assert ep.n == len(df) and ep.actions.shape == (df["step"].iloc[-1] + 1, 4)
    assert ep.repairs == []
    # The diagnosis's channels never include privileged state: scrambling sim_* changes nothing.
    scrambled = df.copy()
    for c in [c for c in df.columns if c.startswith("sim_")]:
        scrambled[c] = np.random.default_rng(0).permutation(df[c].to_numpy())
    np.testing.assert_array_equal(episode_from_log("ep", header, scrambled).lf, ep.lf)
    np.testing.assert_array_equal(
        episode_from_log("ep", header, df.drop(columns=[c for c in df if c.startswith("sim_")])).lf, ep.lf
    )


def test_stage_estimate_from_the_commanded_depth_follows_lis_stages(log):
    _, header, df = log
    sc = header["scenario"]
    stage = stage_labels(df["depth_cmd_m"], df["phase"], sc["beta_deg"], sc["drill_diameter_mm"])
    seen = [int(s) for i, s in enumerate(stage) if i == 0 or s != stage[i - 1]]
    assert seen == [0, 1, 2, 3, 4, 5]
    # The true tip lags the command (it skids downhill and the arm gives): the simulator's own
    # (privileged) stage never runs ahead of the estimate.
    true = df["sim_stage"].to_numpy()
    touching = (df["phase"].to_numpy() == 1) & (true > 0)
    assert np.all(true[touching] <= stage[touching])
    assert STAGES[stage[-1]] == "retract"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda df: df.drop(columns=["q3_rad"]), "missing column"),
        (lambda df: df.drop(index=range(40, 43)).reset_index(drop=True), "time gap"),
        (lambda df: df.assign(t_s=df["t_s"] * 1000), "in ms"),
        (lambda df: df.assign(ft_fz_n=df["ft_fz_n"] * 1000), "mN"),
        (lambda df: df.assign(q1_rad=np.degrees(df["q1_rad"])), "degrees"),
        (lambda df: df.assign(tcp_x_base_m=df["tcp_x_base_m"] * 1000), "mm"),
        (lambda df: _nan(df, "ft_fx_n", 50, MAX_REPAIR_SAMPLES + 1), "consecutive NaN"),
        (lambda df: df.assign(cmd_dx_base_m=np.arange(len(df)) * 1e-6), "changes inside agent step"),
    ],
)
def test_bad_logs_raise_a_clear_error(log, edit, message):
    _, header, df = log
    with pytest.raises(LogCheckError, match=message):
        check_log("ep", header, edit(df.copy()))


def test_short_nan_runs_are_repaired_by_interpolation_and_reported(log):
    _, header, df = log
    bad = _nan(df.copy(), "ft_fy_n", 80, MAX_REPAIR_SAMPLES)
    fixed, repairs = check_log("ep", header, bad)
    assert repairs == [
        f"ft_fy_n: {MAX_REPAIR_SAMPLES} NaN sample(s) in 1 run(s) of <= {MAX_REPAIR_SAMPLES} interpolated"
    ]
    assert np.isfinite(fixed["ft_fy_n"]).all()
    a, b = df["ft_fy_n"].iloc[79], df["ft_fy_n"].iloc[80 + MAX_REPAIR_SAMPLES]
    assert min(a, b) - 1e-12 <= fixed["ft_fy_n"].iloc[81] <= max(a, b) + 1e-12


def test_tracker_dropouts_are_left_out_not_repaired(log):
    _, header, df = log
    d = df.copy()
    d.loc[100:140, ["tracker_x_base_m", "tracker_y_base_m", "tracker_z_base_m"]] = np.nan
    d.loc[100:140, "tracker_valid"] = False
    ep = episode_from_log("ep", header, d)
    assert np.isnan(ep.lf[100:141, 6:9]).all() and ep.repairs == []


def test_a_folder_with_a_bad_log_skips_it_with_the_reason(log, tmp_path):
    d, _, _ = log
    (tmp_path / "good.parquet").write_bytes((d / "ep.parquet").read_bytes())
    (tmp_path / "broken.parquet").write_bytes(b"not parquet")
    episodes, skipped = load_episodes(tmp_path)
    assert [e.name for e in episodes] == ["good"]
    assert len(skipped) == 1 and skipped[0].startswith("broken.parquet")
    with pytest.raises(Exception, match="broken"):
        load_episodes(tmp_path, strict=True)


def _nan(df: pd.DataFrame, col: str, start: int, n: int) -> pd.DataFrame:
    df.loc[start : start + n - 1, col] = np.nan
    return df
