"""Discrete-time diagnostic observers for manipulators — Caccavale & Villani, "Fault Diagnosis for Industrial
Robots" (in Caccavale & Villani eds., 2003), eqs. (10)–(48).

The Euler model of the arm, eq. (11)–(12), with state x = [q; q̇] and sample time T:

    x(k+1) = A x(k) + h(x(k)) + B(x(k)) u(k) + η(k),   A = [[I, T I], [0, I]],
    h(x) = [0; −T M̂⁻¹ n̂],  B(x) = [0; T M̂⁻¹]

Every scheme is one :class:`DiagnosticObserver` (eq. (23)) with a different uncertainty estimator η̂:
``simple`` (η̂ = 0, residual of eq. (20)), :class:`TimeDelayed` (eq. (28)), :class:`Recursive` (eq. (33)) and
:class:`Adaptive` (eqs. (37)–(39) with the ripple model of eq. (50)). ``velocity="backward_difference"``
gives the position-only variant of Sec. 5 (eqs. (43)–(48)).

Sampling convention of ``update(y, u)``: y = x̄(k) is the measurement at sample k and u = ū(k−1) the input
held over the interval that *ended* at sample k. The residual returned is r(k) of eq. (26); it uses only
x̄(k), x̄(k−1) and ū(k−1) — no look-ahead.

h and B are evaluated at the measured state x̄ (the default ``eval_at="measured"``, which makes eq. (25)
exact); ``eval_at="estimate"`` evaluates them at x̂ as printed in eq. (23) [spec ERRATUM/RECON].
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robofdi import RobofdiError
from robofdi.jit import einsum as _einsum
from robofdi.jit import kernel
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers.evaluations import evaluations
from robofdi.observers.residual import Residual, shared_measurement

__all__ = [
    "EulerArmModel",
    "NoEstimate",
    "TimeDelayed",
    "Recursive",
    "Adaptive",
    "RippleModel",
    "DiagnosticObserver",
]


class EulerArmModel:
    """The discrete-time nominal model of eqs. (11)–(12)."""

    def __init__(self, model: ManipulatorModel, T: float):
        if not (np.isfinite(T) and T > 0):
            raise RobofdiError(f"EulerArmModel: field 'T' must be a positive sample time, got {T}")
        self.model, self.T, self.n = model, float(T), model.n
        n = self.n
        self.A = np.block([[np.eye(n), T * np.eye(n)], [np.zeros((n, n)), np.eye(n)]])

    def apply_A(self, x: np.ndarray) -> np.ndarray:
        """A x = [x1 + T x2; x2] without the matrix product."""
        n = self.n
        return np.concatenate([x[:n] + self.T * x[n:], x[n:]])

    def predict(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """A x + h(x) + B(x) u."""
        n, T = self.n, self.T
        q, v = x[:n], x[n:]
        return np.concatenate([q + T * v, v + T * self.model.acceleration(q, v, u)])


# ----------------------------------------------------------------------------------------------------------
# Uncertainty estimators: each keeps η̂ and is told the residual r(k) once it is known.
# ----------------------------------------------------------------------------------------------------------
class NoEstimate:
    """η̂ ≡ 0: the observer's residual is then the simple model-based residual of eq. (20)."""

    def reset(self, dim: int) -> None:
        self.eta_hat = np.zeros(dim)

    def update(self, r: np.ndarray, r_model: np.ndarray, x: np.ndarray, u: np.ndarray) -> None:
        """Called with r(k), r₂₀(k), x̄(k−1), ū(k−1); leaves η̂(k) in ``eta_hat``."""

    def prepare(self, x: np.ndarray, u: np.ndarray) -> None:
        """Called with x̄(k), ū(k) before η̂(k) is used (only the adaptive estimator needs it)."""

    def fault_estimate(self, r_model: np.ndarray) -> np.ndarray:
        """f̂ once a fault is declared (Sec. 6): η̂ — or, with no uncertainty estimate, r₂₀ = η + f itself."""
        return r_model


