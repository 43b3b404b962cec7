"""Fixtures shared by the whole suite. The tests sit in folders that mirror the subsystems (``envs/``,
``controllers/``, ``training/``, ``eval/``, ``diagnosis/``, ``real/``, ``scale/``); a folder's own fixtures are in
its ``conftest.py``, its helpers in modules imported by name (``physics_helpers``, ``real_cell``, ...)."""

from __future__ import annotations

import os

# One thread per BLAS / torch pool in each test process: pytest-xdist already runs one process per core, and
# a second thread would steal the core that a real-time test (the emulated UR pipeline) runs on.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import pytest

from drillgym import envs  # noqa: F401  (registers the ids)
from drillgym.controllers.compiled import compile_kernels as compile_controller_kernels
from drillgym.envs.compiled import compile_kernels


def pytest_configure(config):
    """Fill numba's cache once, before the workers start, so that no test (a real-time one least) compiles."""
    if not hasattr(config, "workerinput"):
        compile_kernels()
        compile_controller_kernels()


@pytest.fixture(scope="session", autouse=True)
def sb3_logdir(tmp_path_factory):
    """SB3 makes a log folder for every ``learn`` without TensorBoard (in the system temp folder by default):
    keep the tests' folders inside pytest's own temporary tree."""
    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3"))
    yield
    if previous is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = previous
