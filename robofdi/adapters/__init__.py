"""Adapters: robofdi's faults (and diagnosers) inside the environments people already use.

Each adapter is a module of its own with an optional dependency (``pip install 'robofdi[dm_control]'``,
``pip install 'robofdi[robosuite]'``), so importing :mod:`robofdi` never needs them.
"""