class _Estimating(NoEstimate):
    def fault_estimate(self, r_model):
        return self.eta_hat


class TimeDelayed(_Estimating):
    """η̂(k) = x̄(k) − A x̄(k−1) − h(x̄(k−1)) − B(x̄(k−1)) ū(k−1) — eq. (28); equals r₂₀(k)."""

    def update(self, r, r_model, x, u):
        self.eta_hat = r_model.copy()


@dataclass
class Recursive(_Estimating):
    """η̂(k+1) = η̂(k) + Γ_η (e(k+1) − F e(k)) — eq. (33). ``gain`` is diag(Γ_η) (2n entries)."""

    gain: np.ndarray = None

    def reset(self, dim):
        g = np.asarray(self.gain, dtype=float)
        if g.shape != (dim,) or not np.all((g > 0) & (g < 2)):
            raise RobofdiError(
                f"Recursive: field 'gain' must be {dim} values in (0, 2) (eig(I − Γ_η) inside the unit circle), got {self.gain!r}"
            )
        self.gamma = g
        super().reset(dim)

    def update(self, r, r_model, x, u):
        self.eta_hat = self.eta_hat + self.gamma * r


@kernel
def _ripple_terms(theta, x1, tau, inv_scale, G, eta):
    """η(θ) of eq. (50) and the non-zero part G of Z, entry by entry in the order of operations of
    :meth:`RippleModel.evaluate`'s array form; the sines and cosines of θ_c x₁ + θ_d and θ_f x₁ + θ_g are the C
    library's (``math``), which equal NumPy's float64 ones (checked on 1.2·10⁶ arguments, and on AVX-512)."""
    n = x1.shape[0]
    for i in range(n):
        k = n + 7 * i
        a, b, e = theta[k], theta[k + 1], theta[k + 4]
        arg1 = theta[k + 2] * x1[i] + theta[k + 3]
        arg2 = theta[k + 5] * x1[i] + theta[k + 6]
        s1, c1, s2, c2 = math.sin(arg1), math.cos(arg1), math.sin(arg2), math.cos(arg2)
        t = tau[i] * inv_scale[i]
        G[i, 0] = 1.0
        G[i, 1] = s1
        G[i, 3] = b * c1
        G[i, 2] = G[i, 3] * x1[i]
        G[i, 4] = t * s2
        G[i, 6] = t * e * c2
        G[i, 5] = G[i, 6] * x1[i]
        eta[i] = theta[i]
        eta[n + i] = a + b * s1 + e * G[i, 4]


@kernel
def _adaptive_step(theta, G, gg, r, q, step, out):
    """θ̂(k+1) of eqs. (37)–(39) with Q diagonal (``gg`` = the row sums of G², NumPy's), entry by entry in the
    order of operations of :meth:`Adaptive.update`'s array form, into ``out``."""
    n = G.shape[0]
    for i in range(n):
        out[i] = theta[i] + step * r[i] / (1.0 + q[i])
    for i in range(n):
        w = step * r[n + i] / (gg[i] + q[n + i])
        for c in range(7):
            k = n + 7 * i + c
            out[k] = theta[k] + G[i, c] * w


