"""Sensor fault-tolerant control by output correction — Edwards, Alwi & Tan §7.2 (Fig. 18): the controller is fed
y − F f̂_o, with f̂_o from the §5 sensor-fault reconstruction SMO
(:func:`robofdi.observers.smo_reconstruction.sensor_fault_observer`)."""
from __future__ import annotations

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["SensorCorrection"]


class SensorCorrection:
    """``update(y, u)`` → y − F f̂_o: steps the sensor-fault observer on (y, u) (u: the input held over the interval
    that ended now) and removes the reconstructed fault from the measurement. ``estimate``: the last f̂_o."""

    def __init__(self, observer, F):
        self.observer = observer
        self.F = np.asarray(F, dtype=float)
        p, q = len(observer.measurements), len(observer.estimate_components)
        if self.F.shape != (p, q):
            raise RobofdiError(f"SensorCorrection: field 'F' must be {p}×{q} (the faulty sensors' directions), got "
                               f"{self.F.shape}")
        self.reset()

    def reset(self) -> None:
        self.observer.reset()
        self.estimate = np.zeros(self.F.shape[1])

    def update(self, y, u) -> np.ndarray:
        res = self.observer.update(y, u)
        self.estimate = np.asarray(res.estimate, dtype=float)
        return np.asarray(y, dtype=float) - self.F @ self.estimate
