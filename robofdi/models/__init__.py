"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
<<<<<<< HEAD
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, resolve_asset
from robofdi.models.linear import LinearMismatch as LinearMismatch, LinearModel as LinearModel, discretize as discretize
=======
from robofdi.models.manipulator import (
    CompiledArm, Drive, ManipulatorModel, ModelMismatch, compile_arm, resolve_asset, sensor_channel_names,
)
>>>>>>> arm

__all__ = ["ManipulatorModel", "ModelMismatch", "CompiledArm", "Drive", "compile_arm", "resolve_asset",
           "sensor_channel_names"]
