"""Composed configuration: one validated frozen dataclass per system, built of parts declared once where they belong.

A system's configuration is composed, not re-listed: the simulator's configuration (e.g.
:class:`robofdi.sims.arm.ArmPlant`), the nominal model's mismatch (:class:`robofdi.models.ModelMismatch`), the
mission draw and the diagnosis settings are each a dataclass of their own, and a configuration holds them as
*parts* (fields declared with :func:`part`). Each default lives in one place, the part that owns it.

Two functions read and change a composed configuration with one rule, so a campaign's ``[system]`` table, keyword
arguments and the command line all name fields the same way:

- :func:`compose` builds one from a mapping in which every field is given either *nested* (a table named after
  the part: ``{"plant": {"robot": "ur5e.xml"}}``) or *flat* (by its own name, ``{"robot": "ur5e.xml"}``): a flat
  name belongs to the configuration's own field of that name, else to the one part (at any depth) that declares
  it; a name two parts declare must be given nested. Unknown names are refused with the names accepted.
- :func:`evolve` is :func:`dataclasses.replace` with the same routing: ``evolve(scenario, robot="ur5e.xml")``.

Given values start from the part's declared default (the part instance the configuration would hold), not from
the part type's own defaults, so ``compose(ArmOptions, {"mass": 0.05})`` changes one field of the arm's mismatch.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import MISSING, field, fields, is_dataclass, replace
from typing import Any, TypeVar

from robofdi.errors import RobofdiError

__all__ = ["part", "parts", "accepted", "compose", "evolve", "check_not_set"]

T = TypeVar("T")


def part(kind: type, default: Callable[[], Any] | None = None):
    """A field holding a part of a composed configuration: a dataclass of type ``kind``, by default ``kind()`` (or
    ``default()``)."""
    return field(default_factory=default or kind, metadata={"part": kind})


def parts(cls_or_obj) -> dict[str, type]:
    """The parts of a composed configuration class (or instance): field name → part type."""
    return {f.name: f.metadata["part"] for f in fields(cls_or_obj) if "part" in f.metadata}


def accepted(cls: type) -> dict[str, tuple[str, ...]]:
    """Every name :func:`compose` accepts for ``cls`` → the path of fields it sets (own fields first, then each
    part's names, flat; a name several parts declare maps to ``()``, i.e. it must be given nested)."""
    names: dict[str, tuple[str, ...]] = {f.name: (f.name,) for f in fields(cls)}
    owners: dict[str, list[tuple[str, ...]]] = {}
    for name, kind in parts(cls).items():
        for inner, path in accepted(kind).items():
            owners.setdefault(inner, []).append((name, *path) if path else ())
    for inner, paths in owners.items():
        if inner not in names:
            names[inner] = paths[0] if len(paths) == 1 and paths[0] else ()
    return names


def _default(cls: type, name: str):
    f = next(f for f in fields(cls) if f.name == name)
    return f.default_factory() if f.default_factory is not MISSING else f.default


def _tuples(v):
    return tuple(_tuples(x) for x in v) if isinstance(v, list) else v


def _route(cls: type, values: Mapping, where: str) -> tuple[dict, dict[str, dict]]:
    """Split ``values`` into (own field values, {part name: its values}) by :func:`accepted`'s rule."""
    own_names = {f.name for f in fields(cls)}
    kinds = parts(cls)
    names = accepted(cls)
    own: dict = {}
    nested: dict[str, dict] = {}
    for key, value in values.items():
        if key in kinds and isinstance(value, Mapping):
            nested.setdefault(key, {}).update(value)
        elif key in own_names:
            own[key] = _tuples(value)
        elif key in names and names[key]:
            path = names[key]
            target = nested.setdefault(path[0], {})
            for step in path[1:-1]:
                target = target.setdefault(step, {})
            target[path[-1]] = _tuples(value)
        elif key in names:
            holders = [p for p, k in kinds.items() if key in accepted(k)]
            raise RobofdiError(f"{where}: field {key!r} is declared by several parts ({', '.join(holders)}); give it "
                               f"nested, e.g. {holders[0]}.{key}")
        else:
            known = sorted(n for n, p in names.items() if p)
            raise RobofdiError(f"{where}: unknown field {key!r}; expected some of {', '.join(known)}")
    return own, nested


def _evolve_part(base, values: Mapping, where: str, label: str | None = None):
    """``base`` (a part instance) with ``values`` routed into it; the part's own errors are reported as
    ``label`` (e.g. ``system.plant: field 'robot' …``)."""
    own, nested = _route(type(base), values, where)
    for name, inner in nested.items():
        own[name] = _evolve_part(own.get(name, getattr(base, name)), inner, where, f"{label or where}.{name}")
    try:
        return replace(base, **own)
    except RobofdiError as exc:
        owner = f"{type(base).__name__}: "
        if label and str(exc).startswith(owner):
            raise RobofdiError(f"{label}: {str(exc)[len(owner):]}") from None
        raise


def compose(cls: type[T], values: Mapping | None = None, where: str | None = None, **kwargs) -> T:
    """A ``cls`` from flat or nested ``values`` (and keyword arguments, the same rule), each part starting from
    its declared default. Errors name ``where`` (default: the class name) and the field."""
    where = where or cls.__name__
    if not is_dataclass(cls):
        raise RobofdiError(f"{where}: not a configuration dataclass")
    own, nested = _route(cls, {**(values or {}), **kwargs}, where)
    for name, inner in nested.items():
        base = own.get(name, _default(cls, name))
        own[name] = _evolve_part(base, inner, where, f"{where}.{name}")
    return cls(**own)


def evolve(obj: T, **changes) -> T:
    """``obj`` with ``changes``, each named flat or nested as in :func:`compose` (a new, validated instance)."""
    return _evolve_part(obj, changes, type(obj).__name__)


def check_not_set(where: str, obj, default, names, why: str) -> None:
    """Refuse fields of ``obj`` among ``names`` that differ from ``default``'s: values that are not options (a
    campaign draws or calibrates them), ``where: field 'f' is not an option: why``."""
    for name in names:
        if getattr(obj, name) != getattr(default, name):
            raise RobofdiError(f"{where}: field {name!r} is not an option: {why}")
