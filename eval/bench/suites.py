"""Benchmark suites: named lists of scenarios (env keyword arguments, user units).

* ``paper``: Li et al. 2023's experiment (the env defaults: β 30°, 0.5 mm/s, Li's Table 2).
* ``sweep``: β ∈ {10, 20, 30, 40}° × feed ∈ {0.25, 0.5, 0.75, 1.0, 1.25} mm/s, the rest at defaults.
* ``heldout``: conditions outside :data:`TRAINING_RANGES` (see :func:`heldout`), for testing how a
  residual policy trained inside them generalises.
* ``generalisation``: 24 plans drawn at random strictly inside the training ranges and bones from a fixed
  stream of the judge's seed namespace (see :func:`generalisation`): plans no tuner or learner was given,
  between the anchors a gain-scheduling table is tuned on.
* ``robustness``: the paper plan in imperfect cells, one unmodelled effect of the diagnosis's library at a
  plausible size each, and all of them together, and the paper and generalisation plans in cells drawn per
  episode (see :func:`robustness`): how each compensator degrades.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.scenario import Scenario
from drillgym.envs.seeds import Purpose, stream
from drillgym.training.cell import TrainingCell
from drillgym.training.domain_randomization import TRAINING_BONES, TRAINING_RANGES

__all__ = [
    "GENERALISATION_PLANS",
    "JUDGE_ONLY_SUITES",
    "ROBUSTNESS_CELLS",
    "ROBUSTNESS_DRAWS",
    "SUITES",
    "TRAINING_BONES",
    "TRAINING_RANGES",
    "SuiteScenario",
    "outside_training",
    "suite_scenarios",
]


class SuiteScenario(NamedTuple):
    """One scenario of a suite: a name (for files and tables), the env keyword arguments and the cell's effects."""

    name: str
    kwargs: dict[str, Any]
    effects: str = ""
    """Unmodelled effects switched on in this scenario (:func:`drillgym.envs.effects.build_effects` spec; empty:
    none). A benchmark's ``--cell`` adds its own."""
    draws: tuple[tuple[str, float, float], ...] = ()
    """``(effect.param, low, high)``: parameters of ``effects`` each episode draws uniformly, seeded by its seed (the
    same cell for every controller on a seed; :meth:`episode_effects`)."""

    def episode_effects(self, seed: int, cell: str = "") -> str:
        """The effect spec of the episode of ``seed``.

        ``cell``'s effects (a benchmark's ``--cell``) first, then ``effects`` with ``draws`` drawn for the episode.
        """
        own = self.effects
        if self.draws:
            drawn = TrainingCell(self.effects, {key: (lo, hi) for key, lo, hi in self.draws})
            own = drawn.draw_spec(np.random.default_rng([seed, EPISODE_DRAWS_KEY]))
        return "+".join(x for x in (cell, own) if x)


EPISODE_DRAWS_KEY = 11
"""Key of a suite scenario's per-episode draws beside the episode's seed."""


def paper() -> list[SuiteScenario]:
    """Li et al. 2023's experiment: the env defaults."""
    return [SuiteScenario("paper", {})]


def sweep() -> list[SuiteScenario]:
    """β × feed grid, named like ``b30_f0.50``."""
    return [
        SuiteScenario(f"b{beta:g}_f{feed:.2f}", {"beta_deg": beta, "feed_mm_s": feed})
        for beta in (10.0, 20.0, 30.0, 40.0)
        for feed in (0.25, 0.5, 0.75, 1.0, 1.25)
    ]


def heldout() -> list[SuiteScenario]:
    """Conditions kept out of the residual-training ranges; each leaves them in one parameter.

    * ``beta10``, ``beta40``: β 10° and 40°, outside 15–35° (shallower and steeper entries).
    * ``feed1.2``: 1.2 mm/s, above the 0.3–1.0 mm/s feeds (thicker chips, higher forces).
    * ``human_femur``: harder cortex with a denser core; not a training bone.
    * ``sawbones``: ``sawbones_20pcf``, a soft uniform synthetic block; not a training bone.
    * ``stickout26``, ``stickout48``: 26 and 48 mm of drill, outside 30–42 mm (stiffer / far softer drill).
    * ``thin_cortex``: 1.5 mm cortex (depth 6 mm, so the drill breaks into the cancellous core), below 3–10 mm.
    """
    return [
        SuiteScenario("beta10", {"beta_deg": 10.0}),
        SuiteScenario("beta40", {"beta_deg": 40.0}),
        SuiteScenario("feed1.2", {"feed_mm_s": 1.2}),
        SuiteScenario("human_femur", {"bone": "human_femur"}),
        SuiteScenario("sawbones", {"bone": "sawbones_20pcf"}),
        SuiteScenario("stickout26", {"stickout_mm": 26.0}),
        SuiteScenario("stickout48", {"stickout_mm": 48.0}),
        SuiteScenario("thin_cortex", {"cortical_thickness_mm": 1.5, "depth_mm": 6.0}),
    ]


GENERALISATION_PLANS = 24
"""Plans of the ``generalisation`` suite."""
GENERALISATION_STREAM_KEY = 2024
"""Key of the generalisation plans' stream in the judge's namespace (:func:`drillgym.envs.seeds.stream`)."""


