"""Fixtures of the real-cell tests: emulator processes on loopback.

Each emulator runs in its own process on a random 127.x.y.z address (so tests run in parallel) and is ended
by its own pid; teardown checks that it exited and that its ports can be bound again.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from drillgym.envs.real.emulator.process import EmulatorProcess, ports_free


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
