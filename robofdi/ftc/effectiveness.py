"""Actuator-gain accommodation: loss of effectiveness — Jiang & Chowdhury (2005) eq. (29), u_R = (I − R̂)⁻¹ u; gain
compensation — Wang, book ch. 2, eq. (104); reconfiguration to the actuators left after a singular fault — eqs.
(110)–(111)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.protocols import Health

__all__ = ["EffectivenessCompensation", "GainCompensation", "ReducedActuators", "reduced_actuator_set"]


class EffectivenessCompensation:
    """u = (I − R̂)⁻¹ u_cmd, R̂ = diag(r̂ᵢ) from the health estimate (the loss of effectiveness of each isolated
    actuator, unit 1), clipped to [0, ``r_max``] so that I − R̂ stays invertible (r_max = 0.95: spec A.3 [HARNESS]).
    Actuators not isolated keep r̂ = 0."""

    def __init__(self, actuators: Sequence[str], r_max: float = 0.95):
        self.actuators = list(actuators)
        if not self.actuators:
            raise RobofdiError("EffectivenessCompensation: field 'actuators' must name at least one actuator")
        if isinstance(r_max, bool) or not isinstance(r_max, (int, float, np.floating)) or not (0 < r_max < 1):
            raise RobofdiError(f"EffectivenessCompensation: field 'r_max' must be in (0, 1), got {r_max!r}")
        self.r_max = float(r_max)
        self._index = {name: i for i, name in enumerate(self.actuators)}

    def reset(self) -> None:
        """Stateless: nothing to forget."""

    def loss(self, health: Health) -> np.ndarray:
        """R̂ (diagonal entries) from ``health``, clipped to [0, r_max]."""
        r = np.zeros(len(self.actuators))
        for target, value in health.estimate.items():
            i = self._index.get(target)
            if i is not None and target in health.isolated:
                r[i] = min(max(float(value), 0.0), self.r_max)
        return r

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        if not health.estimate:
            return u_cmd
        return np.asarray(u_cmd, dtype=float) / (1.0 - self.loss(health))


class GainCompensation:
    """u = f_H f̂⁻¹ u_cmd per isolated actuator — Wang, book ch. 2, eq. (104) for a controller K that does not
    depend on f (then (105)–(106) reduce to it). f̂ from the health estimate (the diagnosed actuator gain); gains
    with |f̂| < ``min_gain`` are treated as a total failure and left uncompensated: the chapter's singular case
    is a redesign on the remaining actuators, :func:`reduced_actuator_set` (110)–(111)."""

    def __init__(self, actuators: Sequence[str], f_H, min_gain: float = 1e-3):
        self.actuators = list(actuators)
        if not self.actuators:
            raise RobofdiError("GainCompensation: field 'actuators' must name at least one actuator")
        fH = np.broadcast_to(np.array(f_H, dtype=float), (len(self.actuators),)).copy()
        if not np.all(np.isfinite(fH)) or np.any(fH == 0):
            raise RobofdiError(f"GainCompensation: field 'f_H' must be non-zero healthy gains, got {f_H!r}")
        self.f_H, self.min_gain = fH, float(min_gain)
        self._index = {name: i for i, name in enumerate(self.actuators)}

    def reset(self) -> None:
        """Stateless: nothing to forget."""

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        u = np.array(u_cmd, dtype=float)
        for target, value in health.estimate.items():
            i = self._index.get(target)
            if i is not None and target in health.isolated and abs(value) >= self.min_gain:
                u[i] *= self.f_H[i] / value
        return u


@dataclass(frozen=True)
class ReducedActuators:
    """The plant on the actuators left after a singular gain fault — eqs. (110)–(111): x⁺ = Ax + B_r f_r u_r + Eω,
    y = Cx + D_r f_r u_r + Fμ. ``kept``: indices of the actuators still in use (into the original u); ``Bf``, ``Df``:
    B_r f_r and D_r f_r, the input matrices for the redesign (any linear or adaptive design, the chapter says)."""

    kept: tuple[int, ...]
    Bf: np.ndarray
    Df: np.ndarray

    def expand(self, u_r: np.ndarray, m: int) -> np.ndarray:
        """The full input vector of ``m`` actuators: u_r on the kept ones, 0 on the switched-off ones."""
        u = np.zeros(m)
        u[list(self.kept)] = np.asarray(u_r, dtype=float)
        return u


def reduced_actuator_set(B, D, f_hat, min_gain: float) -> ReducedActuators:
    """The switching function of Sec. 9.1: actuators whose diagnosed gain |f̂ᵢ| < ``min_gain`` are switched off, and
    (110)–(111) are formed from the rest (f̂ diagonal: one gain per actuator). The chapter gives no threshold: a
    tunable. Refuses a fault that leaves no actuator (nothing to reconfigure to)."""
    B, D = np.atleast_2d(np.asarray(B, dtype=float)), np.atleast_2d(np.asarray(D, dtype=float))
    f = np.asarray(f_hat, dtype=float)
    f = np.diag(f) if f.ndim == 2 else f.ravel()
    if B.shape[1] != f.size or D.shape[1] != f.size:
        raise RobofdiError(f"reduced_actuator_set: field 'f_hat' must hold one gain per column of B and D "
                           f"({B.shape[1]}), got {f.size}")
    if isinstance(min_gain, bool) or not isinstance(min_gain, (int, float, np.floating)) or not min_gain > 0:
        raise RobofdiError(f"reduced_actuator_set: field 'min_gain' must be a number > 0, got {min_gain!r}")
    kept = tuple(int(i) for i in np.flatnonzero(np.abs(f) >= min_gain))
    if not kept:
        raise RobofdiError("reduced_actuator_set: every actuator is below 'min_gain': no actuator left to "
                           "reconfigure to (110)–(111)")
    idx = list(kept)
    return ReducedActuators(kept, B[:, idx] * f[idx], D[:, idx] * f[idx])
