"""Nominal models: the belief a diagnoser is built from (never the simulator's own model)."""
from robofdi.models.linear import LinearMismatch, LinearModel, discretize
from robofdi.models.manipulator import ManipulatorModel, ModelMismatch, sensor_channel_names

__all__ = ["ManipulatorModel", "ModelMismatch", "sensor_channel_names", "LinearModel", "LinearMismatch", "discretize",
           "ControlAffineModel"]


def __getattr__(name: str):
    # ControlAffineModel is symbolic (SymPy, ~1 s to import): loaded when first asked for, so arms, AUVs and linear
    # plants do not pay for it (PEP 562)
    if name == "ControlAffineModel":
        from robofdi.models.control_affine import ControlAffineModel

        return ControlAffineModel
    raise AttributeError(f"module 'robofdi.models' has no attribute {name!r}")
