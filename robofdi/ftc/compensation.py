"""Compensation of identified additive actuator faults (Caccavale & Villani Sec. 6: once δτ is identified, the
controller can cancel it; Blanke et al., *Diagnosis and Fault-Tolerant Control*, 2016, Sec. 7.2, fault
accommodation by disturbance compensation)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.protocols import Health

__all__ = ["FaultCompensation"]


class FaultCompensation:
    """u = u_cmd − δ̂ on every isolated actuator, with δ̂ the identified fault in the actuator's unit.

    ``gain`` in (0, 1] scales the compensation (1: cancel the whole estimate). Health that names no actuator
    (a sensor or component hypothesis) leaves u = u_cmd.
    """

    def __init__(self, actuators: Sequence[str], gain: float = 1.0):
        self.actuators = list(actuators)
        if not self.actuators:
            raise RobofdiError("FaultCompensation: field 'actuators' must name at least one actuator")
        if not (np.isfinite(gain) and 0 < gain <= 1):
            raise RobofdiError(f"FaultCompensation: field 'gain' must be in (0, 1], got {gain}")
        self.gain = float(gain)
        self._index = {name: i for i, name in enumerate(self.actuators)}

    def reset(self) -> None:
        """Stateless: nothing to forget."""

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        if not health.estimate:
            return u_cmd
        u = np.array(u_cmd, dtype=float)
        for target, value in health.estimate.items():
            i = self._index.get(target)
            if i is not None:
                u[i] -= self.gain * value
        return u
