"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
from robofdi.models.control_affine import ControlAffineModel
from robofdi.models.linear import LinearMismatch, LinearModel, discretize
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, sensor_channel_names

__all__ = ["ManipulatorModel", "ModelMismatch", "sensor_channel_names", "LinearModel", "LinearMismatch", "discretize",
           "ControlAffineModel"]
