"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, resolve_asset

__all__ = ["ManipulatorModel", "ModelMismatch", "resolve_asset"]
