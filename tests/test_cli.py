import json

from eval.cli import COMMANDS, main


def test_help_lists_every_command(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


def test_unknown_command_is_an_error_naming_it(capsys):
    try:
        main(["drill-faster"])
    except SystemExit as e:
        assert e.code == 2
    assert "drill-faster" in capsys.readouterr().err


def test_bench_speed_json_reports_a_real_time_factor(capsys):
    assert main(["bench-speed", "--runs", "1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["real_time_factor_median"] > 0
    assert result["episode_sim_s"] > 10
    assert result["peak_rss_mib"] > 0


def test_demo_writes_metrics_and_a_plot(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--seeds", "2"]) == 0
    out = capsys.readouterr().out
    assert "deviation_mean_mm" in out and str(tmp_path) in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["deviation_mean_mm"]["paper"] == 0.703
    assert (tmp_path / "paper_uncompensated.png").stat().st_size > 10_000
    assert len((tmp_path / "paper_uncompensated.csv").read_text().splitlines()) == 3
