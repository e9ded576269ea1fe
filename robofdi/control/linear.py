"""Observer-based state feedback for discrete linear models, and the discrete LQR gain."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg

from robofdi.errors import RobofdiError
from robofdi.models.linear import (
    LinearModel, covariance_factor, format_mode, require_discrete, uncontrollable_modes,
)

__all__ = ["lqr_gain", "StateFeedback", "OpenLoop"]


def lqr_gain(model: LinearModel, Qx, Ru) -> np.ndarray:
    """Discrete LQR K (m×n) for u = −K x minimising Σ xᵀQx x + uᵀRu u: K = (Ru + BᵀPB)⁻¹ BᵀPA, P the stabilising
    DARE solution — Lewis, Vrabie & Syrmos, *Optimal Control*, 3rd ed. 2012, Sec. 2.4 (steady-state LQR).

    Qx: n×n PSD (or n weights); Ru: m×m positive definite (or m weights).
    """
    where = "lqr_gain"
    model = require_discrete(model, where, "control")
    Qx, _ = covariance_factor(Qx, model.n, "Qx")
    Ru, _ = covariance_factor(Ru, model.m, "Ru")
    if np.linalg.eigvalsh(Ru).min() <= 0:
        raise RobofdiError(f"{where}: field 'Ru' must be positive definite, got eigenvalues {np.linalg.eigvalsh(Ru)}")
    unstable = [lam for lam in uncontrollable_modes(model.A, model.B) if abs(lam) >= 1.0 - 1e-12]
    if unstable:
        raise RobofdiError(f"{where}: (A, B) is not stabilizable: mode λ={format_mode(unstable[0])} uncontrollable")
    A, B = model.A, model.B
    try:
        P = scipy.linalg.solve_discrete_are(A, B, Qx, Ru)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise RobofdiError(f"{where}: no stabilising LQR gain ({exc}); every mode on the unit circle must be "
                           "weighted by 'Qx'") from None
    K = np.linalg.solve(Ru + B.T @ P @ B, B.T @ P @ A)
    rho = float(np.max(np.abs(np.linalg.eigvals(A - B @ K))))
    if not rho < 1.0:
        raise RobofdiError(f"{where}: A − B K is not stable (spectral radius {rho:.6g}); check 'Qx' and 'Ru'")
    return K


def observer_gain_unused(n: int, p: int) -> np.ndarray:
    """Placeholder L (zeros) when an external estimator replaces the built-in observer."""
    return np.zeros((n, p))


def _vector(value, size: int, name: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(size, default)
    a = np.array(value, dtype=float)
    if a.ndim == 0:
        a = np.full(size, float(a))
    if a.shape != (size,) or np.isnan(a).any():
        raise RobofdiError(f"StateFeedback: field {name!r} must be {size} numbers (±inf allowed), got {value!r}")
    return a


class StateFeedback:
    """Controller protocol: u(k) = sat(−K x̂(k) + N ref(k)), x̂ from a predictor observer on the nominal model
    (x̂(k+1) = A x̂ + B u(k) + L (y(k) − C x̂(k) − D u(k−1))) — separation principle: closed-loop eigenvalues are
    eig(A − BK) ∪ eig(A − LC) for the nominal model (Franklin, Powell & Workman, *Digital Control of Dynamic
    Systems*, 3rd ed., Ch. 8, combined control law and estimator).

    tracked: names of the outputs whose setpoints ``reference`` gives (default: every output); N is the
    (pseudo-)inverse of the closed-loop DC gain from N·ref to those outputs, so a nominal plant settles on the
    setpoints (least squares when there are more tracked outputs than inputs). ``reference``: an array of setpoints,
    a tuple whose first entry is that array, or None (zeros). u_min / u_max: the controller clips its command (and
    its observer uses the clipped command); default ±inf. x0: initial estimate (None: C⁺ y of the first sample).
    estimator: optional state estimator used instead of the built-in observer (then ``L`` may be None) — any object
    with ``reset()``, ``update(y(k), u(k−1))`` and ``state_estimate`` (x̂(k) after the update), e.g. a fault-decoupled
    :class:`robofdi.observers.kalman.KalmanFaultEstimator`, so that an actuator fault does not bias x̂.
    """

    def __init__(self, model: LinearModel, K, L, tracked: Sequence[str] | None = None, u_min=None, u_max=None, x0=None,
                 estimator=None):
        where = "StateFeedback"
        self.model = model = require_discrete(model, where, "control")
        n, m, p = model.n, model.m, model.p
        self.K = np.array(K, dtype=float)
        if self.K.shape != (m, n) or not np.all(np.isfinite(self.K)):
            raise RobofdiError(f"{where}: field 'K' must be a finite {m}x{n} matrix (inputs x states), got shape {self.K.shape}")
        if estimator is not None and not all(hasattr(estimator, a) for a in ("reset", "update", "state_estimate")):
            raise RobofdiError(f"{where}: field 'estimator' must have reset(), update(y, u) and state_estimate")
        self.estimator = estimator
        if L is None and estimator is not None:
            L = observer_gain_unused(n, p)
        self.L = np.array(L, dtype=float)
        if self.L.shape != (n, p) or not np.all(np.isfinite(self.L)):
            raise RobofdiError(f"{where}: field 'L' must be a finite {n}x{p} matrix (states x outputs), got shape {self.L.shape}")
        A, B, C, D = model.A, model.B, model.C, model.D
        for name, M in (("K", A - B @ self.K),) + ((("L", A - self.L @ C),) if estimator is None else ()):
            rho = float(np.max(np.abs(np.linalg.eigvals(M))))
            if not rho < 1.0:
                what = "A − B K" if name == "K" else "A − L C"
                raise RobofdiError(f"{where}: field {name!r} does not stabilise {what}: spectral radius {rho:.6g}, expected < 1")
        if tracked is None:
            tracked = list(model.output_names)
        if isinstance(tracked, str):
            raise RobofdiError(f"{where}: field 'tracked' must be a list of output names, got the string {tracked!r}")
        unknown = [t for t in tracked if t not in model.output_names]
        if unknown or not tracked or len(set(tracked)) != len(tracked):
            raise RobofdiError(
                f"{where}: field 'tracked' must be distinct names of {list(model.output_names)}, got {list(tracked)}"
            )
        self.tracked = list(tracked)
        idx = [model.output_names.index(t) for t in tracked]
        G = ((C - D @ self.K) @ np.linalg.solve(np.eye(n) - A + B @ self.K, B) + D)[idx]
        if np.linalg.matrix_rank(G) < min(G.shape):
            raise RobofdiError(f"{where}: field 'tracked': the closed loop has a rank-deficient DC gain to {self.tracked}")
        self.N = np.linalg.pinv(G)
        self.u_min = _vector(u_min, m, "u_min", -np.inf)
        self.u_max = _vector(u_max, m, "u_max", np.inf)
        if np.any(self.u_min > self.u_max):
            raise RobofdiError(f"{where}: field 'u_min' must be <= u_max per input")
        if x0 is not None:
            x0 = np.array(x0, dtype=float)
            if x0.shape != (n,) or not np.all(np.isfinite(x0)):
                raise RobofdiError(f"{where}: field 'x0' must be None or a finite vector of {n} values")
        self.x0 = x0
        self.reset()

    def reset(self) -> None:
        self._x = None
        self._u = np.zeros(self.model.m)
        if self.estimator is not None:
            self.estimator.reset()

    def update(self, y: np.ndarray, reference=None) -> np.ndarray:
        """y(k) measured now, reference(k) → u(k), held until the next sample."""
        md = self.model
        y = np.array(y, dtype=float)
        if y.shape != (md.p,) or not np.all(np.isfinite(y)):
            raise RobofdiError(f"StateFeedback: input 'y' must be a finite vector of {md.p} values, got {y!r}")
        ref = reference[0] if isinstance(reference, tuple) else reference
        ref = np.zeros(len(self.tracked)) if ref is None else np.atleast_1d(np.array(ref, dtype=float))
        if ref.shape != (len(self.tracked),) or not np.all(np.isfinite(ref)):
            raise RobofdiError(f"StateFeedback: input 'reference' must be {len(self.tracked)} finite setpoints for "
                               f"{self.tracked}, got {reference!r}")
        if self.estimator is not None:
            self.estimator.update(y, self._u)
            self._x = np.asarray(self.estimator.state_estimate, dtype=float)
        elif self._x is None:
            self._x = self.x0.copy() if self.x0 is not None else np.linalg.lstsq(md.C, y - md.D @ self._u, rcond=None)[0]
        else:
            self._x = md.A @ self._x + md.B @ self._u + self.L @ self._innovation
        self._innovation = y - md.C @ self._x - md.D @ self._u
        u = np.clip(-self.K @ self._x + self.N @ ref, self.u_min, self.u_max)
        self._u = u
        return u.copy()


class OpenLoop:
    """Controller protocol for open-loop experiments: u(k) = reference(k) (e.g. the step input of Guo et al. 2008)."""

    def __init__(self, m: int):
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
            raise RobofdiError(f"OpenLoop: field 'm' must be the number of inputs (>= 1), got {m!r}")
        self.m = int(m)

    def reset(self) -> None:
        """Stateless."""

    def update(self, y: np.ndarray, reference=None) -> np.ndarray:
        ref = reference[0] if isinstance(reference, tuple) else reference
        u = np.zeros(self.m) if ref is None else np.atleast_1d(np.array(ref, dtype=float))
        if u.shape != (self.m,) or not np.all(np.isfinite(u)):
            raise RobofdiError(f"OpenLoop: input 'reference' must be {self.m} finite input values, got {reference!r}")
        return u
