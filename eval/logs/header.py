"""The JSON header of an episode log: what ran, with what, where and when."""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import json
import platform
from importlib import metadata
from typing import Any

import numpy as np

from drillgym.envs.constants import CONTROL_DT_S, FT_RATE_HZ, RTDE_RATE_HZ, TRACKER_RATE_HZ
from drillgym.envs.errors import UserError
from drillgym.eval.logs.schema import LOG_SCHEMA_VERSION

VERSIONED_PACKAGES = ("drillgym", "numpy", "gymnasium", "pybullet", "pin", "pandas", "pyarrow", "stable-baselines3")
"""Distributions whose versions go into every header (a missing optional one is left out)."""
SOURCES = ("sim", "real")


def package_versions() -> dict[str, str]:
    """Installed versions of :data:`VERSIONED_PACKAGES` and the Python version (a new dict each call)."""
    return dict(_installed_versions())


@functools.cache
def _installed_versions() -> tuple[tuple[str, str], ...]:
    """Looked up once per process: reading the distributions' metadata takes ~10 ms, once per log header."""
    versions = {}
    for name in VERSIONED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    versions["python"] = platform.python_version()
    return tuple(versions.items())


def to_jsonable(value: Any) -> Any:
    """Plain JSON types from numpy scalars/arrays, tuples and dataclasses (recursively)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_jsonable({f.name: getattr(value, f.name) for f in dataclasses.fields(value)})
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def build_header(
    env: Any,
    controller: dict[str, Any] | None,
    seed: int | None = None,
    source: str = "sim",
    extra: dict[str, Any] | None = None,
    env_id: str | None = None,
) -> dict[str, Any]:
    """Header of one episode of ``env`` (a gymnasium env, wrapped or not).

    Args:
        env: the env; its ``unwrapped.scenario`` and ``unwrapped.plan`` and its spec id are recorded.
        controller: the controller's ``describe()`` (``{"name", "config"}``), or None for no policy.
        seed: the reset seed; None lets :class:`drillgym.eval.logs.EpisodeLogger` fill it in at ``reset``.
        source: ``"sim"`` or ``"real"``.
        extra: anything else worth keeping (e.g. the benchmark suite and scenario name), under ``"run"``.
        env_id: the env's registered id, for an env not made by ``gym.make`` (default: its spec's, or its class name).

    Returns:
        A JSON-ready dict (see ``docs/log_schema.md``).
    """
    if source not in SOURCES:
        raise UserError(f"source={source!r}; allowed: {SOURCES}")
    unwrapped = env.unwrapped
    spec = getattr(env, "spec", None)
    header = {
        "schema_version": LOG_SCHEMA_VERSION,
        "source": source,
        "env_id": env_id or (spec.id if spec is not None else type(unwrapped).__name__),
        "seed": seed,
        "scenario": unwrapped.scenario.to_dict(),
        "controller": controller,
        "plan": unwrapped.plan,  # the surgical plan (SI; T_base_task as a nested 4x4 list)
        "rates_hz": {"ft": FT_RATE_HZ, "control": 1.0 / CONTROL_DT_S, "rtde": RTDE_RATE_HZ, "tracker": TRACKER_RATE_HZ},
        "versions": package_versions(),
        "created_utc": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "run": extra or {},
    }
    return to_jsonable(header)


def dumps(header: dict[str, Any]) -> str:
    """Canonical JSON text of a header (raises ``TypeError`` naming a value that is not JSON)."""
    return json.dumps(to_jsonable(header), indent=2, sort_keys=True, allow_nan=True)
