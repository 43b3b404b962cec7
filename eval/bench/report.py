"""Benchmark outputs: ``episodes.csv``, ``summary.csv``, ``paired.csv``, ``summary.md`` and the plots."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import pandas as pd

from drillgym.envs.errors import UserError
from drillgym.envs.metrics import METRIC_NAMES
from drillgym.envs.scenario import Scenario
from drillgym.eval.bench.plots import plot_bars, plot_sweep
from drillgym.eval.bench.summary import markdown_table, paired_differences, summarize, verdict_lines

SCENARIO_COLUMNS = tuple(f.name for f in fields(Scenario))
EPISODE_COLUMNS = (
    "suite",
    "scenario",
    *SCENARIO_COLUMNS,
    "controller",
    "seed",
    *METRIC_NAMES,
    "steps",
    "sim_time_s",
    "failure",
    "error",
    "log",
    "wall_time_s",
)
"""Columns of ``episodes.csv``: one row per episode, sorted by (suite, scenario, controller, seed)."""
MAIN_METRICS = (
    "deviation_mean_mm",
    "deviation_max_mm",
    "lateral_force_max_n",
    "lateral_force_stable_n",
    "hole_offset_mm",
    "drill_time_s",
)
"""Metrics shown in ``summary.md``; lower is better for each (``drill_time_s`` too: a shorter drilling time)."""
FEW_SEEDS = 20
"""Below this many seeds per scenario, ``drillgym bench`` warns that its CIs are wide."""


@dataclass
class BenchReport:
    """What :func:`write_report` computed, besides the files."""

    episodes: pd.DataFrame
    """``episodes.csv``."""
    paired: pd.DataFrame
    """``paired.csv``: every controller minus the reference."""
    reference: str
    """The controller the paired differences are taken against."""
    verdict_scenario: str
    """Scenario of the verdicts: ``all`` (every scenario pooled) when the suite has several, else its one."""
    verdicts: list[str]
    """One line per controller and metric of :data:`MAIN_METRICS` (:func:`drillgym.eval.bench.summary.verdict`)."""


def few_seeds_warning(seeds: int) -> str:
    """The warning for fewer than :data:`FEW_SEEDS` seeds per scenario; ``""`` from there on."""
    if seeds >= FEW_SEEDS:
        return ""
    return (
        f"fewer than {FEW_SEEDS} seeds per scenario: the 95 % CIs are wide (--seeds {seeds}), so a real difference "
        f"may show as no significant difference; use --seeds {FEW_SEEDS} or more to rank controllers"
    )


def episodes_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Rows sorted by (suite, scenario, controller, seed), columns in :data:`EPISODE_COLUMNS` order."""
    rows = sorted(rows, key=lambda r: (r["suite"], r["scenario"], r["controller"], r["seed"]))
    frame = pd.DataFrame(rows)
    for c in EPISODE_COLUMNS:
        if c not in frame:
            frame[c] = pd.NA
    return frame[list(EPISODE_COLUMNS)]


def write_report(
    out: Path,
    rows: list[dict[str, Any]],
    suite: str,
    scenarios: Sequence[str],
    controllers: Sequence[str],
    seeds: int,
    reference: str | None = None,
) -> BenchReport:
    """Write every output into ``out``.

    Args:
        out: the output folder.
        rows: one ``episodes.csv`` row per episode, in any order.
        suite: the suite's name.
        scenarios: its scenarios' names, in order.
        controllers: the controller specs, in order.
        seeds: seeds per scenario and controller.
        reference: the controller of ``controllers`` the paired differences are taken against (default the first).
    """
    reference = controllers[0] if reference is None else reference
    if reference not in controllers:
        raise UserError(f"reference {reference!r} is not one of the controllers {list(controllers)}")
    episodes = episodes_frame(rows)
    episodes.to_csv(out / "episodes.csv", index=False)
    tracebacks = [
        f"{r['scenario']} {r['controller']} seed {r['seed']}\n{r['traceback']}" for r in rows if r.get("traceback")
    ]
    if tracebacks:
        (out / "errors.log").write_text("\n".join(tracebacks))
    ok = episodes[episodes["error"].fillna("") == ""]
    groups = [(suite, s, c) for s in scenarios for c in controllers]
    summary = summarize(ok, METRIC_NAMES, groups)
    summary.to_csv(out / "summary.csv", index=False)
    paired = paired_differences(ok, METRIC_NAMES, groups, baseline=reference)
    if len(scenarios) > 1:  # every scenario together, paired by (scenario, seed)
        pooled = ok.assign(seed=ok["scenario"] + "#" + ok["seed"].astype(str), scenario="all")
        pooled_groups = [(suite, "all", c) for c in controllers]
        paired = pd.concat([paired, paired_differences(pooled, METRIC_NAMES, pooled_groups, reference)])
    paired.to_csv(out / "paired.csv", index=False)
    scenario = "all" if len(scenarios) > 1 else scenarios[0]
    report = BenchReport(episodes, paired, reference, scenario, verdict_lines(paired, MAIN_METRICS, scenario))
    plots = _plots(out, suite, summary, ok, controllers)
    (out / "summary.md").write_text(_markdown(suite, summary, report, controllers, seeds, plots))
    return report


