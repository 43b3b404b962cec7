"""The candidate's best equivalent of a reality: what an interval can be checked against.

A candidate of another form than the reality's (a linear drift for an exponential settling, a fixed delay for a
jittered one) has no "true" value in the reality's own terms; what it converges to as the episodes grow is its
**pseudo-true** value: the parameters that fit the reality best within its own form. It is estimated here by
fitting the candidate alone on many fresh episodes of the same reality (:data:`EPISODES`, all of them for the
fit, other seeds than any benchmark case's), with the diagnosis's own search (:func:`fit_model`, then the joint
refit it gives a named model), refined between the evaluated points as the intervals' resamples are. The benchmark scores each named
effect's interval against it beside the reality's written-down value (:meth:`RealityEffect.candidate_values`).
"""

from __future__ import annotations

import json
import tempfile
import zlib
from pathlib import Path
from typing import Any

from drillgym.envs.effects.registry import EFFECTS
from drillgym.envs.errors import UserError
from drillgym.eval.diagnosis.bench.cases import Case
from drillgym.eval.diagnosis.context import DiagnosisData, Evaluator, baseline_job
from drillgym.eval.diagnosis.episodes import load_episodes
from drillgym.eval.diagnosis.fit import fit_model, refit_jointly
from drillgym.eval.diagnosis.intervals import refined_minimum
from drillgym.eval.diagnosis.reality.generate import make_reality
from drillgym.eval.diagnosis.replay import Replayer
from drillgym.eval.pool import run_unordered

EPISODES = 36
"""Fresh episodes of a reality the pseudo-true value is fitted on (three times the benchmark's 12)."""
SEED = 10_000_000
"""Seeds of those episodes start here (plus a checksum of the reality's spec), apart from every case's."""

Job = tuple[str, str, int]
"""``(reality spec, candidate, episodes)``."""


def jobs_for(cases: list[Case], episodes: int = EPISODES) -> list[Job]:
    """One job per single-effect reality whose candidate has written-down values (a reality spec once).

    Not for a random effect's: its mean's truth is the written-down population mean itself, which a fit on other
    episodes would only estimate with their own scatter.
    """
    specs = dict.fromkeys(
        c.spec for c in cases if c.kind == "single" and c.truth_values and not EFFECTS[c.truth[0]].per_episode
    )
    return [(spec, next(c for c in cases if c.spec == spec).truth[0], episodes) for spec in specs]


def pseudo_truth(job: Job) -> tuple[str, dict[str, Any]]:
    """``(spec, {"candidate", "params", "episodes", "seed", "calibration_gap", "error"})`` of one job."""
    spec, candidate, episodes = job

    seed = SEED + zlib.crc32(spec.encode()) % 1_000_000  # the reality's own seed, whatever else is run
    with tempfile.TemporaryDirectory(prefix="drillgym-pseudo-truth-") as tmp:
        make_reality(spec, episodes, seed, Path(tmp) / "logs")
        eps, _ = load_episodes(Path(tmp) / "logs")
    data = DiagnosisData.from_episodes(eps, cal=list(range(len(eps))), ho=[])
    replayer = Replayer()
    data.add_baseline([baseline_job(replayer, ep) for ep in eps])
    ev = Evaluator(data, replayer)
    fit = fit_model(ev, (candidate,))
    refit = refit_jointly(ev, (candidate,), [fit.params])
    if not refit.error and refit.cal_objective <= fit.cal_objective:
        refit.samples = [*fit.samples, *refit.samples]
        fit = refit
    # Refined between the evaluated points, as every resample of an interval is: the search stops at 1/1024 of
    # each range (16 µm of stick-out), coarser than a 36-episode fit is known to.
    params = refined_minimum(fit.samples).get(candidate) or fit.params[0]
    return spec, {
        "candidate": candidate,
        "params": params,
        "searched": fit.params[0],
        "episodes": len(eps),
        "seed": seed,
        "calibration_gap": fit.cal_objective,
        "error": fit.error,
    }


def load_or_compute(path: Path, cases: list[Case], workers: int, episodes: int = EPISODES) -> dict[str, Any]:
    """The pseudo-true values of ``cases``' realities: read from ``path``, the missing ones computed and added."""
    table = _read(path) if path.is_file() else {}
    todo = [j for j in jobs_for(cases, episodes) if j[0] not in table]
    for _, (spec, entry) in run_unordered(pseudo_truth, todo, max(1, workers)):
        table[spec] = entry
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(table, indent=2))  # written as each finishes: an interruption loses nothing
    return table


def _read(path: Path) -> dict[str, Any]:
    """A table written by :func:`load_or_compute`; ``ValueError`` naming the file if it is not one."""
    try:
        table = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise UserError(f"{path}: not a pseudo-truth table ({e}); name another file or delete it") from e
    entries = table.values() if isinstance(table, dict) else []
    if not isinstance(table, dict) or not all(
        isinstance(v, dict) and isinstance(v.get("candidate"), str) and isinstance(v.get("params"), dict)
        for v in entries
    ):
        raise UserError(f"{path}: not a pseudo-truth table (entries need 'candidate' and 'params')")
    return table
