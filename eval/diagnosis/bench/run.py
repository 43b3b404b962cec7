"""``drillgym bench-diagnosis``: generate each case's reality, diagnose it blind, tabulate how it did.

Per case (:mod:`drillgym.eval.diagnosis.bench.cases`): write the reality's logs, diagnose them with the candidate
library (the true effect is never in the diagnosing simulator: the library holds other models of the
same physics, and none of the outside effect), and compare with the truth. Cases run in parallel (one
process each); each diagnosis runs in its process.
"""

from __future__ import annotations

import json
import math
import statistics
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from drillgym.envs.effects.registry import EFFECTS, physics_of, physics_set
from drillgym.eval.diagnosis.bench.cases import Case
from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, run_diagnosis
from drillgym.eval.diagnosis.episodes import load_episodes
from drillgym.eval.diagnosis.reality.generate import episode_name, make_reality
from drillgym.eval.pool import run_unordered

ACCEPTANCE = {
    "top1_accuracy_single": 0.98,
    "median_shrink_true_effect": 0.60,
    "clean_no_effect_named": 1.0,
    "pair_both_named": 0.90,
    "outside_unexplained_and_located": 0.90,
}
"""The targets of the figures (at least), judged on the cases of several seed offsets pooled (``--seed-offsets``,
:mod:`~drillgym.eval.diagnosis.bench.offsets`): one offset holds five pairs and six clean datasets."""
ACCEPTANCE_AT_MOST = {"wrong_effect_named_rate": 0.0}
"""Figures held to at most a value: no effect of the wrong physics named."""


CaseJob = tuple[Case, int, tuple[str, ...], bool]
"""``(case, episodes per case, candidate effects, keep the diagnosis)``."""
DIAGNOSIS_KEY = "diagnosis"
"""Row key of a case's ``diagnosis.json`` content (kept jobs only; written by :func:`run_bench`)."""


def error_row(case: Case, error: str) -> dict[str, Any]:
    """The row of a case that could not be run (scored as failed)."""
    return {
        "case": case.name,
        "kind": case.kind,
        "spec": case.spec,
        "truth": case.truth,
        "verdict": "error",
        "named": [],
        "top_single": None,
        "location": None,
        "shape_refused": {},
        "location_moved": False,
        "true_effect_shrink": None,
        "correct": False,
        "top1_ranked": False,
        "located": False,
        "located_raw": False,
        "diagnose_s": 0.0,
        "error": error,
    }


def run_case(job: CaseJob) -> dict[str, Any]:
    """Generate, diagnose and score one case (in a worker); a case that raises is scored as failed."""
    try:
        return _run_case(job)
    except Exception as e:  # one broken case must not stop the benchmark
        return error_row(job[0], f"{type(e).__name__}: {e}\n{traceback.format_exc()}")


def _run_case(job: CaseJob) -> dict[str, Any]:
    case, episodes, candidates, keep = job

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="drillgym-reality-") as tmp:
        truth = make_reality(case.spec, episodes, case.seed, Path(tmp) / "logs")
        eps, skipped = load_episodes(Path(tmp) / "logs")
    gen_s = time.perf_counter() - t0
    diag = run_diagnosis(eps, DiagnoseOptions(workers=1, candidates=candidates, seed=case.seed, progress=False))
    row = score_case(case, diag.result, gen_s, skipped)
    row["episode_params"] = episode_checks(diag.result, truth["episodes"])
    if keep:
        row[DIAGNOSIS_KEY] = _clean_json(diag.result)
    return row


def local_rows(jobs: list[CaseJob], workers: int) -> Iterator[dict[str, Any]]:
    """Run the cases in this process (one worker) or a ``spawn`` pool, yielding rows as they finish."""
    for _, row in run_unordered(run_case, jobs, max(workers, 1)):
        yield row


