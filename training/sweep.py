"""Sweep files for ``drillgym train --sweep SPEC.yaml``: read and check them (without Ray).

A sweep file (``training/sweeps/*.yaml``) names a base training configuration, fixed overrides, a
search space over :class:`drillgym.training.config.TrainConfig` fields and the ASHA early-stopping schedule::

    base_config: ../configs/residual_sac.yaml   # relative to the sweep file; optional
    fixed: {total_timesteps: 150000, eval_freq: 10000}
    search:
      learning_rate: {loguniform: [1.0e-4, 1.0e-3]}
      gamma: {choice: [0.95, 0.98, 0.99]}
      net_arch: {choice: [[64, 64], [256, 256]]}
      residual_scale: {uniform: [0.25, 0.75]}
    samples: 16          # random draws (each draw runs every grid point)
    seed: 0              # seed of the draws
    scheduler: {grace_period: 30000, reduction_factor: 3}   # ASHA: agent steps before a first cut
    max_concurrent_trials: 4
    cpus_per_trial: 2
    max_failures: 2      # restarts of a failed trial, from its latest checkpoint

Search kinds: ``choice`` (list), ``grid`` (list; every value, times ``samples``), ``uniform``,
``loguniform`` ([low, high]), ``randint`` ([low, high), integers). This module reads and checks a
sweep without Ray; running it (:mod:`drillgym.eval.scale.tune_sweep`) needs ``drillgym[ray]``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drillgym.envs.errors import UserError, read_yaml
from drillgym.training.config import TrainConfig, load_config

SEARCH_KINDS = ("choice", "grid", "uniform", "loguniform", "randint")
"""Distributions a search entry may use."""
NOT_SEARCHABLE = ("total_timesteps", "eval_freq", "n_envs")
"""Fields that set ASHA's time axis or a trial's resources: fixed for the whole sweep."""
SPEC_KEYS = (
    "base_config",
    "fixed",
    "search",
    "samples",
    "seed",
    "scheduler",
    "max_concurrent_trials",
    "cpus_per_trial",
    "max_failures",
)


@dataclass
class SweepSpec:
    """A validated sweep."""

    name: str
    """The sweep file's stem."""
    base: TrainConfig
    """Base configuration with the fixed overrides: what every trial starts from."""
    search: dict[str, tuple[str, list[Any]]] = field(default_factory=dict)
    """Field -> (kind, arguments), see :data:`SEARCH_KINDS`."""
    samples: int = 1
    seed: int = 0
    grace_period: int = 0
    """ASHA: agent steps a trial runs before it can be stopped (default: one evaluation)."""
    reduction_factor: float = 2.0
    """ASHA: share 1/reduction_factor of the trials continues at each rung."""
    max_concurrent_trials: int | None = None
    """At most this many trials at once (default: as many as the cluster's CPUs allow)."""
    cpus_per_trial: int = 1
    max_failures: int = 1

    def __post_init__(self) -> None:
        if self.grace_period <= 0:
            self.grace_period = self.base.eval_freq

    @property
    def evaluations(self) -> int:
        """Evaluations (and so reports) of a trial that runs its whole budget."""
        every = max(self.base.eval_freq // self.base.n_envs, 1) * self.base.n_envs
        return self.base.total_timesteps // every


def _check_search(search: Any, base: TrainConfig) -> dict[str, tuple[str, list[Any]]]:
    if not isinstance(search, dict) or not search:
        raise UserError("search: expected a non-empty mapping of TrainConfig fields to {kind: arguments}")
    out: dict[str, tuple[str, list[Any]]] = {}
    known = {f.name for f in dataclasses.fields(TrainConfig)}
    for name, entry in search.items():
        if name not in known:
            raise UserError(f"search: unknown training option {name!r}; known: {sorted(known)}")
        if name in NOT_SEARCHABLE:
            raise UserError(f"search: {name} is fixed for a sweep (put it under 'fixed')")
        if not (isinstance(entry, dict) and len(entry) == 1 and next(iter(entry)) in SEARCH_KINDS):
            raise UserError(f"search.{name}: expected one of {{{', '.join(SEARCH_KINDS)}: ...}}, got {entry!r}")
        kind, args = next(iter(entry.items()))
        if not isinstance(args, list) or not args:
            raise UserError(f"search.{name}.{kind}: expected a non-empty list, got {args!r}")
        if kind in ("uniform", "loguniform", "randint") and not (
            len(args) == 2 and all(isinstance(a, (int, float)) for a in args) and args[0] < args[1]
        ):
            raise UserError(f"search.{name}.{kind}: expected [low, high] with low < high, got {args}")
        if kind == "loguniform" and args[0] <= 0:
            raise UserError(f"search.{name}.loguniform: bounds must be > 0, got {args}")
        values = args if kind in ("choice", "grid") else [int(args[0])] if kind == "randint" else args
        for value in values:
            try:
                TrainConfig(**{**base.to_dict(), name: value})
            except (TypeError, ValueError) as e:
                raise UserError(f"search.{name}: value {value!r} is not a valid training option: {e}") from e
        out[name] = (kind, list(args))
    return out


def load_sweep(path: Path, overrides: dict[str, Any] | None = None, base_config: Path | None = None) -> SweepSpec:
    """Read and check a sweep file; ``overrides`` replace fixed fields, ``base_config`` the file's base."""
    path = Path(path)
    data = read_yaml(path) or {}
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise UserError(f"{path}: unknown sweep key(s) {unknown}; known: {list(SPEC_KEYS)}")
    if base_config is None and data.get("base_config"):
        base_config = path.parent / str(data["base_config"])
    fixed = dict(data.get("fixed") or {})
    base = load_config(base_config, {**fixed, **(overrides or {})})
    scheduler = dict(data.get("scheduler") or {})
    bad = sorted(set(scheduler) - {"grace_period", "reduction_factor"})
    if bad:
        raise UserError(f"{path}: unknown scheduler key(s) {bad}; known: grace_period, reduction_factor")
    spec = SweepSpec(
        name=path.stem,
        base=base,
        search=_check_search(data.get("search"), base),
        samples=int(data.get("samples", 1)),
        seed=int(data.get("seed", 0)),
        grace_period=int(scheduler.get("grace_period", 0)),
        reduction_factor=float(scheduler.get("reduction_factor", 2.0)),
        max_concurrent_trials=None if data.get("max_concurrent_trials") is None else int(data["max_concurrent_trials"]),
        cpus_per_trial=int(data.get("cpus_per_trial", base.n_envs)),
        max_failures=int(data.get("max_failures", 1)),
    )
    if spec.samples < 1 or spec.cpus_per_trial < 1 or spec.max_failures < 0 or spec.reduction_factor <= 1:
        raise UserError(f"{path}: need samples >= 1, cpus_per_trial >= 1, max_failures >= 0, reduction_factor > 1")
    if spec.evaluations < 1:
        raise UserError(f"{path}: total_timesteps {base.total_timesteps} < eval_freq {base.eval_freq}: no evaluation")
    return spec
