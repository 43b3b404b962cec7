"""From a diagnosis to a training cell: the named effects at their fitted values, their intervals as draw ranges.

``drillgym train --cell-from-diagnosis OUT/diagnosis.json`` diagnoses a real cell, then trains the residual for it:
the effects the diagnosis named (``named`` in ``diagnosis.json``), at the values fitted to the real logs
(``params``), become the cell of training, evaluation and model selection (:class:`drillgym.training.cell.TrainingCell`),
and each parameter's 95 % interval (``param_intervals``) the range a training episode draws it from, so the policy
meets the values the data allow, not only the best fit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drillgym.envs.errors import UserError, read_json
from drillgym.training.cell import TrainingCell, spec_of


def cell_from_diagnosis(path: Path | str) -> TrainingCell:
    """The training cell of a ``diagnosis.json`` (its named model); ``UserError`` when it named nothing.

    A parameter with no interval (held fixed by the search) or a zero-width one is not drawn.
    """
    data = read_json(Path(path))
    if not isinstance(data, dict) or "effects" not in data or "named" not in data:
        raise UserError(f"{path}: not a drillgym diagnosis.json (no 'named' and 'effects')")
    named = list(data["named"])
    if not named:
        raise UserError(
            f"{path}: the diagnosis named no effect (verdict {data.get('verdict')!r}); there is no cell to train for"
        )
    entry = next((e for e in data["effects"] if list(e.get("effects", [])) == named), None)
    if entry is None:
        raise UserError(f"{path}: the named model {'+'.join(named)} is not among its effects")
    values: dict[str, dict[str, float]] = {
        name: {k: float(v) for k, v in entry["params"][name].items()} for name in named
    }
    ranges: dict[str, tuple[float, float]] = {}
    for name, params in (entry.get("param_intervals") or {}).items():
        for param, interval in (params or {}).items():
            if interval and float(interval["high"]) > float(interval["low"]):
                ranges[f"{name}.{param}"] = (float(interval["low"]), float(interval["high"]))
    return TrainingCell(spec_of(values), ranges)


def cell_overrides(path: Path | str) -> dict[str, Any]:
    """``cell`` and ``cell_ranges`` training-configuration overrides from a ``diagnosis.json``."""
    cell = cell_from_diagnosis(path)
    return {"cell": cell.spec, "cell_ranges": {k: list(v) for k, v in cell.ranges.items()}}