def _plots(out: Path, suite: str, summary: pd.DataFrame, ok: pd.DataFrame, controllers: Sequence[str]) -> list[str]:
    if suite == "sweep":
        names = ["sweep_lateral_force_vs_beta.png", "sweep_deviation_vs_feed.png"]
        plot_sweep(summary, ok, controllers, "lateral_force_max_n", "beta_deg", "feed_mm_s", out / names[0])
        plot_sweep(summary, ok, controllers, "deviation_mean_mm", "feed_mm_s", "beta_deg", out / names[1])
        return names
    name = f"{suite}_deviation_force.png"
    plot_bars(summary, controllers, out / name, title=f"{suite} suite: mean ± 95% CI")
    return [name]


def _count(n: int, noun: str) -> str:
    """``"1 episode"``, ``"3 episodes"``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _markdown(
    suite: str,
    summary: pd.DataFrame,
    report: BenchReport,
    controllers: Sequence[str],
    seeds: int,
    plots: list[str],
) -> str:
    ctrl = ", ".join(f"`{c}`" for c in controllers)
    episodes, ref = report.episodes, report.reference
    parts = [
        f"# drillgym bench: {suite} suite",
        "",
        f"{_count(len(episodes), 'episode')}: {'seed 0' if seeds == 1 else f'seeds 0..{seeds - 1}'} "
        f"(the same seeds for every controller), controllers {ctrl}"
        + (f", reference `{ref}`." if len(controllers) > 1 else "."),
        "Cells: mean [95% CI of the mean, Student t; – with one episode]; n counts the episodes that define the metric.",
    ]
    warning = few_seeds_warning(seeds)
    if warning:
        parts += ["", f"Warning: {warning}."]
    parts += ["", "## Metrics", "", markdown_table(summary, MAIN_METRICS)]
    if len(controllers) > 1:
        parts += [
            "",
            f"## Paired differences vs `{ref}`",
            "",
            f"Controller minus `{ref}` on the same seed (negative = smaller); mean [95% CI]; in bold where the CI "
            "excludes 0 (a significant difference). "
            "Scenario `all` pools every scenario of the suite (pairs: same scenario, same seed).",
            "",
            markdown_table(report.paired, MAIN_METRICS, label="Δ ", bold_significant=True),
            "",
            f"## Verdicts vs `{ref}`",
            "",
            f"On scenario `{report.verdict_scenario}`"
            + (" (every scenario pooled)" if report.verdict_scenario == "all" else "")
            + "; lower is better for every metric here (drill_time_s: a shorter drilling time); "
            "a difference is significant when its 95% CI excludes 0.",
            "",
            *(f"* {line}" for line in report.verdicts),
        ]
    failed = episodes[episodes["error"].fillna("") != ""]
    if len(failed):
        parts += ["", f"## Failed episodes ({len(failed)}, left out above; tracebacks in errors.log)", ""]
        parts += [f"* {r.scenario} `{r.controller}` seed {r.seed}: {r.error}" for r in failed.itertuples(index=False)]
    stopped = episodes[(episodes["failure"].fillna("") != "") & (episodes["error"].fillna("") == "")]
    if len(stopped):
        parts += [
            "",
            f"Episodes ended early (safety stop or time limit): {len(stopped)}; see `failure` in episodes.csv.",
        ]
    parts += ["", "Files: episodes.csv, summary.csv, paired.csv, " + ", ".join(plots), ""]
    parts += [f"![{p}]({p})" for p in plots]
    return "\n".join(parts) + "\n"