def score_case(case: Case, res: dict[str, Any], gen_s: float = 0.0, skipped: list[str] | None = None) -> dict[str, Any]:
    """Compare one diagnosis with its case's truth.

    A candidate counts as the physics it models (:func:`~drillgym.envs.effects.registry.physics_of`): a drift
    fitted per episode names an F/T drift, as the shared drift does (``per_episode_named`` says which form).
    """
    truth = case.truth
    named = res["named"]
    truth_physics = [physics_of(n) for n in truth]
    named_physics = [physics_of(n) for n in named]
    singles = [e for e in res["effects"] if len(e["effects"]) == 1]
    top_single = singles[0]["name"] if singles else None
    true_shrink = next((e["shrink"] for e in singles if truth and e["name"] == truth[0]), None)
    row: dict[str, Any] = {
        "case": case.name,
        "kind": case.kind,
        "spec": case.spec,
        "truth": truth,
        "verdict": res["verdict"],
        "named": named,
        "top_single": top_single,
        "location": res["location"],
        "shape_refused": {
            e["name"]: e["shape"]["reason"] for e in res["effects"] if e.get("shape") and not e["shape"]["passes"]
        },
        "location_moved": not (res.get("location_check") or {}).get("agree", True),
        "true_effect_shrink": true_shrink if len(truth) == 1 else None,
        "gap": res["significance"]["gap"],
        "null": res["significance"]["null"],
        "diagnose_s": res["timing"]["total_s"],
        "generate_s": gen_s,
        "skipped_logs": list(skipped or []),
        "per_episode_named": any(EFFECTS[n].per_episode for n in named if n in EFFECTS),
        "truth_not_ruled_out": truth_not_ruled_out(truth, res.get("alternatives") or []),
    }
    row["params"] = parameter_checks(case, res)
    if case.kind == "single":
        row["correct"] = res["verdict"] == "explained" and named_physics == truth_physics
        row["top1_ranked"] = top_single is not None and physics_of(top_single) == truth_physics[0]
    elif case.kind == "pair":
        row["correct"] = res["verdict"] == "explained" and set(truth_physics) <= set(named_physics)
    elif case.kind == "clean":
        row["correct"] = not named
    else:
        loc = case.expected_location
        where = res["location"]
        located = where is not None and loc is not None and where["channel"] in loc[0] and where["stage"] in loc[1]
        row["located"] = located
        raw = ((res.get("location_check") or {}).get("raw") or [None])[0]
        row["located_raw"] = raw is not None and loc is not None and raw["channel"] in loc[0] and raw["stage"] in loc[1]
        row["correct"] = res["verdict"] == "unexplained" and located
    return row


def parameter_checks(case: Case, res: dict[str, Any]) -> list[dict[str, Any]]:
    """For each rightly named effect with written-down true values: fitted value, 95 % interval, truth, covered."""
    truth = {physics_of(n): v for n, v in case.truth_values.items()}
    chosen = next((e for e in res["effects"] if e.get("named")), None)
    if chosen is None:
        return []
    out = []
    for name in chosen["effects"]:
        for param, true in truth.get(physics_of(name), {}).items():
            fit = chosen["params"].get(name, {}).get(param)
            ci = (chosen.get("param_intervals") or {}).get(name, {}).get(param)
            low, high = (ci["low"], ci["high"]) if ci else (None, None)
            covered = low is not None and high is not None and low <= true <= high
            out.append(
                {
                    "effect": name,
                    "param": param,
                    "truth": true,
                    "fit": fit,
                    "low": low,
                    "high": high,
                    "covered": covered,
                }
            )
    return out


