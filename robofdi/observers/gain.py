"""Actuator-gain fault detection and diagnosis for linear stochastic systems — Wang, "Fault diagnosis and fault
tolerant control for non-Gaussian stochastic systems with random parameters", in Caccavale & Villani (eds.), 2003,
ch. 2, Secs. 2–4 (eqs. (1)–(51)).

Plant (1)–(2): x(k+1) = A x + B f u + E ω,  y = C x + D f u + F μ, with the actuator gain matrix f (healthy f_H).
Detection observer (4)–(5) with the healthy gain gives ē; the diagnostic observer (24)–(25) with f̂ gives ε, and f̂
follows the deadbeat update (35)+(38). The feedthrough D acts at the same sample: ``update(y(k), u(k))`` takes
the input applied at the sample of y (Wang's convention; u(k) may depend on x(k), never on y(k)). D must have full
row rank (M₀ = D must have a right inverse, spec W3 [RECONSTRUCTED caveat]).
"""
from __future__ import annotations

from collections import deque

import numpy as np

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import LinearModel, require_discrete
from robofdi.observers.linear import spectral_radius
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["residual_polynomials", "GainFaultObserver"]


def residual_polynomials(A0: np.ndarray, B0: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, M): G(q⁻¹) = C (I − q⁻¹A₀)⁻¹ q⁻¹ B₀ + D = M(q⁻¹)/N(q⁻¹) — Wang eqs. (17), (28)–(30).

    N = det(I − q⁻¹A₀): a = numpy.poly(A₀) (a₀ = 1); M = N·G, computed as the convolution of a with the impulse
    response h₀ = D, hᵢ = C A₀^{i−1} B₀ (exact: M has degree n). M has shape (n+1, r, m), M₀ = D.
    """
    n = A0.shape[0]
    a = np.real(np.poly(A0))
    h = [np.asarray(D, dtype=float)]
    P = np.eye(n)
    for _ in range(n):
        h.append(C @ P @ B0)
        P = A0 @ P
    M = np.array([sum(a[j] * h[i - j] for j in range(i + 1)) for i in range(n + 1)])
    return a, M


class GainFaultObserver:
    """Diagnoser protocol: residual ē(k) of the healthy-gain observer (4)–(5) (one per output) and the gain
    estimate f̂ (diagonal entries, one per actuator, unit 1) of the recursive estimator (24)–(38).

    model: discrete, with the *unit-gain* input matrices B, D (the plant applies B f u). f_H: healthy gain
    (scalar, m values or an m×m matrix). L: n×r observer gain with A − LC stable. min_input: the update (38) is
    skipped when uᵀu < min_input (the chapter only asks u ≠ 0, eq. (6)).
    """

    def __init__(self, model: LinearModel, L, f_H, min_input: float = 1e-12):
        where = "GainFaultObserver"
        self.model = model = require_discrete(model, where, "diagnosis")
        n, m, r = model.n, model.m, model.p
        L = np.array(L, dtype=float)
        if L.shape != (n, r) or not np.all(np.isfinite(L)):
            raise RobofdiError(f"{where}: field 'L' must be a finite {n}x{r} matrix, got shape {L.shape}")
        rho = spectral_radius(model.A - L @ model.C)
        if not rho < 1:
            raise RobofdiError(f"{where}: A − L C is not stable (spectral radius {rho:.6g}); eq. (4) needs a stable observer")
        fH = np.array(f_H, dtype=float)
        fH = fH * np.eye(m) if fH.ndim == 0 else (np.diag(fH) if fH.ndim == 1 else fH)
        if fH.shape != (m, m) or not np.all(np.isfinite(fH)):
            raise RobofdiError(f"{where}: field 'f_H' must be a scalar, {m} values or an {m}x{m} matrix")
        if np.linalg.matrix_rank(model.D) < r:
            raise RobofdiError(f"{where}: D must have full row rank r={r} (M₀ = D needs a right inverse, eq. (37)); "
                               f"got rank {np.linalg.matrix_rank(model.D)}")
        self.L, self.f_H, self.min_input = L, fH, float(min_input)
        self.A0, self.B0 = model.A - L @ model.C, model.B - L @ model.D
        self.a, self.M = residual_polynomials(self.A0, self.B0, model.C, model.D)
        self._M0_inv = np.linalg.pinv(self.M[0])
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(model.output_names)
        self.estimate_components = list(model.input_names)
        self.estimate_modes = ["level"] * m
        self.units = {"residual": list(model.units["y"]), "estimate": ["1"] * m}
        self.reset()

    def reset(self) -> None:
        md = self.model
        n = md.n
        self._z = np.zeros(n)                     # detection observer (4)
        self._x = np.zeros(n)                     # diagnostic observer (24)
        self._eps = deque([np.zeros(md.p)] * (n + 1), maxlen=n + 1)     # ε(k−1), …, ε(k−n−1)
        self._f = deque([self.f_H.copy()] * (n + 1), maxlen=n + 1)      # f̂(k−1), …, f̂(k−n−1)
        self._u = deque([np.zeros(md.m)] * n, maxlen=max(n, 1))         # u(k−1), …, u(k−n)
        self.gain = self.f_H.copy()
        self.innovation = np.zeros(md.p)

    def signatures(self) -> list:
        """A gain fault of actuator j shows on every output it reaches (single-actuator models: on all)."""
        from robofdi.decision import Signature

        return [Signature(a, frozenset(self.components)) for a in self.inputs]

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y(k) and u(k) (same sample, see the module docstring) → ē(k), diag f̂(k)."""
        md = self.model
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        A, B, C, D, fH = md.A, md.B, md.C, md.D, self.f_H
        ebar = y - C @ self._z - D @ fH @ u                                          # (5)
        self._z = A @ self._z + B @ fH @ u + self.L @ ebar                           # (4)
        n = md.n
        eps, f, up = list(self._eps), list(self._f), list(self._u)
        tilde = eps[0] + sum(self.a[i] * eps[i] for i in range(1, n + 1))             # (35): ε(k−1) + Σ aᵢ ε(k−1−i)
        tilde = tilde + sum(self.M[i] @ (f[i] - f[i - 1]) @ up[i - 1] for i in range(1, n + 1))
        f_new = f[0]
        uu = float(u @ u)
        if uu >= self.min_input:
            f_new = f[0] + self._M0_inv @ np.outer(tilde, u) / uu                    # (38)
        e = y - C @ self._x - D @ f_new @ u                                          # (25)
        self._x = A @ self._x + B @ f_new @ u + self.L @ e                           # (24)
        if not (all_finite(e) and all_finite(f_new.ravel())):
            raise RobofdiError("GainFaultObserver: the estimate diverged (non-finite)")
        self._eps.appendleft(e)
        self._f.appendleft(f_new)
        self._u.appendleft(u)
        self.gain, self.innovation = f_new, e
        return Residual(ebar, np.diag(f_new).copy())
