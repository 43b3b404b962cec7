"""Fixtures of the real-cell tests: emulator processes on loopback.

Each emulator runs in its own process on a random 127.x.y.z address (so tests run in parallel) and is ended
by its own pid; teardown checks that it exited and that its ports can be bound again.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from drillgym.envs.real.emulator.process import EmulatorProcess, ports_free

CELL_MODULES = frozenset(
    {
        "test_dry_run_reach",
        "test_real_cli",
        "test_real_episode",
        "test_real_faults",
        "test_real_ft_calibration",
        "test_real_servo_process",
        "test_record_session",
        "test_run_load_report",
        "test_run_plan_file",
        "test_run_record_append_only",
    }
)
"""Modules whose realtime tests drive a whole cell (env or ``drillgym run``: agent, servo process and emulator, about
one core together) or time its faults. ``make test`` runs the realtime tests on two processes with
``--dist loadgroup``: these share one group, so one runs at a time, beside at most one of the emulator's protocol
tests, which mostly wait on sockets. The suite passes beside two spinning processes (docs/testing.md), more load than
a protocol test brings."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put every realtime test of CELL_MODULES in xdist group ``cell`` (ignored unless ``--dist loadgroup``)."""
    for item in items:
        if item.get_closest_marker("realtime") and item.module is not None and item.module.__name__ in CELL_MODULES:
            item.add_marker(pytest.mark.xdist_group("cell"))


@pytest.fixture
def start_emulator() -> Iterator[Callable[..., EmulatorProcess]]:
    """Factory: ``start_emulator(seed=0, scenario={...}, extra_args=[...])`` -> a running emulator."""
    started: list[EmulatorProcess] = []

    def _start(**kwargs: Any) -> EmulatorProcess:
        emu = EmulatorProcess(max_lifetime_s=300.0, **kwargs)
        started.append(emu)
        return emu.start()

    yield _start
    for emu in started:
        code = emu.stop()
        assert emu.proc is not None and emu.proc.poll() is not None, f"emulator {emu.host} still running"
        assert code == 0, f"emulator {emu.host} exited with {code}: {emu.log_tail()}"
        assert ports_free(emu.host), f"an emulator port is still bound on {emu.host}"