def episode_checks(res: dict[str, Any], plans: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """For a named effect fitted per episode: each parameter's per-episode error against the reality's own.

    ``plans``: the reality's episodes (``make_reality``'s truth), whose ``episode_values`` hold what the effect
    was in each, in its candidate's terms. Per parameter: the RMS error over the episodes, the RMS of the true
    values about their mean (the spread to be found), and their correlation.
    """
    per_episode = res.get("per_episode")
    if not per_episode:
        return []
    name = res["named"][0]
    fitted = per_episode["episodes"]
    out = []
    for param in per_episode["spread"]:
        pairs = [
            (fitted[episode_name(i)][param], values[param])
            for i, plan in enumerate(plans)
            for n, values in (plan.get("episode_values") or {}).items()
            if physics_of(n) == physics_of(name) and episode_name(i) in fitted and param in values
        ]
        if len(pairs) < 2:
            continue
        est, true = np.array(pairs).T
        out.append(
            {
                "effect": name,
                "param": param,
                "n": len(pairs),
                "rms_error": float(np.sqrt(np.mean((est - true) ** 2))),
                "truth_spread": float(np.std(true)),
                "correlation": float(np.corrcoef(est, true)[0, 1]) if np.std(true) > 0 and np.std(est) > 0 else None,
            }
        )
    return out


def add_best_equivalent(rows: list[dict[str, Any]], table: dict[str, Any]) -> None:
    """Score each parameter check against the candidate's best equivalent of the reality, where there is one.

    ``table``: :func:`~drillgym.eval.diagnosis.bench.pseudo_truth.load_or_compute`'s pseudo-true values, by reality
    spec (single-effect cases). A random effect's mean has the written-down population mean as its own. Adds
    ``best_equivalent`` and ``covered_best_equivalent`` (None where there is no reference).
    """
    for r in rows:
        entry = table.get(r["spec"])
        for p in r.get("params") or []:
            ref = None
            if p["effect"] in EFFECTS and EFFECTS[p["effect"]].per_episode:
                ref = p["truth"]  # the population mean, whatever a shared form of the same physics converges to
            elif entry and not entry.get("error") and physics_of(entry["candidate"]) == physics_of(p["effect"]):
                ref = entry["params"].get(p["param"])
            p["best_equivalent"] = ref
            p["covered_best_equivalent"] = (
                None if ref is None or p["low"] is None or p["high"] is None else bool(p["low"] <= ref <= p["high"])
            )


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Benchmark figures from the case rows."""

    def rate(kind: str, key: str = "correct") -> float | None:
        sel = [r[key] for r in rows if r["kind"] == kind]
        return sum(bool(x) for x in sel) / len(sel) if sel else None

    shrinks = [r["true_effect_shrink"] for r in rows if r["kind"] == "single" and r["true_effect_shrink"] is not None]
    wrong_named = [r for r in rows if r["kind"] in ("single", "pair") and named_wrong_physics(r)]
    figures = {
        "top1_accuracy_single": rate("single"),
        "top1_ranked_single": rate("single", "top1_ranked"),
        "median_shrink_true_effect": statistics.median(shrinks) if shrinks else None,
        "clean_no_effect_named": rate("clean"),
        "false_alarm_rate_clean": None if rate("clean") is None else 1.0 - (rate("clean") or 0.0),
        "wrong_effect_named_rate": len(wrong_named) / max(1, sum(r["kind"] in ("single", "pair") for r in rows)),
        "wrong_effect_named_truth_not_ruled_out": sum(bool(r.get("truth_not_ruled_out")) for r in wrong_named),
        "pair_both_named": rate("pair"),
        "outside_unexplained_and_located": rate("outside"),
        "outside_unexplained": _outside_unexplained(rows),
        "outside_located_before_specimen_fit": rate("outside", "located_raw"),
        **_shape_refusals(rows),
        **_trend_forms(rows),
        "location_moved_by_specimen_fit": sum(bool(r.get("location_moved")) for r in rows),
        "interval_coverage": _coverage(rows),
        "parameters_scored": sum(len(r.get("params") or []) for r in rows),
        "interval_coverage_best_equivalent": _coverage(rows, "covered_best_equivalent"),
        "parameters_scored_best_equivalent": sum(
            p.get("covered_best_equivalent") is not None for r in rows for p in (r.get("params") or [])
        ),
    }
    passed = {k: float(figures[k] or 0.0) >= v for k, v in ACCEPTANCE.items() if figures.get(k) is not None}
    passed |= {k: float(figures[k] or 0.0) <= v for k, v in ACCEPTANCE_AT_MOST.items() if figures.get(k) is not None}
    return {
        "figures": figures,
        "acceptance": ACCEPTANCE,
        "acceptance_at_most": ACCEPTANCE_AT_MOST,
        "passed": passed,
        "cases": len(rows),
    }


def truth_not_ruled_out(truth: list[str], alternatives: list[dict[str, Any]]) -> bool:
    """Whether the diagnosis listed a model of the truth's physics among those the held-out data do not rule out.

    A wrong model named with the right one listed beside it is a false attribution the report flags itself
    ("not ruled out: ..."), where ``drillgym separate`` says which holes would decide.
    """
    return bool(truth) and any(physics_set(a["effects"]) == physics_set(truth) for a in alternatives)


def named_wrong_physics(row: dict[str, Any]) -> bool:
    """Whether a case named an effect of physics its truth does not hold (a form of the true physics is right)."""
    return bool(physics_set(row["named"]) - physics_set(row["truth"]))


def _shape_refusals(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Models refused by the shape test: of other physics than the case's truth (right) or of the truth (wrong)."""
    right = wrong = 0
    for r in rows:
        truth = physics_set(r["truth"])
        for name in r.get("shape_refused") or {}:
            if truth and physics_set(name.split("+")) <= truth:
                wrong += 1
            else:
                right += 1
    return {"shape_refusals_other_physics": right, "shape_refusals_true_physics": wrong}


def _trend_forms(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Where a trend form (:attr:`~drillgym.envs.effects.base.Effect.in_series`) was named.

    On realities that drift over the series (the right form) and on those with the same physics held still (a trend
    where there is none).
    """
    trend = {n for n, c in EFFECTS.items() if c.in_series}
    physics = physics_set(trend)
    drifting = [r for r in rows if set(r["truth"]) & trend]
    still = [r for r in rows if not set(r["truth"]) & trend and physics_set(r["truth"]) & physics]
    return {
        "drifting_cases": len(drifting),
        "drifting_trend_named": sum(bool(set(r["named"]) & trend) for r in drifting),
        "still_cases": len(still),
        "still_trend_named": sum(bool(set(r["named"]) & trend) for r in still),
    }


def _coverage(rows: list[dict[str, Any]], key: str = "covered") -> float | None:
    checks = [p[key] for r in rows for p in (r.get("params") or []) if p.get(key) is not None]
    return sum(checks) / len(checks) if checks else None


def _outside_unexplained(rows: list[dict[str, Any]]) -> float | None:
    sel = [r for r in rows if r["kind"] == "outside"]
    return sum(r["verdict"] == "unexplained" for r in sel) / len(sel) if sel else None


def run_bench(
    cases: list[Case],
    episodes: int,
    candidates: tuple[str, ...],
    out: Path,
    workers: int,
    progress: bool = True,
    rows_of: Callable[[list[CaseJob]], Iterable[dict[str, Any]]] | None = None,
    best_equivalent: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run every case and write ``bench.json``, ``bench.md`` and ``cases/NAME/diagnosis.json`` into ``out``.

    ``rows_of`` runs the jobs and yields their rows as they finish (default: :func:`local_rows` with
    ``workers`` processes; :func:`drillgym.eval.diagnosis.bench.on_ray.ray_rows` for a Ray cluster).
    ``best_equivalent``: pseudo-true values by reality spec (:mod:`~drillgym.eval.diagnosis.bench.pseudo_truth`),
    to score the intervals against them too.
    """
    out.mkdir(parents=True, exist_ok=True)
    jobs: list[CaseJob] = [(c, episodes, candidates, True) for c in cases]
    run_jobs = rows_of or (lambda js: local_rows(js, workers))
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    bar = tqdm(total=len(jobs), desc="bench-diagnosis", file=sys.stderr, disable=None if progress else True)
    for row in run_jobs(jobs):
        diagnosis = row.pop(DIAGNOSIS_KEY, None)
        if diagnosis is not None:
            d = out / "cases" / row["case"]
            d.mkdir(parents=True, exist_ok=True)
            (d / "diagnosis.json").write_text(json.dumps(diagnosis, indent=2))
        rows.append(row)
        bar.set_postfix_str(f"{row['case']}: {row['verdict']}")
        bar.update()
    bar.close()
    order = {c.name: k for k, c in enumerate(cases)}
    rows.sort(key=lambda r: order[r["case"]])
    if best_equivalent is not None:
        add_best_equivalent(rows, best_equivalent)
    summary = summarise(rows)
    summary.update(
        wall_s=time.perf_counter() - t0, workers=workers, episodes_per_case=episodes, candidates=list(candidates)
    )
    result = {"summary": summary, "rows": rows}
    (out / "bench.json").write_text(json.dumps(_clean_json(result), indent=2))
    (out / "bench.md").write_text(markdown(result))
    return result


def markdown(result: dict[str, Any]) -> str:
    """The benchmark as Markdown."""
    s = result["summary"]
    fmt = lambda v: "–" if v is None else (f"{100 * v:.0f} %" if isinstance(v, float) else str(v))  # noqa: E731
    lines = [
        "# Withheld-effect benchmark of the sim-to-real diagnosis",
        "",
        f"{s['cases']} cases, {s['episodes_per_case']} episodes each, {s['workers']} worker(s), {s['wall_s']:.0f} s.",
        "",
        "| figure | value | acceptance | passed |",
        "|---|---|---|---|",
    ]
    for k, v in s["figures"].items():
        acc, most = s["acceptance"].get(k), s.get("acceptance_at_most", {}).get(k)
        target = "" if acc is None else "≥ " + fmt(acc)
        target = target if most is None else "≤ " + fmt(most)
        lines.append(f"| {k} | {fmt(v)} | {target} | {s['passed'].get(k, '')} |")
    lines += [
        "",
        "| case | kind | truth | verdict | named | top single | true-effect shrink | location | correct | s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        loc = "" if not r["location"] else f"{r['location']['channel']}, {r['location']['stage']}"
        lines.append(
            f"| {r['case']} | {r['kind']} | {'+'.join(r['truth']) or '–'} | {r['verdict']} | {'+'.join(r['named']) or '–'} | "
            f"{r['top_single']} | {fmt(r['true_effect_shrink'])} | {loc} | {r['correct']} | {r['diagnose_s']:.0f} |"
        )
    g = lambda v: "–" if v is None else f"{v:.4g}"  # noqa: E731
    lines += _table(
        "Parameters of rightly named effects against the reality's own (``RealityEffect.candidate_values``) and "
        "against the candidate's best equivalent (``--pseudo-truth``):",
        ["case", "parameter", "truth", "fit", "95 % interval", "covered", "best equivalent", "covered"],
        [
            [
                r["case"],
                f"{p['effect']}.{p['param']}",
                g(p["truth"]),
                g(p["fit"]),
                f"[{g(p['low'])}, {g(p['high'])}]",
                str(p["covered"]),
                g(p.get("best_equivalent")),
                "" if p.get("covered_best_equivalent") is None else str(p["covered_best_equivalent"]),
            ]
            for r in result["rows"]
            for p in (r.get("params") or [])
        ],
    )
    lines += _table(
        "Models refused by the shape test (docs/diagnosis.md §3), and cases whose gap's location the per-specimen "
        "hardness fit moved:",
        ["case", "truth", "refused or moved", "reason"],
        [
            [r["case"], "+".join(r["truth"]) or "–", m, why]
            for r in result["rows"]
            for m, why in (r.get("shape_refused") or {}).items()
        ]
        + [
            [r["case"], "+".join(r["truth"]) or "–", "location", "moved by the specimen fit"]
            for r in result["rows"]
            if r.get("location_moved")
        ],
    )
    lines += _table(
        "Per-episode parameters of effects named as random effects, against each episode's own value:",
        ["case", "parameter", "episodes", "RMS error", "true spread (SD)", "correlation"],
        [
            [
                r["case"],
                f"{p['effect']}.{p['param']}",
                str(p["n"]),
                g(p["rms_error"]),
                g(p["truth_spread"]),
                g(p["correlation"]),
            ]
            for r in result["rows"]
            for p in (r.get("episode_params") or [])
        ],
    )
    lines.append("")
    return "\n".join(lines)


def _table(intro: str, columns: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table with a line above it; nothing without rows."""
    if not rows:
        return []
    out = ["", intro, "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    return out + ["| " + " | ".join(row) + " |" for row in rows]


def _clean_json(v: Any) -> Any:

    if isinstance(v, dict):
        return {str(k): _clean_json(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean_json(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
