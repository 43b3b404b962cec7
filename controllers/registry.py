"""Controller specs: ``name[:field=value,...]`` -> a configured controller.

Every spec also takes the slow-entry fields (:data:`drillgym.controllers.feed_schedule.SCHEDULE_FIELDS`), which
put an entry feed schedule on top of the controller, and the contact-registration fields
(:data:`drillgym.controllers.contact_registration.REGISTRATION_FIELDS`), which re-index it at the measured contact;
a name may be a preset (:data:`PRESETS`): a
named spec whose fields a user's own fields override.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Callable, Mapping
from importlib.metadata import entry_points
from types import MappingProxyType
from typing import Any

from drillgym.controllers.base import Controller
from drillgym.controllers.contact_registration import REGISTRATION_FIELDS, ContactRegistered, ContactRegistration
from drillgym.controllers.feed_schedule import SCHEDULE_FIELDS, EntryFeedSchedule, SlowEntry
from drillgym.controllers.li2023 import Li2023Config, Li2023Controller
from drillgym.controllers.li2023_cmrr import Li2023CmrrConfig, Li2023CmrrController
from drillgym.controllers.none import NoCompensation, NoCompensationConfig
from drillgym.controllers.zhang2005 import Zhang2005Config, Zhang2005Controller
from drillgym.envs.errors import UserError
from drillgym.envs.key_values import convert, split_items, split_named

CONTROLLERS: dict[str, tuple[Callable[[Any], Controller], type]] = {
    "none": (NoCompensation, NoCompensationConfig),
    "li2023": (Li2023Controller, Li2023Config),
    "zhang2005": (Zhang2005Controller, Zhang2005Config),
    "li2023_cmrr": (Li2023CmrrController, Li2023CmrrConfig),
}
"""name -> (class, config dataclass)."""

_TUNED = "li2023:kp=3,y_gain=1.3,entry_feed_scale=0.45,entry_depth_mm=1.25"
PRESETS: dict[str, str] = {
    "li2023_slow_entry": "li2023:kp=3,entry_feed_scale=0.4,entry_depth_mm=1",
    "li2023_tuned": _TUNED,
    "li2023_registered": _TUNED + ",register_contact=1",
}
"""Named specs, each tuned on the paper and sweep suites only (``docs/controllers.md``, ``drillgym tune-entry``).
``li2023_slow_entry``: li2023 with a slow entry and its proportional gain tuned together (round 2).
``li2023_tuned``, the strongest classical baseline: the same with a stronger correction across the plane of
inclination (``y_gain``) tuned with the schedule (round 3). ``li2023_registered``: ``li2023_tuned`` with contact
registration (:mod:`drillgym.controllers.contact_registration`), which tunes nothing."""

BEST_CLASSICAL = "li2023_tuned"
"""The strongest classical baseline: the default a learnt policy is judged against."""


LOADER_GROUP = "drillgym.controllers"
"""Entry-point group of third-party controller loaders: ``NAME = "module:function"``, where ``function(rest)``
builds the controller of the spec ``NAME:rest`` (the text after the colon, unparsed)."""
BUILTIN_LOADERS: dict[str, str] = {
    "table": "drillgym.controllers.schedule_table:load_table_controller",
    "registered": "drillgym.controllers.registry:load_registered_controller",
}
"""Loaders of this package, ``name -> "module:function"`` (imported when a spec uses them)."""
NEEDS_IMPORT: dict[str, str] = {"residual": "drillgym.training"}
"""Loaders that a package registers when it is imported (:func:`register_loader`), named in the error when a spec
uses one before its package was imported (``drillgym.eval`` and the ``drillgym`` command import them all)."""
_registered: dict[str, str] = {}
_merged: dict[str, str] | None = None
"""Every loader by name, merged once (:func:`loaders`); :func:`register_loader` drops it."""


def register_loader(name: str, target: str) -> None:
    """Build ``name:rest`` specs with ``target`` (``"module:function"``; ``function(rest)`` returns the controller).

    A package above this one registers its own family when it is imported (``drillgym.training`` registers
    ``residual``), so the registry never imports upward; a loader registered here wins over an entry point.
    """
    global _merged
    module, _, function = target.partition(":")
    if not module or not function:
        raise ValueError(f"loader target {target!r}: expected 'module:function'")
    _registered[name] = target
    _merged = None


@functools.cache
def _entry_point_loaders() -> dict[str, str]:
    return {ep.name: ep.value for ep in entry_points(group=LOADER_GROUP)}


def loaders() -> Mapping[str, str]:
    """Controller loaders by name, ``"module:function"``: entry points, this package's, then registered ones (read-only)."""
    global _merged
    if _merged is None:
        _merged = {**_entry_point_loaders(), **BUILTIN_LOADERS, **_registered}
    return MappingProxyType(_merged)


