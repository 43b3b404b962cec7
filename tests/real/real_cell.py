"""Helpers of the real-cell tests: the real env on an emulator, and an episode runner (the emulator fixture is in
this folder's ``conftest.py``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.emulator.process import EmulatorProcess

REAL_ENV_ID = "drillgym/UR5BoneDrillReal-v1"
ONE_CELL_AT_A_TIME = pytest.mark.cell
"""The mark (``pytestmark``) of every module whose realtime tests drive a whole cell (the env or ``drillgym run``:
agent, servo process and emulator, about one core together) or time its faults, and of the fuzz test, whose 100 ms
bar on the emulator's stream a cell beside it broke once (114 ms, in a clean clone's ``make test``). ``make test`` runs the realtime
tests in two processes: ``-m "realtime and cell"`` one test at a time, and beside it ``-m "realtime and not cell"``,
the emulator's protocol tests, which mostly wait on sockets. Two cells at once on two cores stopped holes
(``program_stopped``, a refused ``moveL``) in 1 of 6 suite runs; the suite passes beside two spinning processes,
more load than a protocol test brings. (Not an xdist group: pytest-xdist 3.8's ``--dist loadgroup`` renames a
test's node id, which pytest 9 no longer reads, so the groups were silently lost.)"""
CI_LIMITS = SafetyLimits(max_cycle_gap_s=0.5, rtde_stale_s=0.5, ft_stale_s=0.5, tracker_stale_s=0.5)
"""Timing limits for long episodes on a shared CI machine (the defaults are exercised by the fault tests): beside
two busy processes the emulator's streams, at ordinary priority, can pause for more than the defaults' 0.1 s
(the tracker's did in one loaded run, and the episode's tracker_valid dropped for a step)."""


def make_real_env(emu: EmulatorProcess, **kwargs: Any) -> gym.Env:
    """The real env connected to ``emu`` (F/T and marker stream from the same emulator)."""
    kwargs.setdefault("tracker", f"udp:{emu.host}")
    return gym.make(REAL_ENV_ID, robot_host=emu.host, **kwargs)


def run_steps(
    env: gym.Env,
    controller: Any,
    seed: int = 0,
    max_steps: int | None = None,
    on_step: Callable[[int], None] | None = None,
    options: dict[str, Any] | None = None,
) -> tuple[int, dict[str, Any], bool]:
    """Reset and step ``controller`` until the episode ends or ``max_steps``; returns (steps, info, ended)."""
    obs, info = env.reset(seed=seed, options=options)
    controller.set_plan(env.unwrapped.plan)
    start, steps = True, 0
    while max_steps is None or steps < max_steps:
        if on_step is not None:
            on_step(steps)
        action, _ = controller.predict(obs, episode_start=np.array([start]))
        obs, _, terminated, truncated, info = env.step(action)
        start, steps = False, steps + 1
        if terminated or truncated:
            return steps, info, True
    return steps, info, False


def wait_until(predicate: Callable[[], Any], timeout_s: float = 2.0, poll_s: float = 0.004) -> bool:
    """Poll ``predicate`` until it holds or ``timeout_s`` (s) has passed; returns its last value as a bool.

    The tests' synchronisation with the emulator's 125 Hz clock: a condition a command or fault brings about shows
    within a few controller cycles on a quiet machine, later on a busy one, so a test waits for the condition (up
    to a deadline that only a broken emulator reaches) instead of sleeping a fixed time and hoping.
    """
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() >= deadline:
            return bool(predicate())
        time.sleep(poll_s)
    return True
