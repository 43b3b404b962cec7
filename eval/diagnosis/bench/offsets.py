"""The withheld-effect benchmark over several seed offsets: each offset's run, then every case of every run pooled.

One offset's 45 cases give each figure from a handful of cases (five pairs, six clean datasets), so one wrong case
moves a figure by 17–20 points: the benchmark's targets are judged on the cases of several offsets together (the
same cases on other episodes and specimens). ``drillgym bench-diagnosis --seed-offsets 0,1000,2000 --out DIR`` runs
each offset into ``DIR/offset-N`` (:func:`~drillgym.eval.diagnosis.bench.run.run_bench`, its own ``bench.json`` and
``bench.md``) and writes ``DIR/bench.json`` and ``DIR/bench.md`` with every offset's counts and the pooled ones.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from drillgym.envs.errors import UserError
from drillgym.eval.diagnosis.bench.cases import Case
from drillgym.eval.diagnosis.bench.run import ACCEPTANCE, named_wrong_physics, summarise

KINDS = ("single", "pair", "clean", "outside")
"""Case kinds, in the order the tables show them."""
TARGETS = {
    "single": ACCEPTANCE["top1_accuracy_single"],
    "pair": ACCEPTANCE["pair_both_named"],
    "clean": ACCEPTANCE["clean_no_effect_named"],
    "outside": ACCEPTANCE["outside_unexplained_and_located"],
}
"""The share of right cases of each kind the pooled offsets are held to (the benchmark's :data:`ACCEPTANCE`), beside
no false attribution at all."""


def false_attributions(rows: list[dict[str, Any]]) -> list[str]:
    """Cases that named an effect of physics the case's truth does not hold (any kind: a clean case naming anything).

    Each as ``case (offset N)`` where the row carries its ``seed_offset``; ``, truth not ruled out`` where the
    diagnosis listed a model of the truth's physics among those the data do not rule out (``truth_not_ruled_out``).
    """
    out = []
    for r in rows:
        if not named_wrong_physics(r):
            continue
        notes = [f"offset {r['seed_offset']}"] if "seed_offset" in r else []
        notes += ["truth not ruled out"] if r.get("truth_not_ruled_out") else []
        out.append(r["case"] + (f" ({', '.join(notes)})" if notes else ""))
    return out


def counts(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Right cases and cases of each kind, and the false attributions, of a set of case rows."""
    out: dict[str, Any] = {}
    for kind in KINDS:
        sel = [r for r in rows if r["kind"] == kind]
        out[kind] = {"right": sum(bool(r["correct"]) for r in sel), "cases": len(sel)}
    out["false_attributions"] = false_attributions(rows)
    return out


def targets_met(tally: dict[str, Any]) -> dict[str, bool | None]:
    """Whether each kind's share of right cases reaches :data:`TARGETS` (None: no case of it), and no false one."""
    out: dict[str, bool | None] = {
        kind: None if not tally[kind]["cases"] else tally[kind]["right"] >= TARGETS[kind] * tally[kind]["cases"]
        for kind in KINDS
    }
    out["false_attributions"] = not tally["false_attributions"]
    return out


def check_offsets(offsets: Sequence[int]) -> None:
    """Refuse an offset given twice (its runs would share a folder and count twice)."""
    if len(set(offsets)) != len(offsets):
        raise UserError(f"a seed offset repeats: {list(offsets)}")


def run_offsets(
    cases: list[Case], offsets: Sequence[int], out: Path, run: Callable[[list[Case], Path], dict[str, Any]]
) -> dict[str, Any]:
    """Run the benchmark once per seed offset (``run(cases, folder)``, e.g. :func:`run_bench` with its options), pool.

    Returns and writes (``out/bench.json``, ``out/bench.md``) ``{"offsets": {N: counts}, "pooled": counts, "summary":
    the pooled rows' figures}``; each offset's rows carry their ``seed_offset``.
    """
    check_offsets(offsets)
    per: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    for offset in offsets:
        shifted = [dataclasses.replace(c, seed=c.seed + offset) for c in cases]
        result = run(shifted, out / f"offset-{offset}")
        per[str(offset)] = {**counts(result["rows"]), "wall_s": result["summary"]["wall_s"]}
        rows += [{**r, "seed_offset": offset} for r in result["rows"]]
    tally = counts(rows)
    pooled = {
        "offsets": per,
        "pooled": tally,
        "targets": TARGETS,
        "met": targets_met(tally),
        "summary": summarise(rows),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.json").write_text(json.dumps(pooled, indent=2))
    (out / "bench.md").write_text(markdown(pooled))
    return pooled


def markdown(pooled: dict[str, Any]) -> str:
    """Every offset's counts beside the pooled ones."""
    offsets = list(pooled["offsets"])
    columns = [*offsets, "pooled"]
    tallies = [*pooled["offsets"].values(), pooled["pooled"]]

    def share(c: dict[str, int]) -> str:
        return f"{c['right']}/{c['cases']}" + (f" ({100 * c['right'] / c['cases']:.1f} %)" if c["cases"] else "")

    lines = [
        "# Withheld-effect benchmark of the diagnosis over seed offsets",
        "",
        "Each offset's run is in `offset-N/` (its `bench.md` lists every case). Right cases of each kind:",
        "",
        "| figure | "
        + " | ".join(f"offset {c}" if c != "pooled" else "**pooled**" for c in columns)
        + " | target | met |",
        "|---|" + "---|" * (len(columns) + 2),
    ]
    met = targets_met(pooled["pooled"])
    for kind in KINDS:
        cells = " | ".join(share(t[kind]) for t in tallies)
        target = f"{'' if TARGETS[kind] >= 1.0 else '≥ '}{100 * TARGETS[kind]:.0f} %"
        lines.append(f"| {kind} | {cells} | {target} | {met[kind]} |")
    wrong = " | ".join(str(len(t["false_attributions"])) for t in tallies)
    lines.append(f"| false attributions | {wrong} | 0 | {met['false_attributions']} |")
    wrong = pooled["pooled"]["false_attributions"]
    lines += ["", "False attributions (named physics the case's truth does not hold): " + (", ".join(wrong) or "none")]
    flagged = sum("truth not ruled out" in w for w in wrong)
    if wrong:
        lines += [
            "",
            f"In {flagged} of {len(wrong)} the diagnosis listed a model of the true physics as not ruled out (its "
            "report says so; `drillgym separate` gives the holes that would decide).",
        ]
    lines.append("")
    return "\n".join(lines)
