"""Fixtures of the scale-out tests (Ray)."""

from __future__ import annotations

import logging

import pytest


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray instance with 2 CPUs per test module (starting Ray takes seconds); skips without Ray."""
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    yield ray
    ray.shutdown()
