"""A run's record is append-only: ``drillgym run`` refuses an ``--out`` that holds one (issue 43, item 1).

On the emulator: a first run's files are hashed, second runs into the same ``--out`` (the same command, a dry run,
a plan) are refused with one line and exit 2, and every file of the first run is unchanged, nothing added, nothing
sent to the robot. Without one: each kind of record file alone is enough to refuse, before any connection; an
empty ``--out``, or one holding something else, is not a record.
"""

from __future__ import annotations

import json

import pytest
from file_hashes import hashes
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.envs.real.emulator.process import free_loopback_host
from drillgym.eval.cli import main

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)

SHORT_PLAN = "feed_mm_s=3,depth_mm=3"
"""A 3 s hole (approach 1.4 s, feed 1.1 s, retract 0.6 s)."""
NO_ROBOT = free_loopback_host()
"""A loopback address nothing listens on: a run that got past the check would fail to connect, not be refused."""


def refused(argv, capsys):
    """Run ``argv``; assert exit 2 and one line on stderr saying the folder holds a previous run's record."""
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("drillgym run: error: ") and "holds a previous run's record" in lines[0], err
    assert "pass another --out" in lines[0]
    return lines[0]


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_no_file_of_a_first_run_changes_when_a_second_run_targets_its_out(start_emulator, tmp_path, capsys):
    emu = start_emulator(scenario={"feed_mm_s": 3.0, "depth_mm": 3.0})
    out = tmp_path / "hole1"
    first = ["run", "--robot", emu.host, "--scenario", SHORT_PLAN, "--yes", "--max-gap-ms", "500", "--out", str(out)]
    assert main(first) == 0
    capsys.readouterr()
    before = hashes(out)
    assert {"metrics.json", "commands.jsonl", "logs/real__li2023__ep0.parquet"} <= set(before)
    commands_before = emu.status()["command_counts"]
    plan = tmp_path / "plan.yaml"
    plan.write_text(
        json.dumps(
            {"scenario": {"feed_mm_s": 3.0, "depth_mm": 3.0}, "holes": [{"entry_point_base_mm": [-446, -110, 100]}]}
        )
    )
    for again in (first, [*first, "--dry-run"], [*first[:3], "--plan", str(plan), "--yes-all", "--out", str(out)]):
        line = refused(again, capsys)
        assert str(out) in line and "metrics.json" in line and "logs/" in line
    assert hashes(out) == before  # the same files, none changed, none added
    assert emu.status()["command_counts"] == commands_before  # and nothing was sent to the robot


@pytest.mark.parametrize(
    "record",
    [
        "metrics.json",
        "commands.jsonl",
        "dry_run.json",
        "plan.json",
        "logs/real__li2023__ep0.parquet",
        "logs/real__li2023__ep0/header.json",  # a log in parts, as a crash leaves it
        "commands/A1.jsonl",
        "dry_run/A1.json",
        "rtde/real__li2023__ep0/rtde.csv",
    ],
)
def test_any_file_of_a_run_s_record_is_enough_to_refuse_its_out_before_connecting(tmp_path, capsys, record):
    out = tmp_path / "out"
    (out / record).parent.mkdir(parents=True, exist_ok=True)
    (out / record).write_text("a record\n")
    before = hashes(out)
    line = refused(["run", "--robot", NO_ROBOT, "--yes", "--out", str(out)], capsys)
    assert record.split("/")[0] + ("/" if "/" in record else "") in line
    assert hashes(out) == before


@pytest.mark.parametrize("content", [None, "notes.txt"])
def test_an_empty_out_or_one_without_a_record_is_used_and_left_as_it_was_when_the_cell_cannot_be_opened(
    tmp_path, capsys, content
):
    """Past the check the run connects; nothing answers, so it fails, and takes back the command log it had
    opened (nothing was sent): a second try into the same folder is not refused."""
    out = tmp_path / "out"
    out.mkdir()
    if content:
        (out / content).write_text("mine\n")
    before = hashes(out)
    for _ in range(2):
        assert main(["run", "--robot", NO_ROBOT, "--yes", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "cannot open the cell" in err and "previous run" not in err
        assert out.is_dir() and hashes(out) == before
