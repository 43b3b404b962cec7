"""Named cells: effect bundles that make the simulated cell behave like a particular real one.

* ``ideal``: no unmodelled effect (the default env).
* ``li2023-lab``: the effect that best explains Li et al. 2023's compensated runs, fitted on his
  uncompensated and KP 1 runs only (``drillgym explain-paper``, ``docs/explain-paper.md``).

Use ``drillgym bench --cell li2023-lab`` or ``env.unwrapped.set_effects(build_effects(CELLS["li2023-lab"]))``.
"""

from __future__ import annotations

from drillgym.envs.errors import UserError

CELLS: dict[str, str] = {
    "ideal": "",
    "li2023-lab": "joint_friction:coulomb_rad=0.000417",
}
"""Cell name -> effect spec (:func:`drillgym.envs.effects.registry.build_effects`)."""


def cell_effects_spec(name: str) -> str:
    """The effect spec of cell ``name``: a named cell's, or ``name`` itself when it is an effect spec.

    Raises ``UserError`` listing the cells when ``name`` is neither (an effect spec names an effect of the library,
    :data:`drillgym.envs.effects.registry.EFFECTS`, e.g. ``joint_friction:coulomb_rad=4e-4``, the ``cell`` of a
    run trained for a diagnosed cell).
    """
    if name in CELLS:
        return CELLS[name]
    from drillgym.envs.effects.registry import build_effects  # it imports every effect; this module, none

    try:
        build_effects(name)
    except UserError as e:
        raise UserError(f"unknown cell {name!r}; choose from {', '.join(CELLS)}, or give an effect spec ({e})") from e
    return name
