"""The augmented-error alternative of Jiang & Chowdhury (2005), Remark 5: "if the system is noise-free or with
low-level noise, one can use the augmented error technique in adaptive control theory [19] to achieve the
estimation" (of the state and of multiplicative model parameters, instead of the EKF,
:class:`robofdi.observers.kalman.ParameterFaultEKF`, whose cost grows with the order). The paper gives no
equations; the reading here [RECONSTRUCTED] is the discrete adaptive observer with a sensitivity filter
(Kreisselmeier's form of the augmented error; Goodwin & Sin, *Adaptive Filtering, Prediction and Control*, 1984,
ch. 3 for the least-squares update):

    truth       x(k+1) = A x + B u + Φ(k) ϑ,   Φ(k) = [A₁x(k) … A_s x(k), −B diag u(k)],   ϑ = col(θ, r)
    observer    x̄(k+1) = A x̄ + B u + L (y − C x̄)
    sensitivity Ξ(k+1) = (A − LC) Ξ(k) + Φ(k)                      ⇒  x − x̄ − Ξ ϑ → 0 as (A − LC)ᵏ
    aug. error  ε(k) = y(k) − C x̄(k) − C Ξ(k) ϑ̂(k−1) = C Ξ(k) (ϑ − ϑ̂(k−1)) + a decaying term
    update      ϑ̂(k) = ϑ̂(k−1) + R Ψᵀ (λ I + Ψ R Ψᵀ)⁻¹ ε,   Ψ = C Ξ(k),   R ← (R − R Ψᵀ(λ I + Ψ R Ψᵀ)⁻¹ Ψ R)/λ

(recursive least squares with forgetting λ on the augmented error; the state estimate is x̂ = x̄ + Ξ ϑ̂). The
regressor Φ(k) uses the measured outputs only: each Aⱼ must act on measured states (Aⱼ = Aⱼ C⁺C, checked), so
Aⱼ x(k) = Aⱼ C⁺ y(k). The cost per sample is that of an n×s filter and an s×s update (s = number of parameters)
instead of the EKF's (n + s)-dimensional covariance.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.signal

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import LinearModel, require_discrete
from robofdi.observers.kalman import EffectivenessDiagnoser, parameter_directions_of
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["AugmentedErrorEstimator"]


class AugmentedErrorEstimator(EffectivenessDiagnoser):
    """Diagnoser protocol: state, multiplicative parameters θ and loss of effectiveness r by the augmented error
    (module docstring). ``parameter_directions``: the Aⱼ (n×n each, acting on measured states only);
    ``poles``: n discrete poles of A − LC (scipy's place_poles; default 0.5, 0.55, …) or ``observer_gain`` L
    (n×p); ``forgetting`` λ in (0, 1]; ``R0``: the initial least-squares covariance (a number: R0·I; its prior
    pulls the estimate towards 0 by about 1/(R0 Σ‖Ψ‖²)). Residual and estimate: r̂ per actuator (unit 1, named like
    the inputs); θ̂ is ``parameter_estimate``. ``update(y(k), u(k−1))``."""

    def __init__(self, model: LinearModel, parameter_directions, poles: Sequence[float] | None = None,
                 observer_gain=None, forgetting: float = 0.999, R0: float = 1e4):
        where = "AugmentedErrorEstimator"
        self.model = model = require_discrete(model, where, "diagnosis")
        n, p = model.n, model.p
        dirs = parameter_directions_of(parameter_directions, n, where)
        C_pinv = np.linalg.pinv(model.C)
        for j, Aj in enumerate(dirs):
            if np.abs(Aj - Aj @ C_pinv @ model.C).max() > 1e-12 * max(1.0, np.abs(Aj).max()):
                raise RobofdiError(f"{where}: parameter direction {j} acts on an unmeasured state (Aⱼ ≠ Aⱼ C⁺C): the "
                                   "augmented-error regressor needs Aⱼ x from the outputs; use ParameterFaultEKF")
        self.directions, self.n_theta = dirs, dirs.shape[0]
        self._dirs_y = np.array([Aj @ C_pinv for Aj in dirs]).reshape(self.n_theta, n, p)   # Aⱼ x = (Aⱼ C⁺) y
        if observer_gain is not None:
            L = np.array(observer_gain, dtype=float)
            if L.shape != (n, p) or not np.all(np.isfinite(L)):
                raise RobofdiError(f"{where}: field 'observer_gain' must be a finite {n}x{p} matrix")
        else:
            z = np.array(0.5 + 0.05 * np.arange(n) if poles is None else poles, dtype=float).ravel()
            if z.shape != (n,) or np.any(np.abs(z) >= 1):
                raise RobofdiError(f"{where}: field 'poles' must be {n} values inside the unit circle, got {poles!r}")
            try:
                L = scipy.signal.place_poles(model.A.T, model.C.T, z).gain_matrix.T
            except ValueError as exc:
                raise RobofdiError(f"{where}: field 'poles' cannot be placed for (A, C): {exc}") from None
        rho = float(np.max(np.abs(np.linalg.eigvals(model.A - L @ model.C))))
        if not rho < 1.0:
            raise RobofdiError(f"{where}: A − LC is not stable (spectral radius {rho:.6g})")
        self.L, self.F = L, model.A - L @ model.C
        if isinstance(forgetting, bool) or not isinstance(forgetting, (int, float)) or not 0 < forgetting <= 1:
            raise RobofdiError(f"{where}: field 'forgetting' must be in (0, 1], got {forgetting!r}")
        if isinstance(R0, bool) or not isinstance(R0, (int, float)) or not (np.isfinite(R0) and R0 > 0):
            raise RobofdiError(f"{where}: field 'R0' must be a number > 0, got {R0!r}")
        self.forgetting, self.R0 = float(forgetting), float(R0)
        self._declare_effectiveness(model)
        self.reset()

    def reset(self) -> None:
        s = self.n_theta + self.model.m
        self._xbar = None
        self._Xi = np.zeros((self.model.n, s))
        self._y = None
        self._R = self.R0 * np.eye(s)
        self._vartheta = np.zeros(s)
        self.innovation = np.zeros(self.model.p)

    @property
    def state_estimate(self) -> np.ndarray | None:
        return None if self._xbar is None else self._xbar + self._Xi @ self._vartheta

    @property
    def parameter_estimate(self) -> np.ndarray:
        return self._vartheta[:self.n_theta].copy()

    @property
    def fault_estimate(self) -> np.ndarray:
        return self._vartheta[self.n_theta:].copy()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        md = self.model
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        if self._xbar is None:
            self._xbar = np.linalg.lstsq(md.C, y, rcond=None)[0]
        else:
            y0 = self._y
            Phi = np.hstack([np.einsum("jnp,p->nj", self._dirs_y, y0), -md.B * u[None, :]])   # Φ(k−1)
            self._xbar = md.A @ self._xbar + md.B @ u + self.L @ (y0 - md.C @ self._xbar)
            self._Xi = self.F @ self._Xi + Phi
            Psi = md.C @ self._Xi
            eps = y - md.C @ self._xbar - Psi @ self._vartheta                              # the augmented error
            RPt = self._R @ Psi.T
            gain = RPt @ np.linalg.inv(self.forgetting * np.eye(md.p) + Psi @ RPt)
            self._vartheta = self._vartheta + gain @ eps
            self._R = (self._R - gain @ RPt.T) / self.forgetting
            self._R = 0.5 * (self._R + self._R.T)
            self.innovation = eps
        self._y = y
        if not (all_finite(self._vartheta) and all_finite(self._R.ravel())):
            raise RobofdiError("AugmentedErrorEstimator: the estimate diverged (non-finite); check the model")
        return Residual(self.fault_estimate, self.fault_estimate)
