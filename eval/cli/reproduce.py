"""``drillgym reproduce``: the paper-reproduction report (Li et al. 2023, with Zhang et al. 2005's claims).

Runs every experiment behind DESIGN's reproduction table in the simulated cell, writes
``OUT/report.md``, ``OUT/reproduction.json`` (rows ``{"name", "unit", "paper", "sim", "rel_err", ...}``) and
the figures. The calibration (uncompensated run) and the predictions (compensated runs) are marked as
such. Sequential and seeded: the same command gives the same numbers.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from drillgym.controllers.registry import BEST_CLASSICAL
from drillgym.envs.errors import UserError, read_json
from drillgym.eval.bench.summary import mean_ci
from drillgym.eval.reproduce.experiments import (
    KP_SWEEP,
    Condition,
    force_model_trends,
    run_condition,
    sim_trends,
    stiffness_identification,
)
from drillgym.eval.reproduce.paper import LI2023_COMPENSATED, LI2023_UNCOMPENSATED


def shipped_policy() -> Path:
    """The headline policy shipped with the package (``residual:shipped``), shown beside the paper's controllers."""
    from drillgym.training.policy_bundle import resolve_policy

    return resolve_policy("shipped")


LEARNED_LABEL = "learned schedule on li2023_tuned (shipped policy)"
"""How the reproduction names the shipped policy's rows."""

PAPER = {
    "dev_none": LI2023_UNCOMPENSATED["deviation_mean_mm"],
    "dev_kp1": LI2023_COMPENSATED["deviation_mean_mm_kp1"],
    "dev_kp4": LI2023_COMPENSATED["deviation_mean_mm"],
    "force_max_none": LI2023_UNCOMPENSATED["lateral_force_max_n"],
    "force_max_comp": LI2023_COMPENSATED["lateral_force_max_n"],
    "force_stable_none": LI2023_UNCOMPENSATED["lateral_force_stable_n"],
    "force_stable_comp": LI2023_COMPENSATED["lateral_force_stable_n"],
    "hole_none": LI2023_UNCOMPENSATED["hole_offset_mm"],
    "hole_comp": LI2023_COMPENSATED["hole_offset_mm"],
}


@dataclass
class Row:
    """One line of reproduction.json."""

    name: str
    unit: str
    paper: float | None
    sim: float
    kind: str
    """``calibration`` (fitted to it), ``prediction`` (not fitted), or ``check`` (physics/identification)."""
    ci: tuple[float, float] | None = None
    note: str = ""
    rel_err: float | None = field(init=False)

    def __post_init__(self) -> None:
        self.rel_err = None if not self.paper else (self.sim - self.paper) / self.paper

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "name": self.name,
            "unit": self.unit,
            "paper": self.paper,
            "sim": self.sim,
            "rel_err": self.rel_err,
            "kind": self.kind,
            "ci95": list(self.ci) if self.ci else None,
            "note": self.note,
        }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", type=Path, default=Path("results/reproduce"), help="output folder")
    parser.add_argument("--seeds", type=int, default=10, help="seeds per compared condition (default 10)")
    parser.add_argument("--quick", action="store_true", help="3 seeds and a short KP sweep (for tests)")
    parser.add_argument(
        "--explanation",
        type=Path,
        default=None,
        help="explanation.json of drillgym explain-paper for the report's section on it (default: OUT/explanation.json if present)",
    )


def _metric(results: list, name: str) -> tuple[float, float, float]:
    mean, lo, hi, _ = mean_ci([r.metrics[name] for r in results])
    return mean, lo, hi


def _paired(a: list, b: list, name: str) -> tuple[float, float, float]:
    mean, lo, hi, _ = mean_ci([x.metrics[name] - y.metrics[name] for x, y in zip(a, b, strict=True)])
    return mean, lo, hi


