"""Adapters: robofdi's faults (and diagnosers) inside the environments people already use.

Each adapter is a module of its own with an optional dependency (``pip install 'robofdi[dm_control]'``,
``pip install 'robofdi[robosuite]'``), so importing :mod:`robofdi` never needs them.
"""
from importlib import import_module

from robofdi.errors import RobofdiError

__all__ = ["adapter"]


def adapter(module: str, extra: str):
    """An adapter module (``robofdi.adapters.<name>``), or one clear error naming the optional extra it needs."""
    try:
        return import_module(module)
    except ImportError as exc:
        raise RobofdiError(f"{module} needs the optional extra: pip install 'robofdi[{extra}]' ({exc})") from None
