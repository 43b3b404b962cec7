"""Write a diagnosis: ``diagnosis.json``, ``report.md`` and its figures."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from drillgym.envs.effects.registry import EFFECTS
from drillgym.envs.json_safe import json_safe
from drillgym.eval.diagnosis.channels import FORCE, STAGES
from drillgym.eval.diagnosis.context import build, make_spec
from drillgym.eval.diagnosis.diagnose import Diagnosis
from drillgym.eval.diagnosis.figures import plot_gap_map, plot_overlays, plot_ranking, plot_spectra
from drillgym.eval.diagnosis.rank import NAME_CI_LOW_MIN, NAME_SHRINK_MIN, other_physics
from drillgym.eval.diagnosis.replay import Replayer, seed_for
from drillgym.eval.diagnosis.shape import CREATED_MODEL_MIN, CREATED_RATIO_MIN, SHAPE_REMOVE_MIN, SHAPE_SHARE_MIN

OVERLAY_CHANNELS = ["fz_n", "fx_n", "tracker_x_task_m", "q1_rad"]


def write_outputs(
    diag: Diagnosis, out: Path, skipped: list[str] | None = None, figures: bool = True
) -> dict[str, Path]:
    """Write ``diagnosis.json``, ``report.md`` and (optionally) figures into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    res = dict(diag.result)
    res["skipped_logs"] = list(skipped or [])
    paths = {"json": out / "diagnosis.json", "report": out / "report.md"}
    paths["json"].write_text(json.dumps(json_safe(res), indent=2))
    figs: dict[str, Path] = {}
    if figures:
        figs = _figures(diag, out)
    paths["report"].write_text(_markdown(res, figs))
    return {**paths, **figs}


def _figures(diag: Diagnosis, out: Path) -> dict[str, Path]:
    res, data = diag.result, diag.data
    figs = {
        "gap_map": plot_gap_map(res["where"]["all_episodes"], res["where"]["heldout_after"], out / "gap_map.png"),
    }
    if res["effects"]:
        figs["ranking"] = plot_ranking(res["effects"], out / "ranking.png")
    ho = data.ho or list(range(len(data.episodes)))
    i = max(ho, key=lambda k: data.baseline_terms[k].j)
    ep = data.episodes[i]
    rp = Replayer()
    try:
        traces = {"real": ep.lf, "sim (nominal)": data.nominal[i].lf}
        named = next((s for s in diag.scores if s.named), None)
        if named is not None:
            spec = make_spec(named.fit.names, named.fit.params)
            effects = build(spec)
            physics = [e for e in effects if not e.sensor_only]
            trace = rp.run(ep, physics) if physics else data.nominal[i]
            traces[f"sim + {named.name}"] = trace.with_sensor_effects([e for e in effects if e.sensor_only]).lf
        figs["overlays"] = plot_overlays(ep.name, ep.t_s, ep.stage, traces, out / "overlays.png", OVERLAY_CHANNELS)
        null = rp.run(ep, seed=seed_for(ep.name, 99), noise=True, variability=True)
        residuals = {
            "real − sim": ep.lf[:, FORCE] - data.nominal[i].lf[:, FORCE],
            "sim's own (null) − sim": null.lf[:, FORCE] - data.nominal[i].lf[:, FORCE],
        }
        figs["spectra"] = plot_spectra(residuals, out / "spectra.png")
    finally:
        rp.close()
    return figs


def _ratio(gap: float, null: float) -> str:
    """``"12×"``: how many times the simulator's own level a gap is."""
    return f"{gap / null:.3g}×" if null > 0 and math.isfinite(gap) else "–"


def _pct(v: Any) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{100 * v:.0f} %"


INTERVAL_CALIBRATION_EPISODES = 6
"""Calibration episodes behind the parameter intervals and the held-out CIs whose coverage the withheld-effect
benchmark measured (its 12-episode cases, ``docs/diagnosis.md`` §6); fewer get a warning in ``report.md``."""


def at_bound(effect: str, param: str, value: float) -> str | None:
    """``"lower"`` or ``"upper"`` if ``value`` sits at that end of the parameter's search range, else None."""
    spec = next((p for p in getattr(EFFECTS.get(effect), "params", ()) if p.name == param), None)
    if spec is None:
        return None
    tol = 1e-6 * (spec.high - spec.low)
    if value <= spec.low + tol:
        return "lower"
    if value >= spec.high - tol:
        return "upper"
    return None


