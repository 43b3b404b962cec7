import json

from drillgym.eval.cli import main


def test_reproduce_quick_writes_report_rows_and_figures(tmp_path, capsys):
    assert main(["reproduce", "--out", str(tmp_path), "--quick"]) == 0
    rows = json.loads((tmp_path / "reproduction.json").read_text())
    names = [r["name"] for r in rows]
    for key in (
        "mean tip deviation, uncompensated",
        "mean tip deviation, li2023 KP = 4",
        "max lateral force, li2023 KP = 4",
        "entry-hole centre offset, li2023 KP = 4",
        "robot-stiffness deflection: max |error| at 3 poses (Table 1)",
    ):
        assert key in names
    for r in rows:
        assert set(r) >= {"name", "unit", "paper", "sim", "rel_err"}
        if r["paper"]:
            assert abs(r["rel_err"] - (r["sim"] - r["paper"]) / r["paper"]) < 1e-9
    kinds = {r["kind"] for r in rows}
    assert (
        {"calibration", "prediction", "check"} <= kinds <= {"calibration", "prediction", "check", "baseline", "learned"}
    )
    assert "mean tip deviation, li2023_tuned (best classical baseline)" in names
    report = (tmp_path / "report.md").read_text()
    assert "## Calibration" in report and "prediction" in report
    for png in (
        "fig9_force_stages.png",
        "fig12_deviation_vs_kp.png",
        "fig13_force_compensation.png",
        "fig14_entry_hole.png",
    ):
        assert (tmp_path / png).stat().st_size > 10_000
        assert png in report
    assert "Report:" in capsys.readouterr().out


def test_terminal_table_keeps_every_name_and_unit_whole(capsys):
    from drillgym.eval.cli.reproduce import Row
    from drillgym.eval.reproduce.report import headline

    long_name = "mean tip deviation, li2023_tuned (best classical baseline)"
    rows = [
        Row(long_name, "mm", None, 0.05, "baseline", None),
        Row("identified K_theta1", "kN m/rad", 25.3, 25.0, "check"),
    ]
    lines = headline(rows).splitlines()
    assert lines[1].startswith(long_name + " ")
    assert "kN m/rad" in lines[2]
    assert lines[1].index(" mm ") + len(" mm") == lines[2].index("kN m/rad") + len("kN m/rad")  # one unit column
