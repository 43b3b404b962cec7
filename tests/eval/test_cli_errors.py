"""Every ``drillgym`` command answers bad input with one line, ``drillgym CMD: error: ...``, and exit 2."""

import pytest

from drillgym.envs.errors import UserError
from drillgym.envs.real.emulator.process import free_loopback_host
from drillgym.eval.cli import COMMANDS, main

NO_ROBOT = free_loopback_host()
"""A loopback address whose UR and F/T ports are all free: nothing, a URSim on this machine included, answers there,
so a test that connects is refused by the network stack, and one that must fail before connecting cannot reach a
robot if it does not."""

BAD_INPUT = {
    "demo": ["--seeds", "0"],
    "identify-stiffness": ["--poses", "9"],
    "bench-speed": ["--runs", "0"],
    "reproduce": ["--seeds", "1"],
    "calibrate": ["--seeds", "0"],
    "explain-paper": ["--candidates", "no_such_candidate"],
    "tune-entry": ["--suites", "papr"],
    "tune-table": ["--seeds", "1"],
    "train": ["--config", "no_such_config.yaml"],
    "bench": ["--suite", "nope"],
    "run": ["--robot", NO_ROBOT, "--scenario", "beta_deg=99", "--dry-run"],
    "emulate": ["--scenario", "beta_deg=99"],
    "bench-rtde": ["--seconds", "-1"],
    "ft-check": ["--ft", NO_ROBOT, "--mass-kg", "-0.5"],
    "diagnose": ["--real", "no_such_folder"],
    "separate": ["--diagnosis", "no_such_folder", "--real", "no_such_folder"],
    "make-reality": ["--effects", "no_such_effect"],
    "bench-diagnosis": ["--only", "no_such_case"],
    "import-rtde": ["no_such_session"],
    "validate-forces": ["--studies", "no_such_study"],
}
"""One bad input per command, each caught before any long work starts."""


def _run(argv):
    try:
        return main(argv)
    except SystemExit as e:  # argparse's own errors
        return e.code


def test_every_command_has_a_bad_input_case():
    assert set(BAD_INPUT) == set(COMMANDS)


@pytest.mark.parametrize("command", sorted(BAD_INPUT))
def test_bad_input_is_one_line_and_exit_2(command, tmp_path, capsys):
    code = _run(
        [command, *BAD_INPUT[command], "--out", str(tmp_path / "out")]
        if command != "emulate"
        else [command, *BAD_INPUT[command]]
    )
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith(f"drillgym {command}: error: "), err
    assert "Traceback" not in err


def test_an_unknown_option_names_the_help(capsys):
    assert _run(["bench", "--no-such-option"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "drillgym bench: error: unrecognized arguments: --no-such-option (see drillgym bench --help)"


def test_version_and_defaults_in_help(capsys):
    assert _run(["--version"]) == 0
    assert capsys.readouterr().out.startswith("drillgym ")
    assert _run(["identify-stiffness", "--help"]) == 0
    assert "tracker noise per axis (mm) (default: 0.05)" in capsys.readouterr().out  # added where help is silent


def test_a_user_error_deep_in_a_command_shows_its_traceback_on_request(tmp_path, monkeypatch):
    monkeypatch.setenv("DRILLGYM_TRACEBACK", "1")
    with pytest.raises(ValueError, match="must be >= 2"):
        main(["reproduce", "--seeds", "1", "--out", str(tmp_path)])


@pytest.mark.parametrize(
    "argv",
    [
        ["make-reality", "--effects", "no_such_effect"],
        ["import-rtde", "no_such_session"],
        ["run", "--robot", NO_ROBOT, "--yes"],  # nothing listens on this loopback address's UR ports
    ],
)
def test_a_failed_command_leaves_no_output_folder(argv, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run([*argv, "--out", str(out)]) == 2
    assert not out.exists(), sorted(p.name for p in out.iterdir())


def test_a_plain_value_error_in_a_command_is_a_bug_and_keeps_its_traceback(monkeypatch):
    """Only ``UserError`` (and OSError, a missing optional package) is the user's: a ``ValueError`` raised by the
    project's own code, like NumPy's on a shape mismatch, propagates out of ``main`` instead of printing as bad input."""
    import drillgym.eval.cli.bench_speed as command

    def broken(args):
        raise ValueError("operands could not be broadcast together with shapes (3,) (4,)")

    monkeypatch.setattr(command, "run", broken)
    with pytest.raises(ValueError, match="broadcast"):
        main(["bench-speed"])


def test_a_user_error_raised_inside_a_command_is_one_line_and_exit_2(monkeypatch, capsys):
    import drillgym.eval.cli.bench_speed as command

    def refuses(args):
        raise UserError("--runs=0 must be >= 1")

    monkeypatch.setattr(command, "run", refuses)
    assert main(["bench-speed"]) == 2
    assert capsys.readouterr().err == "drillgym bench-speed: error: --runs=0 must be >= 1\n"


@pytest.mark.parametrize(
    ("command", "file_name", "text", "option"),
    [
        ("train", "bad.yaml", "algo: [sac\n", "--config"),
        ("reproduce", "explanation.json", '{"chosen": ', "--explanation"),
    ],
    ids=["yaml", "json"],
)
def test_a_malformed_input_file_is_one_line_naming_it_and_exit_2(command, file_name, text, option, tmp_path, capsys):
    path = tmp_path / file_name
    path.write_text(text)
    code = _run([command, option, str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"drillgym {command}: error: {path}: not valid ") and err.count("\n") == 1, err


def test_emulate_names_a_scenario_that_is_not_json():
    from drillgym.envs.real.emulator.cli import parse_scenario

    with pytest.raises(UserError, match="not valid JSON"):
        parse_scenario('{"beta_deg": ')


@pytest.mark.parametrize(
    ("command", "record", "argv"),
    [
        ("explain-paper", "explanation.json", ["--quick", "--folds", "kp4"]),
        ("calibrate", "calibration.md", ["--seeds", "1"]),
        ("tune-entry", "best.json", ["--seeds", "1", "--scales", "0.5", "--depths-mm", "1"]),
    ],
)
def test_a_previous_record_in_out_is_refused_before_any_work_unless_overwrite(
    tmp_path, capsys, monkeypatch, command, record, argv
):
    (tmp_path / record).write_text("a previous run's\n")
    assert main([command, *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "holds a previous" in err and record in err and "--overwrite" in err
    assert (tmp_path / record).read_text() == "a previous run's\n"  # nothing written, nothing run
    (tmp_path / "file").write_text("")
    assert main([command, *argv, "--out", str(tmp_path / "file")]) == 2
    assert "is not a folder" in capsys.readouterr().err