@dataclass
class RippleModel:
    """Parametric uncertainty of eq. (50), one block of 7 parameters per joint (p = n + 7n):

        η_i        = θ_i                                                          (positions)
        η_{n+i}    = θ_a + θ_b sin(θ_c x_{1i} + θ_d) + τ_i θ_e sin(θ_f x_{1i} + θ_g)   (velocities)

    ``torque_scale`` divides τ_i (same function class, θ_e rescaled): with τ in N·m the torque column of
    Z dominates Γ_θ and θ_e soaks up Coulomb friction, then diverges when τ changes sign (measured);
    scaling τ by the motor torque limit keeps eq. (39)'s gain well conditioned.
    """

    n: int
    torque_scale: np.ndarray | float = 1.0

    def __post_init__(self):
        scale = np.broadcast_to(np.asarray(self.torque_scale, dtype=float), (self.n,))
        if not np.all(np.isfinite(scale) & (scale > 0)):
            raise RobofdiError(f"RippleModel: field 'torque_scale' must be {self.n} finite values > 0, got {self.torque_scale!r}")
        self._inv_scale = 1.0 / scale
        n = self.n
        # where the 7 columns of each velocity row sit in Z (row n+i, columns n+7i … n+7i+6)
        self._rows = np.repeat(np.arange(n, 2 * n), 7)
        self._cols = (n + 7 * np.arange(n)[:, None] + np.arange(7)).ravel()

    @property
    def p(self) -> int:
        return 8 * self.n

    def split(self, theta: np.ndarray):
        n = self.n
        return theta[:n], theta[n:].reshape(n, 7).T  # (a, b, c, d, e, f, g) rows, each (n,)

    def evaluate(self, theta: np.ndarray, x1: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """η(θ) and the non-zero part of Z: row n+i of Z is ∂η_{n+i}/∂(θ_a … θ_g of joint i), an (n × 7)
        array (position row i of Z is the unit vector on θ_i)."""
        n = self.n
        x1 = np.asarray(x1, dtype=float)
        G, eta = np.empty((n, 7)), np.empty(2 * n)
        _ripple_terms(theta, x1, np.asarray(tau, dtype=float), self._inv_scale, G, eta)
        return eta, G

    def eta(self, theta: np.ndarray, x1: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """η(k, x, u, θ) of eq. (50)."""
        return self.evaluate(theta, x1, tau)[0]

    def jacobian(self, theta: np.ndarray, x1: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Z = ∂η/∂θ — eq. (38), a (2n × 8n) matrix; each row has its own parameters, so Z Zᵀ is diagonal."""
        n = self.n
        Z = np.zeros((2 * n, 8 * n))
        Z[np.arange(n), np.arange(n)] = 1.0
        Z[self._rows, self._cols] = self.evaluate(theta, x1, tau)[1].ravel()
        return Z


class Adaptive(_Estimating):
    """θ̂(k+1) = θ̂(k) + Zᵀ Γ_θ (e(k+1) − F e(k)),  Γ_θ = 2 (Z Zᵀ + Q)⁻¹ — eqs. (37)–(39).

    :meth:`freeze` stops the adaptation until ``reset`` (the digest's ``freeze_on_detect``, driven by
    :class:`DiagnosticObserver`'s ``freeze_threshold``); η̂ is still evaluated with the frozen θ̂.
    """

    def __init__(self, model: RippleModel, Q: np.ndarray, theta0: np.ndarray | None = None, step: float = 2.0):
        if not (np.isfinite(step) and 0 < step <= 2):
            raise RobofdiError(f"Adaptive: field 'step' must be in (0, 2] (eq. (39) uses 2), got {step}")
        self.ripple, self.step = model, float(step)
        Q = np.asarray(Q, dtype=float)
        Q = np.diag(Q) if Q.ndim == 1 else Q
        dim = 2 * model.n
        if Q.shape != (dim, dim) or not np.allclose(Q, Q.T) or np.min(np.linalg.eigvalsh(Q)) <= 0:
            raise RobofdiError(f"Adaptive: field 'Q' must be a symmetric positive definite {dim}x{dim} matrix")
        self.Q = Q
        self._q = np.diag(Q).copy() if np.count_nonzero(Q - np.diag(np.diag(Q))) == 0 else None
        theta0 = np.zeros(model.p) if theta0 is None else np.asarray(theta0, dtype=float)
        if theta0.shape != (model.p,) or not np.all(np.isfinite(theta0)):
            raise RobofdiError(f"Adaptive: field 'theta0' must be {model.p} finite values")
        self.theta0 = theta0
        self.frozen = False

    def reset(self, dim):
        super().reset(dim)
        self.theta = self.theta0.copy()
        self._Z = None
        self.frozen = False

    def prepare(self, x, u):
        n = self.ripple.n
        self.eta_hat, G = self.ripple.evaluate(self.theta, x[:n], u)
        self._Z = G if self._q is not None else self.ripple.jacobian(self.theta, x[:n], u)

    def gain(self, Z: np.ndarray) -> np.ndarray:
        """Γ_θ = 2 (Z Zᵀ + Q)⁻¹ — eq. (39); ``step`` replaces the factor 2."""
        return self.step * np.linalg.inv(Z @ Z.T + self.Q)

    def freeze(self) -> None:
        """Stop adapting θ̂ (a fault is not the ripple's to learn)."""
        self.frozen = True

    def update(self, r, r_model, x, u):
        if self._Z is None or self.frozen:
            return
        if self._q is None:                      # eqs. (37), (39) as printed
            self.theta = self.theta + self._Z.T @ (self.gain(self._Z) @ r)
            return
        # Same update with Q diagonal: Z Zᵀ + Q is diagonal (|z_j|² + q_j), so Γ_θ acts row by row.
        G, theta = self._Z, np.empty(self.theta.shape[0])
        _adaptive_step(self.theta, G, _einsum("ij,ij->i", G, G), r, self._q, self.step, theta)
        self.theta = theta


@kernel
def _observer_step(x, x_prev, x_hat, e_prev, acc, acc_hat, measured, eta_prev, T, gains, out):
    """Eqs. (20), (23)–(26) for one sample, entry by entry in the order of operations of their array form, given
    the forward dynamics q̈ at x̄(k−1) (``acc``) and at x̂(k−1) (``acc_hat``, used when not ``measured``) and
    ``gains`` = [K1; K2; F] (4n): r₂₀(k), x̂(k), e(k) and r(k) into the rows of ``out`` (4, 2n)."""
    n = acc.shape[0]
    r_model, x_hat_out, e, r = out[0], out[1], out[2], out[3]
    for i in range(n):
        j = n + i
        q_model, v_model = x_prev[i] + T * x_prev[j], x_prev[j] + T * acc[i]        # predict(x̄(k−1), ū)
        r_model[i], r_model[j] = x[i] - q_model, x[j] - v_model                     # eq. (20)
        if measured:        # A (x̂ − x̄) + predict(x̄)
            dq, dv = x_hat[i] - x_prev[i], x_hat[j] - x_prev[j]
            q_base, v_base = dq + T * dv + q_model, dv + v_model
        else:               # predict(x̂)
            q_base, v_base = x_hat[i] + T * x_hat[j], x_hat[j] + T * acc_hat[i]
        ko_q, ko_v = gains[i] * e_prev[i] + T * e_prev[j], gains[n + i] * e_prev[j]   # K_o e, eq. (24)
        x_hat_out[i], x_hat_out[j] = q_base + ko_q + eta_prev[i], v_base + ko_v + eta_prev[j]   # eq. (23)
        e[i], e[j] = x[i] - x_hat_out[i], x[j] - x_hat_out[j]
        r[i], r[j] = e[i] - gains[2 * n + i] * e_prev[i], e[j] - gains[2 * n + j] * e_prev[j]   # eq. (26)


@kernel
def _backward_state(q, q_prev, T, z):
    """z = [q; (q − q_prev)/T] — eq. (43), entry by entry."""
    n = q.shape[0]
    for i in range(n):
        z[i] = q[i]
        z[n + i] = (q[i] - q_prev[i]) / T


@kernel
def _output_rows(r_model, m_f, r, m_r, T, torque, estimate, out):
    """The estimate [r₂₀ position rows; (M̂ f̂₂)/T] and, when ``torque``, the residual [r₁; (M̂ r₂)/T], given the
    products M̂ f̂₂ (``m_f``) and M̂ r₂ (``m_r``), into ``estimate`` and ``out``."""
    n = m_f.shape[0]
    for i in range(n):
        estimate[i] = r_model[i]
        estimate[n + i] = m_f[i] / T
        if torque:
            out[i] = r[i]
            out[n + i] = m_r[i] / T


# Batch forms of the kernels above (robofdi.lockstep): each on every run's rows, one call a sample for all runs.
@kernel
def _backward_state_each(Y, Y_prev, T, Z):
    """Eq. (43) per run: _backward_state."""
    n = Y.shape[1] // 2
    for i in range(Z.shape[0]):
        _backward_state(Y[i, :n], Y_prev[i, :n], T, Z[i])


@kernel
def _ripple_terms_each(theta, X, U, inv_scale, G, eta):
    """Eq. (50) per run: _ripple_terms."""
    n = U.shape[1]
    for i in range(G.shape[0]):
        _ripple_terms(theta[i], X[i, :n], U[i], inv_scale[i], G[i], eta[i])


@kernel
def _observer_step_each(X, X_prev, X_hat, E_prev, acc, acc_hat, measured, eta, T, gains, rows):
    """Eqs. (20), (23)–(26) per run: _observer_step."""
    for i in range(rows.shape[0]):
        _observer_step(X[i], X_prev[i], X_hat[i], E_prev[i], acc[i], acc_hat[i], measured, eta[i], T, gains, rows[i])


@kernel
def _adaptive_step_each(theta, G, gg, r, q, step, out):
    """Eqs. (37)–(39) per run: _adaptive_step."""
    for i in range(out.shape[0]):
        _adaptive_step(theta[i], G[i], gg[i], r[i], q, step, out[i])


@kernel
def _output_rows_each(r_model, m_f, r, m_r, T, torque, estimate, out):
    """The residual and estimate rows per run: _output_rows."""
    for i in range(out.shape[0]):
        _output_rows(r_model[i], m_f[i], r[i], m_r[i], T, torque, estimate[i], out[i])


# ----------------------------------------------------------------------------------------------------------
class DiagnosticObserver:
    """x̂(k+1) = A x̂ + h(x̄) + B(x̄) ū + K_o e + η̂ with K_o = [[K1, T I], [0, K2]] — eqs. (23)–(27).

    residual_space: "state" gives r of eq. (26) (rad and rad/s per sample, components ``joint{i}_pos`` and
    ``joint{i}_vel``); "torque" maps the velocity rows to joint torques, r_τ = (M̂(x̄₁)/T) r₂ [N·m], which
    isolates actuator i on component ``joint{i}`` (the velocity rows of an actuator fault are coupled through
    M̂⁻¹; spec §4).

    Identification (Sec. 6): ``estimate`` holds δτ̂ = (M̂/T) f̂₂ per joint (components ``joint{i}``) with
    f̂ = η̂, and the per-sample position-fault increment f̂₁ = r₁ (components ``joint{i}_pos``, summed from
    the isolation sample on by :class:`robofdi.decision.Identification`).

    freeze_threshold: the digest's ``freeze_on_detect`` [RECONSTRUCTED; the chapter is silent] — thresholds on this
    observer's residual (2n, its ``residual_space`` units, e.g. the decision's calibrated ones; None: never). Once
    any |r_i| exceeds its threshold the estimator's adaptation stops until ``reset`` (``Adaptive.freeze``), so the
    ripple model cannot absorb the fault; estimators that do not adapt ignore it.
    """

    def __init__(
        self,
        model: ManipulatorModel,
        T: float,
        estimator: NoEstimate | None = None,
        K1: float | np.ndarray = 0.1,
        K2: float | np.ndarray = 0.1,
        velocity: str = "measured",
        eval_at: str = "measured",
        residual_space: str = "torque",
        freeze_threshold=None,
    ):
        self.euler = EulerArmModel(model, T)
        self.model, self.T, self.n = model, float(T), model.n
        n = self.n
        K1 = np.broadcast_to(np.asarray(K1, dtype=float), (n,)).copy()
        K2 = np.broadcast_to(np.asarray(K2, dtype=float), (n,)).copy()
        for name, K in (("K1", K1), ("K2", K2)):
            if not np.all((K > 0) & (K < 2)):
                raise RobofdiError(
                    f"DiagnosticObserver: field {name!r} must be diagonal gains in (0, 2) (F = I − K stable), got {K}"
                )
        if velocity not in ("measured", "backward_difference"):
            raise RobofdiError(
                f"DiagnosticObserver: field 'velocity' must be 'measured' or 'backward_difference', got {velocity!r}"
            )
        if eval_at not in ("measured", "estimate"):
            raise RobofdiError(f"DiagnosticObserver: field 'eval_at' must be 'measured' or 'estimate', got {eval_at!r}")
        if residual_space not in ("state", "torque"):
            raise RobofdiError(f"DiagnosticObserver: field 'residual_space' must be 'state' or 'torque', got {residual_space!r}")
        self.K1, self.K2 = K1, K2
        self.F = np.concatenate([1.0 - K1, 1.0 - K2])          # F = blkdiag(I − K1, I − K2), eq. (25)
        self._gains = np.concatenate([K1, K2, self.F])         # the kernel's [K1; K2; F]
        self.Ko = np.block([[np.diag(K1), T * np.eye(n)], [np.zeros((n, n)), np.diag(K2)]])  # eq. (24)
        self.estimator = estimator if estimator is not None else NoEstimate()
        self.freeze_threshold = None if freeze_threshold is None else np.asarray(freeze_threshold, dtype=float)
        if self.freeze_threshold is not None and (self.freeze_threshold.shape != (2 * n,)
                                                  or not np.all(self.freeze_threshold > 0)):
            raise RobofdiError(f"DiagnosticObserver: field 'freeze_threshold' must be None or {2 * n} thresholds > 0")
        self.velocity, self.eval_at, self.residual_space = velocity, eval_at, residual_space
        self._evaluations = evaluations(model)     # M̂ and the forward dynamics, shared with the other diagnosers
        names = model.joint_names
        self.inputs = list(names)
        self.measurements = [f"{j}_pos" for j in names] + [f"{j}_vel" for j in names]
        self.components = [f"{j}_pos" for j in names] + (
            list(names) if residual_space == "torque" else [f"{j}_vel" for j in names]
        )
        # same order as the residual: the position-sensor candidates first, then the joint torques
        self.estimate_components = [f"{j}_pos" for j in names] + list(names)
        self.units = {
            "residual": ["rad"] * n + (["N·m"] * n if residual_space == "torque" else ["rad/s"] * n),
            "estimate": ["rad"] * n + ["N·m"] * n,
        }
        self.reset()

    def reset(self) -> None:
        self.estimator.reset(2 * self.n)
        self._x_prev = None      # x̄(k−1)
        self._q_prev = None      # raw position for backward differences
        self.x_hat = None
        self._e_prev = None

    def _state(self, y: np.ndarray) -> np.ndarray | None:
        n = self.n
        if self.velocity == "measured":
            return y                # read-only (shared_measurement): kept as x̄(k−1) without a copy
        q = y[:n]                   # read-only: kept without a copy
        if self._q_prev is None:
            self._q_prev = q
            return None
        z = np.empty(2 * n)
        _backward_state(q, self._q_prev, self.T, z)  # eq. (43)
        self._q_prev = q
        return z

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """One sample: y = x̄(k), u = ū(k−1). Returns r(k) and the identification candidates."""
        n = self.n
        y = shared_measurement(y, 2 * n, "y")
        u = shared_measurement(u, n, "u")
        x = self._state(y)
        if x is None or self._x_prev is None:
            if x is not None:
                self._x_prev, self.x_hat, self._e_prev = x, x.copy(), np.zeros(2 * n)
            return Residual(np.zeros(2 * n), np.zeros(2 * n), state_residual=np.zeros(2 * n))
        est = self.estimator
        est.prepare(self._x_prev, u)           # η̂(k−1) with x̄(k−1), ū(k−1)
        x_prev, m = self._x_prev, 2 * n
        acc = self._evaluations.acceleration_at(x_prev, u)      # the model term of eq. (20), at x̄(k−1), ū(k−1)
        # eval_at "measured": A x̂ + h(x̄) + B(x̄)ū = A(x̂ − x̄) + predict(x̄); "estimate": predict(x̂), eq. (23)
        acc_hat = acc if self.eval_at == "measured" else self.model.acceleration(self.x_hat[:n], self.x_hat[n:], u)
        rows = np.empty((4, m))         # r₂₀, x̂, e, r: four fresh rows (each kept or handed on as its own array)
        _observer_step(x, x_prev, self.x_hat, self._e_prev, acc, acc_hat, self.eval_at == "measured", est.eta_hat,
                       self.T, self._gains, rows)
        r_model, x_hat, e, r = rows
        self.x_hat = x_hat
        est.update(r, r_model, x_prev, u)
        self._x_prev, self._e_prev = x, e
        res = self._output(x, r, est.fault_estimate(r_model), r_model)
        if self.freeze_threshold is not None and hasattr(est, "freeze") and np.any(np.abs(res.r) > self.freeze_threshold):
            est.freeze()                        # freeze_on_detect, from the next sample on
        return res

    def _output(self, x: np.ndarray, r: np.ndarray, f_hat: np.ndarray, r_model: np.ndarray) -> Residual:
        n, T = self.n, self.T
        M = self._evaluations.mass_matrix_at(x)
        # δτ̂ = (M̂/T) f̂₂ (Sec. 6, with M̂ for the unknown M); "torque": r_τ = (M̂/T) r₂ (the products NumPy's)
        torque = self.residual_space == "torque"
        estimate = np.empty(2 * n)
        out = np.empty(2 * n) if torque else r
        _output_rows(r_model, M.dot(f_hat[n:]), r, M.dot(r[n:]) if torque else r, T, torque, estimate, out)
        # Position faults: f_s1(k) = δx1(k+1) − δx1(k) (eq. (19)), so the position rows of r₂₀ summed from the
        # isolation sample estimate δx1 (instead of x̄1 − x1d, which needs the reference; spec erratum 2–4).
        return Residual(out, estimate, state_residual=r)

    def signatures(self):
        """Fault signatures of the residual: sensor i raises its position component and may raise the
        velocity/torque ones (Sec. 6); actuator i raises its torque (or velocity) component and, in closed loop,
        may raise position components too — the Euler truncation error T²q̈/2 of eq. (10) follows the
        acceleration step a torque fault causes. Which one is isolated is then decided by the larger
        residual-to-threshold ratio (:class:`robofdi.decision.ThresholdDecision`)."""
        from robofdi.decision import Signature

        n = self.n
        names = self.model.joint_names
        upper, lower = frozenset(self.components[:n]), frozenset(self.components[n:])
        coupled = lower if self.residual_space == "state" else frozenset()   # M̂⁻¹ couples the velocity rows
        sigs = [Signature(names[i], frozenset([self.components[n + i]]), upper | coupled) for i in range(n)]
        for i in range(n):
            # eq. (48): with backward-difference velocities a position fault necessarily enters velocity row i
            required = {self.components[i]} | ({self.components[n + i]} if self.velocity == "backward_difference" else set())
            sigs.append(Signature(f"{names[i]}_pos", frozenset(required), lower))
        return sigs

    @property
    def estimate_modes(self) -> list[str]:
        """'level' components are read as they are; 'increment' ones are summed from the isolation sample."""
        return ["increment"] * self.n + ["level"] * self.n