def param_text(effect: dict[str, Any]) -> str:
    """``"dl_m=-0.00058 [-0.0011, -0.00054]"``: each fitted parameter with its 95 % interval where it has one.

    A value at an end of its search range is flagged (``at its upper bound``): the fit may want a value outside
    the range, so the value is a limit, not an estimate. The lower end is flagged only where it is not the off
    value (0).
    """
    intervals = effect.get("param_intervals") or {}
    parts = []
    for name, vals in effect["params"].items():
        items = []
        for p, v in vals.items():
            ci = (intervals.get(name) or {}).get(p)
            text = f"{p}={v:.3g}" + (f" [{ci['low']:.3g}, {ci['high']:.3g}]" if ci else "")
            end = at_bound(name, p, v)
            if end is not None and not (end == "lower" and v == 0.0):
                text += f" (**at its {end} bound**)"
            items.append(text)
        parts.append(", ".join(items))
    return "; ".join(parts)


def distinct_models(effects: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``effects`` (best first) with one row per set of effects.

    A pair fitted in both orders (``latency+joint_friction``, ``joint_friction+latency``) keeps its better-ranked
    order, or its named one.
    """
    named = {frozenset(e["effects"]) for e in effects if e.get("named")}
    seen: set[frozenset[str]] = set()
    out = []
    for e in effects:
        key = frozenset(e["effects"])
        if key in seen or (key in named and not e.get("named")):
            continue
        seen.add(key)
        out.append(e)
    return out


def episode_warning(res: dict[str, Any]) -> list[str]:
    """A warning paragraph when fewer calibration episodes than :data:`INTERVAL_CALIBRATION_EPISODES` back the figures."""
    n_cal, n_ho = len(res["episodes"]["calibration"]), len(res["episodes"]["heldout"])
    if n_cal >= INTERVAL_CALIBRATION_EPISODES:
        return []
    return [
        "",
        f"> **Few episodes:** {n_cal} calibration and {n_ho} held-out episodes. The parameter intervals and the "
        f"held-out confidence intervals were checked for coverage with {INTERVAL_CALIBRATION_EPISODES} of each "
        f"({2 * INTERVAL_CALIBRATION_EPISODES} episodes); with fewer they are wide or too narrow and the verdict is "
        f"fragile. Log {2 * INTERVAL_CALIBRATION_EPISODES} or more episodes.",
    ]


def why_not_named(effect: dict[str, Any], res: dict[str, Any]) -> str:
    """Why a model ranked above the named one (or any model, when none is named) was not named."""
    names = [e["name"] for e in res["effects"]]
    named = next((n for n, e in zip(names, res["effects"], strict=True) if e["named"]), None)
    if named is not None and names.index(effect["name"]) > names.index(named):
        return ""
    shrink, low = effect["shrink"], effect["ci_low"]
    if not (math.isfinite(shrink) and math.isfinite(low)) or shrink < NAME_SHRINK_MIN or low < NAME_CI_LOW_MIN:
        return f"no: below the bar (shrink ≥ {NAME_SHRINK_MIN:.0%}, CI low ≥ {NAME_CI_LOW_MIN:.0%})"
    shape = effect.get("shape")
    if shape and not shape["passes"]:
        return f"no: not the gap's shape ({shape['reason']})"
    guard = res.get("single_guard") or {}
    if guard.get("contradicted") and guard.get("effect") == effect["name"]:
        return "no: it predicts a change before contact that the data do not show"
    rescue = res.get("rescue") or {}
    if rescue.get("reason") and rescue.get("decided") == effect["name"]:
        return "no: " + rescue["reason"]
    off = res.get("off_point_guard") or []
    if named is None and set(effect["effects"]) & set(off):
        return "no: its parameters' intervals contain the off point (" + ", ".join(off) + ")"
    if named is None:
        return "no: " + str(res["verdict"])
    if set(named.split("+")) < set(effect["effects"]):
        seconds = {p["name"] for p in res.get("possible_second_effects") or []}
        if effect["name"] in seconds:
            return "no: its second effect is not shown to be one (it must explain alone what it adds)"
        return "no: not surely better than the named model"
    if effect["name"] in {a.get("name") for a in res.get("alternatives") or []}:
        return "no: an alternative the data do not rule out"
    return "no: the named model scores better across resamples"


def separate_hint(res: dict[str, Any]) -> list[str]:
    """A paragraph when a model with other physics than the named one is not ruled out: how to plan holes that decide."""
    named = list(res.get("named") or [])
    if not named:
        return []
    others = [a["name"] for a in other_physics(named, res.get("alternatives") or [])]
    if not others:
        return []
    return [
        "",
        f"**Not ruled out, with other physics: {', '.join(others)}.** These logs cannot tell it from "
        f"{'+'.join(res['named'])}; `drillgym separate --diagnosis OUT --real LOGS --out DIR` simulates some of the "
        "logged holes at other feeds and angles with each model as the reality and says where the next holes would tell them "
        "apart (docs/diagnosis.md §4).",
    ]


def per_episode_lines(res: dict[str, Any]) -> list[str]:
    """The per-episode section: each episode's role, specimen hardness and a random effect's own parameters."""
    eps = res["episodes"]
    hardness = eps.get("specimen_hardness_sigma") or {}
    own = res.get("per_episode") or {}
    params = list(own.get("spread") or {})
    lines = ["", "## Per episode", ""]
    if own:
        effect = res["named"][0]
        chosen: dict[str, Any] = next((e["param_intervals"] for e in res["effects"] if e["named"]), {})
        intervals = chosen.get(effect) or {}
        spread = []
        for p in params:
            ci = intervals.get(p + "_spread")
            spread.append(f"{p} {own['spread'][p]:.3g}" + (f" [{ci['low']:.3g}, {ci['high']:.3g}]" if ci else ""))
        lines += [
            f"`{effect}` differs per episode (a random effect around its mean). Spread between episodes (SD, "
            f"95 % CI): {'; '.join(spread)}. The held-out score counts {own['effective_params']:.3g} parameters "
            "for it (mean and spread of each, plus each held-out episode's effective share).",
            "",
        ]
    lines += [
        "| episode | half | specimen hardness (σ) | " + " | ".join(params) + (" |" if params else ""),
        "|---|---|---|" + "---|" * len(params),
    ]
    cal = set(eps["calibration"])
    for name in [*eps["calibration"], *eps["heldout"]]:
        values = own.get("episodes", {}).get(name, {})
        cells = "".join(f" {values[p]:.3g} |" if p in values else " – |" for p in params)
        h = hardness.get(name)
        lines.append(
            f"| {name} | {'calibration' if name in cal else 'held-out'} | {'–' if h is None else f'{h:+.2f}'} |{cells}"
        )
    return lines


def shape_lines(res: dict[str, Any]) -> list[str]:
    """The shape test of every nameable model: the regions it was judged on, passed or refused and why."""
    tested = [e for e in distinct_models(res["effects"]) if e.get("shape")]
    if not tested:
        return []
    lines = [
        "",
        f"Shape test (every nameable model; each region holding ≥ {SHAPE_SHARE_MIN:.0%} of the held-out excess must "
        f"lose ≥ {SHAPE_REMOVE_MIN:.0%} of it under the model; on the raw gap, the model must leave no region at "
        f"{CREATED_MODEL_MIN:g}x the simulator's own level or more and {CREATED_RATIO_MIN:g}x the data's there):",
        "",
    ]
    for e in tested:
        sh = e["shape"]
        regions = "; ".join(
            f"{r['region']}: {_pct(r['share'])} of the excess, {_pct(r['removed'])} removed" for r in sh["regions"]
        )
        verdict = "passes" if sh["passes"] else f"**refused** — {sh['reason']}"
        top = (sh.get("created") or [None])[0]
        raw = f"; raw gap most raised at {top['region']} ({top['before']:.2g}x → {top['after']:.3g}x)" if top else ""
        lines.append(f"* `{e['name']}` {verdict} ({regions or 'no region that large'}{raw})")
    return lines


def _where_lines(res: dict[str, Any]) -> list[str]:
    """The cells holding the most excess gap, after the per-specimen fit and before it (and a note if it moved)."""
    lines = ["", "## Where", ""]
    for cell in res["where"]["largest_excess"]:
        lines.append(f"* {cell['channel']} in stage {cell['stage']}: {_pct(cell['share'])} of the excess gap")
    check = res.get("location_check")
    if check:
        raw = ", ".join(f"{c['channel']} in {c['stage']} ({_pct(c['share'])})" for c in check["raw"])
        lines += ["", f"Before the per-specimen hardness fit (every specimen as preset): {raw or '–'}."]
        if check["note"]:
            lines += ["", f"**The location moved**: {check['note']}."]
    return lines


def _markdown(res: dict[str, Any], figs: dict[str, Path]) -> str:
    sig = res["significance"]
    lines = [
        "# Sim-to-real gap diagnosis",
        "",
        f"**Verdict: `{res['verdict']}`** — {res['summary']}.",
        "",
        f"{res['episodes']['n']} episodes ({len(res['episodes']['calibration'])} calibration, "
        f"{len(res['episodes']['heldout'])} held-out). **The gap is {_ratio(sig['gap'], sig['null'])} the "
        f"simulator's own scatter** (gap {sig['gap']:.3g}, scatter {sig['null']:.3g}; median episode "
        f"{sig['median_episode_ratio']:.3g}×; significant: {sig['significant']}). Gaps are mean squared block-mean "
        "differences in units of the simulator's noise after profiling out each specimen's hardness "
        "(see docs/diagnosis.md).",
        *episode_warning(res),
        *separate_hint(res),
        "",
        "## Which effect",
        "",
        "Rows are ordered by the penalised held-out score (best first); a row above the named model says why "
        "it was not named. A pair fitted in both orders is shown once.",
        "",
        "| rank | model | parameters (95 % CI) | held-out gap before | after | left (× sim) | shrink (95 % CI) | "
        "P(best) | named |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for k, e in enumerate(distinct_models(res["effects"])[:12], 1):
        params = param_text(e)
        left = e.get("leftover_ratio")
        lines.append(
            f"| {k} | {e['name']} | {params} | {e['heldout_gap_before']:.3g} | {e['heldout_gap_after']:.3g} | "
            f"{'–' if left is None or not math.isfinite(left) else f'{left:.3g}'} | "
            f"{_pct(e['shrink'])} ({_pct(e['ci_low'])} to {_pct(e['ci_high'])}) | {e['p_best']:.2f} | "
            f"{'**yes**' if e['named'] else why_not_named(e, res)} |"
        )
    lines += shape_lines(res)
    left = res.get("leftover")
    if left:
        cells = ", ".join(f"{c['channel']} in {c['stage']} ({_pct(c['share'])})" for c in left["cells"])
        named = [e for e in res.get("effects", []) if e.get("named")]
        was = ""
        if named and named[0]["heldout_gap_after"] > 0:
            before_ratio = left["ratio"] * named[0]["heldout_gap_before"] / named[0]["heldout_gap_after"]
            was = f" (before it, the gap was {before_ratio:.3g}× that level)" if math.isfinite(before_ratio) else ""
        lines += [
            "",
            f"Left after the named model: **{left['ratio']:.3g}× the simulator's own level** on the held-out "
            f"episodes{was}, most of it at {cells or '–'}.",
        ]
    search = res.get("leftover_search")
    if search:
        lines += ["", f"Leftover search: {search['note']}."]
    ev = res.get("second_effect_evidence")
    if ev:
        how = ["it explains alone what it adds"] if ev["alone"] else []
        if ev["own_cells"]:
            how.append(
                f"on the {', '.join(ev['own_groups'])} cells only it reaches, the pair brings the gap from "
                f"{ev['own_gap_first']:.3g} (first effect alone) to {ev['own_gap_pair']:.3g} "
                f"(simulator: {ev['own_gap_null']:.3g})"
            )
        lines += ["", f"Second effect `{ev['second']}`: " + "; ".join(how or ["–"]) + "."]
    lines += per_episode_lines(res)
    lines += _where_lines(res)
    lines += ["", f"Stages (estimated from the commanded depth): {', '.join(STAGES)}.", ""]
    fr = res["where"].get("frequency") or {}
    if fr:
        bands = [f"{lo:g}–{hi:g} Hz" for lo, hi in fr["bands_hz"]]
        lines += ["Force residual power, real over the simulator's own (per band):", ""]
        lines += ["| channel | " + " | ".join(bands) + " |", "|---|" + "---|" * len(bands)]
        for ch, row in zip(fr["channels"], fr["ratio"], strict=True):
            cells = " | ".join("–" if v is None or not math.isfinite(v) else f"{v:.3g}×" for v in row)
            lines.append(f"| {ch} | {cells} |")
        lines.append("")
    for key, title in (
        ("gap_map", "Gap map"),
        ("ranking", "Ranking"),
        ("overlays", "Overlays (held-out episode with the largest gap)"),
        ("spectra", "Force residual spectra"),
    ):
        if key in figs:
            lines += [f"### {title}", "", f"![{title}]({figs[key].name})", ""]
    reps = res["episodes"]["repairs"]
    if reps or res.get("skipped_logs"):
        lines += ["## Data", ""]
        lines += [f"* repaired {name}: {'; '.join(r)}" for name, r in reps.items()]
        lines += [f"* skipped {s}" for s in res.get("skipped_logs", [])]
        lines.append("")
    t = res["timing"]
    lines += [
        "## Run",
        "",
        f"{t['total_s']:.0f} s on {t['workers']} worker(s): replays {t['baseline_s']:.0f} s, single fits "
        f"{t['singles_s']:.0f} s, pairs {t['pairs_s']:.0f} s, refining the named model {t.get('polish_s', 0.0):.0f} s "
        f"({t['candidates']} candidates, {t['pairs']} pairs).",
        "",
    ]
    return "\n".join(lines)
