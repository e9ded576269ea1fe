"""Field checks for configuration dataclasses: one set, one error shape.

Every configuration is validated at construction and refuses bad input with one line that names the owner,
the field, what was expected and what it got::

    check_fields("system", options, [("duration", is_positive(options.duration, 600), "a time in (0, 600] s")])
    # robofdi.errors.RobofdiError: system: field 'duration' must be a time in (0, 600] s, got -1.0
"""
from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["check_fields", "is_int", "is_number", "is_positive", "check_robot_seeds"]


def check_fields(where: str, obj, checks: Iterable[tuple[str, bool, str]]) -> None:
    """Raise on the first ``(field, ok, expected)`` whose ``ok`` is false: ``where: field 'f' must be …, got …``."""
    for name, ok, expected in checks:
        if not ok:
            raise RobofdiError(f"{where}: field {name!r} must be {expected}, got {getattr(obj, name)!r}")


def is_int(v, least: int = 0) -> bool:
    """An integer (not a bool) >= ``least``."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= least


def is_number(v) -> bool:
    """A finite real number (not a bool)."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and bool(np.isfinite(v))


def is_positive(v, high: float = float("inf")) -> bool:
    """A number in (0, ``high``]."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v <= high


def check_robot_seeds(options, where: str = "system") -> None:
    """``options.robot_seeds`` as a tuple of integers >= 0, non-empty (set in place on a frozen dataclass)."""
    object.__setattr__(options, "robot_seeds", tuple(options.robot_seeds))
    check_fields(where, options, [("robot_seeds", options.robot_seeds and all(is_int(s) for s in options.robot_seeds),
                                   "a non-empty list of integers >= 0")])