def generalisation() -> list[SuiteScenario]:
    """Plans inside the training ranges that no tuner or learner saw, named ``g01`` .. ``g24``.

    Each plan draws β (rounded to 0.5°), feed (0.01 mm/s), stick-out and cortical thickness (0.1 mm) uniformly
    inside :data:`TRAINING_RANGES` and a bone among :data:`TRAINING_BONES`, from
    ``stream(JUDGE, GENERALISATION_STREAM_KEY)``; the cell (noise, latency) is the env's default. Tuning and
    training draw their plans from streams of their own namespaces, so none of these is a plan they were
    given (the chance that a continuous draw repeats one is nil), and none lies on the edge of a range, where
    a table's anchors sit.
    """
    rng = stream(Purpose.JUDGE, GENERALISATION_STREAM_KEY)
    rounding = {"beta_deg": 0.5, "feed_mm_s": 0.01, "stickout_mm": 0.1, "cortical_thickness_mm": 0.1}
    out = []
    for i in range(GENERALISATION_PLANS):
        kwargs: dict[str, Any] = {}
        for name, (lo, hi) in TRAINING_RANGES.items():
            step = rounding[name]
            value = round(float(rng.uniform(lo, hi)) / step) * step
            kwargs[name] = float(min(max(value, lo + step), hi - step))  # strictly inside the range
            kwargs[name] = round(kwargs[name], 2)
        kwargs["bone"] = str(TRAINING_BONES[int(rng.integers(len(TRAINING_BONES)))])
        out.append(SuiteScenario(f"g{i + 1:02d}", kwargs))
    return out


ROBUSTNESS_CELLS: dict[str, str] = {
    "lab_friction": "joint_friction:coulomb_rad=0.000417",
    "latency_60ms": "latency:extra_latency_s=0.06",
    "backlash": "joint_backlash:play_rad=3e-4",
    "tool_long": "tool_length:dl_m=2e-3",
    "tool_short": "tool_length:dl_m=-2e-3",
    "ft_drift": "ft_drift:fx_rate_n_s=0.01,fy_rate_n_s=-0.01",
    "all": "joint_friction:coulomb_rad=0.000417+latency:extra_latency_s=0.06+joint_backlash:play_rad=3e-4"
    "+tool_length:dl_m=2e-3+ft_drift:fx_rate_n_s=0.01,fy_rate_n_s=-0.01",
}
"""The robustness suite's cells, each at a size a real cell plausibly has:

* ``lab_friction``: joint friction, Coulomb 0.417 mrad: the cell fitted to Li's runs (``li2023-lab``,
  docs/explain-paper.md).
* ``latency_60ms``: 60 ms more delay of the streamed target than the cell's 14 ms (a slower servo interface or
  network; the effect allows up to 0.3 s).
* ``backlash``: 0.3 mrad of play in the first three joints (a worn harmonic drive; new ones have 0.03–0.3 mrad).
* ``tool_long``, ``tool_short``: the drill 2 mm further out of, or into, the chuck than planned (a re-grip).
* ``ft_drift``: the F/T's lateral forces drifting 0.01 N/s (0.15 N over a hole; a sensor not warmed up).
* ``all``: every one of them together (the longer tool)."""


ROBUSTNESS_DRAWS: tuple[tuple[str, float, float], ...] = (
    ("joint_friction.coulomb_rad", 0.0, 0.000417),
    ("latency.extra_latency_s", 0.0, 0.06),
    ("joint_backlash.play_rad", 0.0, 3e-4),
    ("tool_length.dl_m", -1e-3, 1e-3),
    ("ft_drift.fx_rate_n_s", -0.01, 0.01),
    ("ft_drift.fy_rate_n_s", -0.01, 0.01),
)
"""The ``drawn`` cell of the robustness suite: each episode draws every effect of ``all`` anew, from none up to its
size there (the tool length within ±1 mm, the drift's sign either way), as cells differ from one another."""


def robustness() -> list[SuiteScenario]:
    """The paper plan in each of :data:`ROBUSTNESS_CELLS` and in cells drawn per episode; the generalisation plans in drawn cells.

    ``paper_<cell>``: the paper plan in the cell. ``paper_drawn``: every effect of the ``all`` cell drawn for each
    episode (:data:`ROBUSTNESS_DRAWS`). ``gNN_drawn``: the ``generalisation`` suite's plans, each in cells drawn
    the same way, so a compensator is judged on plans and cells that no tuner or learner saw.
    """
    cells = [SuiteScenario(f"paper_{cell}", {}, spec) for cell, spec in ROBUSTNESS_CELLS.items()]
    drawn = ROBUSTNESS_CELLS["all"]
    plans = [SuiteScenario(f"{s.name}_drawn", s.kwargs, drawn, ROBUSTNESS_DRAWS) for s in generalisation()]
    return [*cells, SuiteScenario("paper_drawn", {}, drawn, ROBUSTNESS_DRAWS), *plans]


SUITES: dict[str, Callable[[], list[SuiteScenario]]] = {
    "paper": paper,
    "sweep": sweep,
    "heldout": heldout,
    "generalisation": generalisation,
    "robustness": robustness,
}
"""Suite name -> its scenarios."""
JUDGE_ONLY_SUITES = ("heldout", "generalisation", "robustness")
"""Suites that judge tuned and learnt controllers and that no tuner may use."""


def suite_scenarios(name: str) -> list[SuiteScenario]:
    """The scenarios of suite ``name``; an unknown name raises ``ValueError`` listing the suites."""
    if name not in SUITES:
        raise UserError(f"unknown suite {name!r}; choose from {', '.join(SUITES)}")
    return SUITES[name]()


def outside_training(kwargs: dict[str, Any]) -> list[str]:
    """Why a scenario lies outside the training ranges (empty if it lies inside), defaults filled in."""
    sc = Scenario.from_kwargs(**kwargs)
    reasons = [
        f"{name}={getattr(sc, name):g} outside [{lo:g}, {hi:g}]"
        for name, (lo, hi) in TRAINING_RANGES.items()
        if not lo <= getattr(sc, name) <= hi
    ]
    if sc.bone not in TRAINING_BONES:
        reasons.append(f"bone={sc.bone} not in {list(TRAINING_BONES)}")
    return reasons
