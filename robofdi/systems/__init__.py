"""Systems: one module per plant family, the only place that knows it; and the registry that finds them.

A system module holds the system's configuration (a validated dataclass, declared once), how its parts are built
and calibrated (through :mod:`robofdi.calibration`), its campaign face (fault targets with their limits, missions
drawn from a seed) and its runs (→ :class:`~robofdi.record.Record`). The protocol is
:class:`robofdi.protocols.System`. Shipped systems: ``arm`` (any MJCF arm), ``auv``, ``hydraulic``, ``linear``,
``helicopter``, ``robosuite-lift``, ``dm_control-cartpole``; the book's and papers' other plants (aircraft, F-16,
refiner, the linearised arm) live here as scenario modules of their experiments.

Registering a system of your own (the CLI and campaigns then find it by name)::

    from robofdi.systems import register_system

    @register_system
    class MySystem:
        name = "my-plant"
        options_type = MyOptions
        ...

It is found when its module has been imported; for an installed package, declare the module (or the class) as
an entry point of the group ``robofdi.systems`` in its pyproject.toml::

    [project.entry-points."robofdi.systems"]
    my-plant = "my_package.my_system"

or name it directly as ``"package.module:attribute"`` (a campaign spec's ``system``, ``robofdi run``). That
imports the module — it runs its code — so a spec naming one is trusted like a script; a campaign spec is checked
for everything that does not need the system before the import.
"""
from __future__ import annotations

import pkgutil
from importlib import import_module
from importlib.metadata import entry_points
from types import ModuleType

from robofdi.errors import RobofdiError
from robofdi.faults import FAULT_KINDS
from robofdi.protocols import Mission, Parts, System, TargetLimit

__all__ = ["SYSTEMS", "RobotInstances", "register_system", "get_system", "system_names", "fault_limit", "TargetLimit", "Mission",
           "Parts", "System", "ENTRY_POINT_GROUP"]

#: The entry-point group through which an installed package adds systems.
ENTRY_POINT_GROUP = "robofdi.systems"

#: name -> system instance, for every system registered so far.
SYSTEMS: dict[str, System] = {}
_discovered = False


#: what a System must have (checked before a ``package.module:attribute`` is instantiated, and on registration)
_SYSTEM_MEMBERS = ("name", "options_type", "diagnosers", "targets", "calibration_keys", "calibrate", "mission", "build",
                   "run")


class RobotInstances:
    """Base of a system whose options have ``robot_seeds``: one robot instance (its seeded plant effects and
    nominal-model errors) and one calibration per seed; a campaign's runs cycle through them. A run is its
    :meth:`~robofdi.protocols.System.build`'s parts run."""

    def calibration_keys(self, options) -> list:
        return list(options.robot_seeds)

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        return self.build(options, calibration, key, mission, faults, seed, diagnosers).run()


def register_system(system):
    """Register a system (a class, instantiated without arguments, or an instance) under its ``name``; usable as
    a class decorator. Returns what it was given."""
    instance = system() if isinstance(system, type) else system
    if not isinstance(instance, System):
        missing = [a for a in _SYSTEM_MEMBERS if not hasattr(instance, a)]
        raise RobofdiError(f"register_system: {system!r} does not implement the System protocol (missing: "
                           f"{', '.join(missing)})")
    SYSTEMS[instance.name] = instance
    return system


def _discover() -> None:
    """Import every module of this package and every entry point of :data:`ENTRY_POINT_GROUP` (once)."""
    global _discovered
    if _discovered:
        return
    _discovered = True
    for info in pkgutil.iter_modules(__path__, f"{__name__}."):
        import_module(info.name)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            loaded = ep.load()
        except Exception as exc:                              # a broken plug-in must not hide the others
            raise RobofdiError(f"system entry point {ep.name!r} ({ep.value}) cannot be loaded: {exc}") from None
        if not isinstance(loaded, ModuleType):             # a class or an instance (a module registers itself)
            register_system(loaded)


def system_names() -> list[str]:
    """Every registered system's name (shipped ones and those of installed plug-ins), sorted."""
    _discover()
    return sorted(SYSTEMS)


def get_system(name: str) -> System:
    """A registered system by name, or ``"package.module:attribute"`` (a System class or instance).

    ``package.module:attribute`` imports that module, which runs its code: name only modules you trust (a spec
    from elsewhere should name registered systems). The attribute is instantiated only if it has every member of
    the System protocol."""
    if not isinstance(name, str) or not name:
        raise RobofdiError(f"system: expected a non-empty name, got {name!r}")
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            system = getattr(import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise RobofdiError(f"system: cannot import {name!r} ({exc})") from None
        missing = [m for m in _SYSTEM_MEMBERS if not hasattr(system, m)]
        if missing:                                   # checked before anything is instantiated
            raise RobofdiError(f"system: {name!r} does not implement the System protocol (missing: {', '.join(missing)})")
        if isinstance(system, type):
            system = system()
        if not isinstance(system, System):
            raise RobofdiError(f"system: {name!r} does not implement the System protocol")
        return system
    if name not in SYSTEMS:
        _discover()
    if name in SYSTEMS:
        return SYSTEMS[name]
    raise RobofdiError(f"system: unknown system {name!r}; expected one of {', '.join(sorted(SYSTEMS))} "
                       "or 'package.module:attribute'")


def fault_limit(targets: dict[str, dict[str, TargetLimit]], kind: str, target: str) -> TargetLimit:
    """The limit of a fault of ``kind`` on ``target``: the target's limit in the kind's unit (per second for
    drifts; 1 for the dimensionless kinds — loss of effectiveness, scale, friction factor)."""
    family = kind.split("_", 1)[0]
    table = targets.get(family if family in ("actuator", "sensor") else kind, {})
    if target not in table:
        raise RobofdiError(f"target {target!r} is not a target of {kind}; expected one of {', '.join(table) or 'none'}")
    base = table[target]
    unit = FAULT_KINDS[kind].unit
    if unit == "1":
        return TargetLimit(1.0, "1")
    if unit == "target/s":
        return TargetLimit(base.limit, f"{base.unit}/s")
    return base
