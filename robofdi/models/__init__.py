"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, resolve_asset
from robofdi.models.linear import LinearMismatch as LinearMismatch, LinearModel as LinearModel, discretize as discretize

__all__ = ["ManipulatorModel", "ModelMismatch", "resolve_asset"]