def run(args: argparse.Namespace) -> int:
    """Run the experiments, write the report, print the headline table."""
    from drillgym.eval.reproduce.figures import write_figures
    from drillgym.eval.reproduce.report import headline, write_report

    if args.seeds < 2:
        raise UserError(f"--seeds={args.seeds} must be >= 2 (confidence intervals need two)")
    given = getattr(args, "explanation", None)  # other commands (demo) build their own arguments
    explanation_path = given if given is not None else args.out / "explanation.json"
    if given is not None and not explanation_path.is_file():
        raise FileNotFoundError(f"--explanation {explanation_path}: no such file")
    explanation = read_json(explanation_path) if explanation_path.is_file() else None
    seeds = list(range(3 if args.quick else args.seeds))
    kp_values = KP_SWEEP[::2] if args.quick else KP_SWEEP
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)

    conditions = {
        "none": Condition("paper", {}, "none"),
        "kp4": Condition("paper", {}, "li2023"),
        "kp1": Condition("paper", {}, "li2023:kp=1.0"),
        "best_classical": Condition("paper", {}, BEST_CLASSICAL),
        "thrust_none": Condition("thrust", {"beta_deg": 0.0, "feed_mm_s": 1.25, "bone": "human_femur"}, "none"),
        "thrust_zhang": Condition(
            "thrust", {"beta_deg": 0.0, "feed_mm_s": 1.25, "bone": "human_femur"}, "zhang2005:cmrr=false"
        ),
        "mrr_none": Condition("layered", {"beta_deg": 0.0, "cortical_thickness_mm": 2.0, "depth_mm": 10.0}, "none"),
        "mrr_zhang": Condition(
            "layered", {"beta_deg": 0.0, "cortical_thickness_mm": 2.0, "depth_mm": 10.0}, "zhang2005:deformation=false"
        ),
    }
    policy = shipped_policy()
    if policy.exists():
        conditions["residual"] = Condition("paper", {}, f"residual:{policy}")
    for kp in kp_values:
        conditions[f"sweep_kp{kp:g}"] = Condition("paper", {}, f"li2023:kp={kp:g}")
    results: dict[str, list] = {}
    bar = tqdm(total=len(conditions) * len(seeds), desc="reproduce", unit="ep", disable=None)
    for key, cond in conditions.items():
        results[key] = run_condition(cond, seeds, keep_hole=key in ("none", "kp4"), progress=bar)
    bar.close()
    trends = force_model_trends()
    sim = sim_trends(seeds[:2], progress=None)
    ident = stiffness_identification()

    rows = _rows(results, trends, ident)
    (out / "reproduction.json").write_text(json.dumps([r.to_dict() for r in rows], indent=2))
    figures = write_figures(out, results, trends, ident, kp_values, sim)
    write_report(out, rows, results, trends, ident, figures, seeds, kp_values)
    from drillgym.eval.explain.report import reproduction_section

    section = reproduction_section(explanation, str(explanation_path) if explanation else "")
    report = out / "report.md"
    report.write_text(report.read_text() + "\n" + "\n".join(section) + "\n")
    print(headline(rows))
    print(f"\nReport: {(out / 'report.md').resolve()}  (reproduction.json and {len(figures)} figures beside it)")
    return 0