def _load(target: str) -> Callable[[str], Controller]:
    module, _, function = target.partition(":")
    loader: Callable[[str], Controller] = getattr(importlib.import_module(module), function)
    return loader


def parse_spec(spec: str) -> tuple[str, dict[str, str]]:
    """Split ``"li2023:kp=1.0,ki=0.5"`` into ``("li2023", {"kp": "1.0", "ki": "0.5"})``.

    The text after a loader's name (``residual:PATH``) is its own and is not split.
    """
    name, rest = split_named(spec)
    if name in loaders() or name in NEEDS_IMPORT:
        return name, {}
    return name, split_items(rest, f"controller spec {spec!r}")


def make_controller(spec: str) -> Controller:
    """Build a controller from a spec; unknown names or fields raise ``ValueError`` listing the options."""
    name, overrides = parse_spec(spec)
    if name in PRESETS:
        name, preset = parse_spec(PRESETS[name])
        overrides = {**preset, **overrides}
    if name in loaders():
        return _load(loaders()[name])(spec.strip().partition(":")[2])
    if name in NEEDS_IMPORT:
        package = NEEDS_IMPORT[name]
        raise UserError(f"{name}:... controllers are registered by {package}: import {package} first")
    if name not in CONTROLLERS:
        plugins = " or ".join(f"{n}:..." for n in sorted(loaders()))
        raise UserError(
            f"unknown controller {name!r}; choose from {sorted([*CONTROLLERS, *PRESETS])}{' or ' if plugins else ''}{plugins}"
        )
    cls, cfg_cls = CONTROLLERS[name]
    schedule = {k: overrides.pop(k) for k in SCHEDULE_FIELDS if k in overrides}
    registration = {k: overrides.pop(k) for k in REGISTRATION_FIELDS if k in overrides}
    controller: Controller = cls(_build(name, cfg_cls, overrides))
    if schedule:
        entry = _build(name, EntryFeedSchedule, schedule)
        if entry.active:
            controller = SlowEntry(controller, entry)
    if registration:
        contact = _build(name, ContactRegistration, registration)
        if contact.register_contact:
            controller = ContactRegistered(controller, contact)
    return controller


def _build(name: str, cfg_cls: type, overrides: dict[str, str]) -> Any:
    """``cfg_cls`` with the overrides converted to its fields' types; clear errors for unknown or bad fields."""
    fields = {f.name: f for f in dataclasses.fields(cfg_cls)}
    kwargs = {}
    for key, raw in overrides.items():
        if key not in fields:
            raise UserError(
                f"{name} has no parameter {key!r}; parameters: {sorted([*fields, *SCHEDULE_FIELDS, *REGISTRATION_FIELDS])}"
            )
        try:
            kwargs[key] = convert(key, raw, fields[key].type)
        except ValueError as e:
            raise UserError(f"{name}: {e}") from e
    try:
        return cfg_cls(**kwargs)
    except ValueError as e:
        raise UserError(f"{name}: {e}") from e


def load_registered_controller(rest: str) -> ContactRegistered:
    """``registered:SPEC`` -> the controller of ``SPEC`` with contact registration (its default fields) on top.

    For the families whose spec takes no fields (``residual:PATH``, ``table:PATH``); a field spec takes
    ``register_contact=1`` instead (:func:`drillgym.controllers.make_controller`).
    """
    if not rest.strip():
        raise UserError("registered: needs the controller to register, e.g. registered:residual:shipped")
    base = make_controller(rest)
    if isinstance(base, ContactRegistered):
        raise UserError(f"{rest!r} already registers its contact")
    return ContactRegistered(base, ContactRegistration(register_contact=True))
