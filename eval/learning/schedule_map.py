"""What a schedule residual does where: each training seed's tuning of the base for each scenario's plan.

A schedule residual (:class:`drillgym.controllers.plan_schedule.PlanScheduledController`) sets the base
controller's fields once per hole from the plan, so its whole behaviour on a suite is one table: seed ×
scenario × field. :func:`schedule_table` builds it, :func:`plot_schedule_map` draws it beside the base's values.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import gymnasium as gym
import pandas as pd

from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import PlanScheduledController
from drillgym.envs import SIM_ENV_ID
from drillgym.eval.bench.suites import suite_scenarios


def schedule_table(policies: Mapping[str, str], suites: Sequence[str]) -> pd.DataFrame:
    """One row per run and scenario: the fields the run's schedule policy sets for that scenario's plan.

    Args:
        policies: run name -> controller spec (``residual:PATH``); runs that are not schedule residuals are left out.
        suites: benchmark suites whose scenarios' plans are tuned.

    Returns:
        Columns ``run``, ``suite``, ``scenario``, one per scheduled field (its value), and ``base_<field>`` (the
        base's value); empty if no run is a schedule residual.
    """
    controllers = {run: make_controller(spec) for run, spec in policies.items()}
    scheduled = {run: c for run, c in controllers.items() if isinstance(c, PlanScheduledController)}
    rows = []
    for suite in suites:
        for scenario in suite_scenarios(suite):
            env = gym.make(SIM_ENV_ID, **scenario.kwargs)
            env.reset(seed=0)
            plan = env.unwrapped.plan  # type: ignore[attr-defined]
            env.close()
            for run, controller in scheduled.items():
                controller.set_plan(plan)
                base = controller.spec.base_values
                values = controller.spec.values(controller.action)
                rows.append(
                    {
                        "run": run,
                        "suite": suite,
                        "scenario": scenario.name,
                        **values,
                        **{f"base_{k}": base[k] for k in values},
                    }
                )
    return pd.DataFrame(rows)


def plot_schedule_map(table: pd.DataFrame, path: Path) -> None:
    """One panel per scheduled field: each run's value per scenario, the base's as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fields = [c for c in table.columns if c not in ("run", "suite", "scenario") and not c.startswith("base_")]
    scenarios = list(dict.fromkeys(table["scenario"]))
    fig, axes = plt.subplots(len(fields), 1, figsize=(max(6.0, 0.7 * len(scenarios)), 2.0 * len(fields)), sharex=True)
    axes = [axes] if len(fields) == 1 else list(axes)
    x = {sc: i for i, sc in enumerate(scenarios)}
    runs = list(dict.fromkeys(table["run"]))
    for ax, field in zip(axes, fields, strict=True):
        for k, run in enumerate(runs):
            part = table[table["run"] == run]
            offset = (k - (len(runs) - 1) / 2) * 0.08
            ax.plot([x[s] + offset for s in part["scenario"]], part[field], "o", ms=4, label=run)
        ax.axhline(float(table[f"base_{field}"].iloc[0]), color="k", lw=1, ls="--", label="base")
        ax.set_ylabel(field)
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=len(runs) + 1, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 1.45))
    axes[-1].set_xticks(range(len(scenarios)))
    axes[-1].set_xticklabels(scenarios, rotation=30, ha="right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