def _rows(results: dict[str, list], trends: dict[str, Any], ident: dict[str, Any]) -> list[Row]:
    rows: list[Row] = []
    none, kp4, kp1 = results["none"], results["kp4"], results["kp1"]

    def m(res: list, name: str) -> tuple[float, tuple[float, float]]:
        mean, lo, hi = _metric(res, name)
        return mean, (lo, hi)

    for key, metric, unit, label in (
        ("dev_none", "deviation_mean_mm", "mm", "mean tip deviation, uncompensated"),
        ("force_max_none", "lateral_force_max_n", "N", "max lateral force, uncompensated"),
        ("force_stable_none", "lateral_force_stable_n", "N", "stable-stage lateral force, uncompensated"),
        ("hole_none", "hole_offset_mm", "mm", "entry-hole centre offset, uncompensated"),
    ):
        v, ci = m(none, metric)
        rows.append(Row(label, unit, PAPER[key], v, "calibration", ci))
    v, ci = m(kp1, "deviation_mean_mm")
    rows.append(Row("mean tip deviation, li2023 KP = 1", "mm", PAPER["dev_kp1"], v, "prediction", ci))
    v, ci = m(kp4, "deviation_mean_mm")
    rows.append(Row("mean tip deviation, li2023 KP = 4", "mm", PAPER["dev_kp4"], v, "prediction", ci))
    red = [
        1.0 - a.metrics["deviation_mean_mm"] / b.metrics["deviation_mean_mm"] for a, b in zip(kp4, none, strict=True)
    ]
    mean, lo, hi, _ = mean_ci(red)
    rows.append(Row("deviation reduction, KP = 4 vs none", "%", 56.6, 100 * mean, "prediction", (100 * lo, 100 * hi)))
    for key, metric, unit, label in (
        ("force_max_comp", "lateral_force_max_n", "N", "max lateral force, li2023 KP = 4"),
        ("force_stable_comp", "lateral_force_stable_n", "N", "stable-stage lateral force, li2023 KP = 4"),
        ("hole_comp", "hole_offset_mm", "mm", "entry-hole centre offset, li2023 KP = 4"),
    ):
        v, ci = m(kp4, metric)
        note = "Li's own numbers: 1.3 N x (1 - 0.385) = 0.80 N, not 0.7 N" if key == "force_max_comp" else ""
        rows.append(Row(label, unit, PAPER[key], v, "prediction", ci, note))
    v, ci = m(kp1, "lateral_force_max_n")
    rows.append(Row("max lateral force, li2023 KP = 1", "N", None, v, "prediction", ci))
    best_note = "beyond the paper: li2023 with a slow entry and its gains tuned on the paper and sweep suites"
    b = BEST_CLASSICAL
    for key, metric, unit, label, note in (
        ("best_classical", "deviation_mean_mm", "mm", f"mean tip deviation, {b} (best classical baseline)", best_note),
        ("best_classical", "lateral_force_max_n", "N", f"max lateral force, {b}", best_note),
        ("best_classical", "hole_offset_mm", "mm", f"entry-hole centre offset, {b}", best_note),
        ("best_classical", "drill_time_s", "s", f"drill time, {b}", best_note),
        ("kp4", "drill_time_s", "s", "drill time, li2023 KP = 4", ""),
    ):
        v, ci = m(results[key], metric)
        rows.append(Row(label, unit, None, v, "baseline", ci, note))
    if "residual" in results:
        for metric, unit, label in (
            ("deviation_mean_mm", "mm", f"mean tip deviation, {LEARNED_LABEL}"),
            ("lateral_force_max_n", "N", f"max lateral force, {LEARNED_LABEL}"),
            ("hole_offset_mm", "mm", f"entry-hole centre offset, {LEARNED_LABEL}"),
            ("drill_time_s", "s", f"drill time, {LEARNED_LABEL}"),
        ):
            v, ci = m(results["residual"], metric)
            rows.append(Row(label, unit, None, v, "learned", ci, "beyond the paper: trained in the sim"))
    rows.append(
        Row("four-stage curve: stage of the peak (model, tip on axis)", "stage", 2, trends["peak_stage"], "check")
    )
    rows.append(Row("four-stage curve: stage-4 force / peak (model)", "-", 0.0, trends["stage4_ratio"], "check"))
    rows.append(Row("max force vs beta below 20 deg: R^2 of a line (model)", "-", None, trends["beta_r2"], "check"))
    rows.append(
        Row("max force vs beta: slope above / below 20 deg (model)", "-", None, trends["beta_slope_ratio"], "check")
    )
    rows.append(Row("max force vs feed: R^2 of a line (model)", "-", None, trends["feed_r2"], "check"))
    rows.append(
        Row(
            "robot-stiffness deflection: max |error| at 3 poses (Table 1)",
            "mm",
            0.15,
            ident["table1_max_err_mm"],
            "check",
        )
    )
    for j in range(3):
        rows.append(
            Row(
                f"identified K_theta{j + 1}",
                "kN m/rad",
                ident["truth_knm"][j],
                ident["estimate_knm"][j],
                "check",
                tuple(ident["ci_knm"][j]),
            )
        )
    thr_none, thr_zhang = results["thrust_none"], results["thrust_zhang"]
    red = [
        1 - a.metrics["deviation_mean_mm"] / b.metrics["deviation_mean_mm"]
        for a, b in zip(thr_zhang, thr_none, strict=True)
    ]
    mean, lo, hi, _ = mean_ci(red)
    rows.append(
        Row(
            "Zhang: deviation reduction by deformation compensation under high thrust",
            "%",
            80.0,
            100 * mean,
            "prediction",
            (100 * lo, 100 * hi),
            "Zhang: milling surface error 0.5 mm -> < 0.1 mm",
        )
    )
    mrr_none, mrr_zhang = results["mrr_none"], results["mrr_zhang"]
    saving = [
        1 - a.metrics["drill_time_s"] / b.metrics["drill_time_s"] for a, b in zip(mrr_zhang, mrr_none, strict=True)
    ]
    mean, lo, hi, _ = mean_ci(saving)
    rows.append(
        Row(
            "Zhang: drill-time saving by controlled MRR (cortical 2 mm + cancellous)",
            "%",
            40.0,
            100 * mean,
            "prediction",
            (100 * lo, 100 * hi),
            "Zhang: cycle time down 30-50 %",
        )
    )
    thrust_ratio = max(r.metrics["thrust_max_n"] for r in mrr_zhang) / 8.0
    rows.append(Row("Zhang: max thrust / reference under controlled MRR", "-", 1.0, thrust_ratio, "prediction"))
    return [r for r in rows if not (isinstance(r.sim, float) and math.isnan(r.sim))]


def paired_summary(a: list, b: list, name: str) -> tuple[float, float, float]:
    """Mean and 95% CI of ``a - b`` paired by seed (for the report)."""
    return _paired(a, b, name)


__all__ = ["PAPER", "Row", "add_arguments", "paired_summary", "run"]
