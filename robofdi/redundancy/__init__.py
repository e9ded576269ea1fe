"""Analytical redundancy: nonlinear AR (symbolic derivation + generated code), derivative estimation, the linear
parity-space, piecewise-linear (PLAR), nearly nonlinear (NNAR) and neural (mlp_ar) baselines, and the residual
generators (Diagnoser protocol)."""
from robofdi.redundancy.derivatives import DerivativeEstimator, SavitzkyGolay, estimate_derivatives
from robofdi.models.control_affine import ControlAffineModel
from robofdi.redundancy.nlar import NLARDesign, derivative_symbol, derive_nlar
from robofdi.redundancy.residuals import RedundancyResidual, SignalMap, nlar_residual

__all__ = ["ControlAffineModel", "NLARDesign", "derive_nlar", "derivative_symbol", "SavitzkyGolay",
           "DerivativeEstimator", "estimate_derivatives", "RedundancyResidual", "SignalMap", "nlar_residual"]
