"""Analytical redundancy: nonlinear AR (symbolic derivation + generated code), derivative estimation, the linear
parity-space, piecewise-linear (PLAR) and neural (NNAR) baselines, and the residual generators (Diagnoser protocol)."""
from robofdi.redundancy.model import ControlAffineModel
from robofdi.redundancy.nlar import NLARDesign, derive_nlar, derivative_symbol

__all__ = ["ControlAffineModel", "NLARDesign", "derive_nlar", "derivative_symbol"]
