"""Experiments: one module per book chapter and per paper, plus :mod:`.system_run` (any registered system).

An experiment module has ``EXPERIMENTS`` ({name: one-line description}), ``run(name, out, seed, progress=True,
**options) -> (summary, run folder)`` and optionally ``OPTIONS`` (the ``robofdi run`` options it takes:
"robot", "faults", "joints", "torque_motors"). :func:`experiments` finds every module of this package and every
module an installed package declares in the entry-point group ``robofdi.experiments``::

    [project.entry-points."robofdi.experiments"]
    my-experiment = "my_package.my_experiment"
"""
from __future__ import annotations

import pkgutil
from importlib import import_module
from importlib.metadata import entry_points

__all__ = ["experiments", "ENTRY_POINT_GROUP"]

#: The entry-point group through which an installed package adds experiments.
ENTRY_POINT_GROUP = "robofdi.experiments"


def experiments() -> dict:
    """{name: (description, module)} of every experiment, shipped ones first (in the order of their modules)."""
    from robofdi.errors import RobofdiError

    modules = [import_module(info.name) for info in pkgutil.iter_modules(__path__, f"{__name__}.")]
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            modules.append(ep.load())
        except Exception as exc:
            raise RobofdiError(f"experiment entry point {ep.name!r} ({ep.value}) cannot be loaded: {exc}") from None
    found = {}
    for mod in modules:
        for name, description in getattr(mod, "EXPERIMENTS", {}).items():
            found[name] = (description, mod)
    return found
