"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
from robofdi.models.control_affine import ControlAffineModel
from robofdi.models.linear import LinearMismatch, LinearModel, discretize
from robofdi.models.manipulator import (
    CompiledArm, Drive, ManipulatorModel, ModelMismatch, compile_arm, resolve_asset, sensor_channel_names,
)

__all__ = ["ManipulatorModel", "ModelMismatch", "CompiledArm", "Drive", "compile_arm", "resolve_asset",
           "sensor_channel_names", "LinearModel", "LinearMismatch", "discretize", "ControlAffineModel"]
