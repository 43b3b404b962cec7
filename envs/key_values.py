"""The one ``key=value`` grammar of drillgym's specs: ``name:key=value,key=value``.

Controllers (``li2023:kp=3,y_gain=1.3``; a list of them is comma-separated too, :func:`split_spec_list`), effects (``ft_drift:rate_n_s=0.01+ft_gain:gain=1.05``, joined by ``+``)
and scenarios (``beta_deg=20,bone=sawbones``) all use it. The values stay text here; each user converts them
to its fields' types with :func:`convert`, so a bad value is reported with its field's name.
"""

from __future__ import annotations

from typing import Any

from drillgym.envs.errors import UserError

TRUE_WORDS = ("1", "true", "yes", "on")
FALSE_WORDS = ("0", "false", "no", "off")


def split_items(text: str, what: str) -> dict[str, str]:
    """``"a=1, b = x"`` -> ``{"a": "1", "b": "x"}`` (keys and values stripped; an empty text gives ``{}``).

    Raises:
        ValueError: ``"{what}: expected key=value, got {item!r}"`` for an item without ``=`` or without a key.
    """
    items: dict[str, str] = {}
    if not text.strip():
        return items
    for item in text.split(","):
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise UserError(f"{what}: expected key=value, got {item!r}")
        items[key.strip()] = value.strip()
    return items


def split_spec_list(text: str, what: str, noun: str = "name", example: str = "") -> list[str]:
    """``"none,li2023:kp=1,ki=0.5,li2023"`` -> ``["none", "li2023:kp=1,ki=0.5", "li2023"]``.

    A ``key=value`` item without a name before it continues the spec before it.

    Args:
        text: the comma-separated specs.
        what: the option they came with, for the errors (e.g. ``"--controllers"``).
        noun: what the first item lacks when it is a ``key=value`` item (``"controller name"``).
        example: a good value, shown when the list is empty.

    Raises:
        ValueError: the list is empty, or starts with a ``key=value`` item.
    """
    specs: list[str] = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        if "=" in item and ":" not in item:
            if not specs:
                raise UserError(f"{what} {text!r}: {item!r} has no {noun} before it")
            specs[-1] += "," + item
        else:
            specs.append(item)
    if not specs:
        raise UserError(f"{what} is empty" + (f"; e.g. {what} {example}" if example else ""))
    return specs


def split_named(spec: str) -> tuple[str, str]:
    """``"name:rest"`` -> ``("name", "rest")``, both stripped (``rest`` is ``""`` without a colon)."""
    name, _, rest = spec.strip().partition(":")
    return name.strip(), rest.strip()


def convert(name: str, raw: str, kind: Any) -> Any:
    """``raw`` as the type ``kind`` (``bool``, ``int``, ``float``, ``str`` or their names); other types stay text.

    Raises:
        ValueError: ``"{name}={raw!r} is not a boolean"`` (or a number, an integer).
    """
    kind = kind if isinstance(kind, type) else str(kind)
    if kind in (bool, "bool"):
        if raw.lower() in TRUE_WORDS:
            return True
        if raw.lower() in FALSE_WORDS:
            return False
        raise UserError(f"{name}={raw!r} is not a boolean")
    try:
        if kind in (int, "int"):
            return int(raw)
        if kind in (float, "float"):
            return float(raw)
    except ValueError as e:
        noun = "an integer" if kind in (int, "int") else "a number"
        raise UserError(f"{name}={raw!r} is not {noun}") from e
    return raw
