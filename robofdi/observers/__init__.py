"""State and fault estimators that produce residuals from nominal models, commands and measurements only."""
from robofdi.observers.diagnostic import (
    Adaptive,
    DiagnosticObserver,
    EulerArmModel,
    NoEstimate,
    Recursive,
    RippleModel,
    TimeDelayed,
)
from robofdi.observers.momentum import MomentumObserver
from robofdi.observers.linear import ObserverResidual as ObserverResidual, observer_gain_kalman as observer_gain_kalman
from robofdi.observers.residual import Residual, check_measurement

__all__ = [
    "Adaptive", "DiagnosticObserver", "EulerArmModel", "NoEstimate", "Recursive", "RippleModel",
    "TimeDelayed", "MomentumObserver", "Residual", "check_measurement",
]
