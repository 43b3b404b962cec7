"""A diagnosis is a record: ``drillgym diagnose`` refuses an ``--out`` that holds one (issue 43, item 1).

A first diagnosis is hashed; a second one into the same ``--out`` is refused with one line and exit 2, and no file
of the first changes. Each file a diagnosis writes is enough to refuse, before any log is read.
"""

from __future__ import annotations

import hashlib

import pytest
from file_hashes import hashes

from drillgym.eval.cli import main
from drillgym.eval.cli.diagnose import RECORD_FILES
from drillgym.eval.diagnosis.reality.generate import make_reality


def refused(argv, capsys):
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("drillgym diagnose: error: ") and "holds a previous diagnosis" in lines[0], err
    return lines[0]


def test_no_file_of_a_first_diagnosis_changes_when_a_second_targets_its_out(tmp_path, capsys):
    make_reality("none", 4, 3, tmp_path / "logs")
    out = tmp_path / "diagnosis"
    argv = ["diagnose", "--real", str(tmp_path / "logs"), "--out", str(out), "--workers", "1", "--no-progress"]
    argv += ["--candidates", "ft_drift"]
    assert main([*argv, "--no-figures"]) == 0
    capsys.readouterr()
    before = hashes(out)
    assert {"diagnosis.json", "report.md"} <= set(before)
    for again in ([*argv, "--no-figures"], argv, [*argv, "--seed", "7"]):
        line = refused(again, capsys)
        assert "diagnosis.json" in line and "report.md" in line and "pass another --out" in line
    assert hashes(out) == before


@pytest.mark.parametrize("record", RECORD_FILES)
def test_any_file_of_a_diagnosis_refuses_its_out_before_any_log_is_read(tmp_path, capsys, record):
    """``--real`` does not exist: a check after reading the logs would complain about that instead."""
    out = tmp_path / "out"
    out.mkdir()
    (out / record).write_text("a record\n")
    line = refused(["diagnose", "--real", str(tmp_path / "no_such_folder"), "--out", str(out)], capsys)
    assert record in line and "no_such_folder" not in line
    assert hashes(out) == {record: hashlib.sha256(b"a record\n").hexdigest()}
