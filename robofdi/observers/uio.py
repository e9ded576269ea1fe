"""Unknown-input observers and the adaptive multiple-model bank for lock-in-place faults — Guo, Jiang, Zhang & Wang,
"Novel robust fault diagnosis method for flight control systems", J. Syst. Eng. Electron. 19(5), 2008, eqs. (2)–(21).

The UIO algebra (2)–(11) is applied to the plant sampled with a zero-order hold, x(k+1) = A x + B u + E ξ, y = C x
(the discrete form of Chen & Patton, *Robust Model-Based Fault Diagnosis*, 1999, Sec. 3.2):

    z(k+1) = F z(k) + T B u(k) + K y(k),   x̂ = z + H y,   H = E[(CE)ᵀCE]⁻¹(CE)ᵀ,  T = I − HC,
    A₁ = T A,  F = A₁ − K₁C,  K₂ = F H,  K = K₁ + K₂   ⇒   e(k+1) = F e(k) whatever ξ (exact decoupling).

Existence (Theorem 1): rank(CE) = rank(E) and (C, A₁) detectable. The observer poles are given in the s-plane
(the paper's σ: F = −σI) and mapped to z = e^{s·dt}.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.signal

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import LinearModel, format_mode, require_discrete, unobservable_modes, vector_field
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["UIODesign", "uio_design", "UnknownInputObserver", "LockInPlaceBank", "spr_output_gains"]


@dataclass(frozen=True)
class UIODesign:
    """Matrices of a discrete UIO (see the module docstring); ``decoupling`` = ‖(HC − I)E‖."""

    F: np.ndarray
    T: np.ndarray
    H: np.ndarray
    K: np.ndarray
    K1: np.ndarray
    A1: np.ndarray
    decoupling: float


def uio_design(model: LinearModel, poles: Sequence[complex], E=None) -> UIODesign:
    """UIO for the discrete ``model`` with unknown-input matrix E (default model.E) — Guo et al. (2008) eqs. (2)–(11).

    poles: n observer poles in the s-plane (Re < 0; e.g. [−3]*n for the paper's σ = 3), placed at e^{s·dt}. With
    rank(C) = n, K₁ = (A₁ − F) C⁻¹ gives F = diag(e^{s·dt}) (eq. (10)); otherwise scipy's place_poles on (A₁ᵀ, Cᵀ).
    """
    where = "uio_design"
    model = require_discrete(model, where, "diagnosis")
    n = model.n
    E = model.E if E is None else np.array(E, dtype=float)
    if E.ndim == 1:
        E = E[:, None]
    if E.ndim != 2 or E.shape[0] != n or not np.all(np.isfinite(E)):
        raise RobofdiError(f"{where}: field 'E' must be a finite {n}xq matrix, got shape {E.shape}")
    if E.shape[1] == 0:
        raise RobofdiError(f"{where}: field 'E' is empty: a UIO needs an unknown-input matrix (model.E or E=...)")
    A, C = model.A, model.C
    rank_E = np.linalg.matrix_rank(E)
    if rank_E < E.shape[1]:
        raise RobofdiError(f"{where}: E must have full column rank, got rank {rank_E} for {E.shape[1]} columns")
    CE = C @ E
    rank_CE = np.linalg.matrix_rank(CE)
    if rank_CE != rank_E:
        raise RobofdiError(f"{where}: Theorem 1 needs rank(CE) = rank(E), got rank(CE) = {rank_CE}, rank(E) = {rank_E}")
    try:
        s = np.array(poles, dtype=complex).ravel()
    except (TypeError, ValueError):
        raise RobofdiError(f"{where}: field 'poles' must be {n} numbers, got {poles!r}") from None
    if s.shape != (n,) or not np.all(np.isfinite(s)) or np.any(s.real >= 0):
        raise RobofdiError(f"{where}: field 'poles' must be {n} s-plane poles with Re < 0, got {poles!r}")
    z = np.exp(s * model.dt)
    H = E @ np.linalg.solve(CE.T @ CE, CE.T)
    T = np.eye(n) - H @ C
    A1 = T @ A
    bad = [lam for lam in unobservable_modes(A1, C) if abs(lam) >= 1.0 - 1e-12]
    if bad:
        raise RobofdiError(f"{where}: Theorem 1 needs (C, A₁) detectable: mode λ={format_mode(bad[0])} of A₁ unobservable")
    if np.linalg.matrix_rank(C) == n:
        if np.any(np.abs(z.imag) > 1e-12):
            raise RobofdiError(f"{where}: with rank(C) = n the poles must be real (F is diagonal), got {poles!r}")
        F = np.diag(z.real)
        K1 = (A1 - F) @ np.linalg.pinv(C)
    else:
        try:
            K1 = np.real(scipy.signal.place_poles(A1.T, C.T, z.real if np.all(np.abs(z.imag) < 1e-12) else z)
                         .gain_matrix.T)
        except ValueError as exc:
            raise RobofdiError(f"{where}: field 'poles' cannot be placed for (A₁, C): {exc}") from None
        F = A1 - K1 @ C
    rho = float(np.max(np.abs(np.linalg.eigvals(F))))
    if not rho < 1.0:
        raise RobofdiError(f"{where}: F = A₁ − K₁C is not stable (spectral radius {rho:.6g})")
    K = K1 + F @ H
    return UIODesign(F=F, T=T, H=H, K=K, K1=K1, A1=A1, decoupling=float(np.linalg.norm((H @ C - np.eye(n)) @ E)))


class UnknownInputObserver:
    """Diagnoser protocol: one UIO, residual r = y − C x̂ per output (named like the outputs), decoupled from ξ.

    A fault that is not along E drives r through e(k+1) = F e + T b f; signatures come from the DC gains
    C (I − F)⁻¹ T bⱼ (required: outputs with at least 30 % of the largest gain). Estimates: none.
    """

    def __init__(self, model: LinearModel, poles: Sequence[complex], E=None):
        self.model = model = require_discrete(model, "UnknownInputObserver", "diagnosis")
        self.design = uio_design(model, poles, E)
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(model.output_names)
        self.estimate_components: list[str] = []
        self.estimate_modes: list[str] = []
        self.units = {"residual": list(model.units["y"]), "estimate": []}
        self.reset()

    def reset(self) -> None:
        self._z = None
        self._y = None

    def signatures(self) -> list:
        from robofdi.decision import Signature

        d, md = self.design, self.model
        gain = np.abs(md.C @ np.linalg.solve(np.eye(md.n) - d.F, d.T @ md.B))
        out = []
        for j, a in enumerate(self.inputs):
            g = gain[:, j]
            if g.max() <= 1e-12:
                continue
            req = frozenset(c for c, v in zip(self.components, g) if v >= 0.3 * g.max())
            out.append(Signature(a, req, frozenset(c for c, v in zip(self.components, g) if v > 1e-9) - req))
        return out

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        md, d = self.model, self.design
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        if self._z is None:
            self._z = d.T @ np.linalg.lstsq(md.C, y, rcond=None)[0]
        else:
            self._z = d.F @ self._z + d.T @ md.B @ u + d.K @ self._y
        self._y = y
        r = y - md.C @ (self._z + d.H @ y)
        return Residual(r, np.zeros(0))

    @property
    def state_estimate(self) -> np.ndarray | None:
        return None if self._z is None else self._z + self.design.H @ self._y


def spr_output_gains(P, TB, C, names=None, tol: float = 1e-8) -> np.ndarray:
    """Rows Gᵢᵀ with P T bᵢ = Cᵀ Gᵢ (the Kalman–Yakubovich / SPR output condition of Guo et al.'s law (16), spec B.2
    [ERRATUM]), by least squares; refuses (naming the actuator) when the relative residual exceeds ``tol``."""
    P, TB, C = (np.asarray(v, dtype=float) for v in (P, TB, C))
    names = list(names) if names is not None else [str(i) for i in range(TB.shape[1])]
    target = P @ TB                                                       # column i: P T bᵢ
    G = np.linalg.lstsq(C.T, target, rcond=None)[0]                       # column i: Gᵢ
    for i in range(TB.shape[1]):
        miss = np.linalg.norm(C.T @ G[:, i] - target[:, i])
        scale = np.linalg.norm(target[:, i])
        if scale > 0 and miss > tol * scale:
            raise RobofdiError(f"LockInPlaceBank: output_form 'spr' needs P T bᵢ in the range of Cᵀ; actuator "
                               f"{names[i]!r} misses it by {miss / scale:.3g} (relative): use output_form='pinv' or "
                               f"another Q_lyap")
    return G.T


class LockInPlaceBank:
    """Diagnoser protocol: the adaptive multiple-model bank of Guo et al. (2008) eqs. (12)–(18).

    One UIO per actuator i, built for B_i (column i removed) with the lock value ûᵢ fed through T bᵢ and adapted by
    the discrete counterpart of eq. (16) with the digest's corrections (spec B.2 [ERRATUM]: T bᵢ for P bᵢ, the output
    form P C⁺ rᵢ for the unmeasurable eᵢ):

        ûᵢ(k) = Proj_[u_min, u_max]( ûᵢ(k−1) + γᵢ (T bᵢ)ᵀ P C⁺ rᵢ(k) ),   F_cᵀP + P F_c = −Q_lyap   (scipy)

    F_c = diag(poles) is the s-plane observer matrix (P = I/(2σ) for the paper's F = −σI, Q = I). Plus a nominal
    UIO (all actuators healthy) for detection. Residual components: "nominal", then one per actuator — the norms
    ‖r₀‖, ‖rᵢ‖ (output units of the weighted residual, W = ``weights``); estimate: ûᵢ per actuator (lock value).

    output_form: how the unmeasurable P eᵢ of (16) is formed from rᵢ = C eᵢ (spec B.2 [ERRATUM]):
    "pinv" (default) P C⁺ rᵢ — exact when C has full column rank (C⁺C = I, the paper's square C); for a non-square
    C (p < n) it sees only the projection C⁺C eᵢ and the Lyapunov argument of Theorem 2 does not hold.
    "spr" the output form of the Kalman–Yakubovich (SPR) condition P T bᵢ = Cᵀ Gᵢ: ûᵢ += γᵢ Gᵢᵀ rᵢ, which equals
    γᵢ (T bᵢ)ᵀ P eᵢ exactly for any C; refused (one-line error) when the condition does not hold for the P of
    ``Q_lyap`` (then no output-only law with this P has the Lyapunov decrease).
    """

    def __init__(self, model: LinearModel, poles: Sequence[complex], E=None, gamma=50.0, u_min=-2.0, u_max=2.0,
                 weights=None, Q_lyap=None, output_form: str = "pinv"):
        where = "LockInPlaceBank"
        if output_form not in ("pinv", "spr"):
            raise RobofdiError(f"{where}: field 'output_form' must be 'pinv' or 'spr', got {output_form!r}")
        self.output_form = output_form
        self.model = model = require_discrete(model, where, "diagnosis")
        n, m, p = model.n, model.m, model.p
        self.design = d = uio_design(model, poles, E)
        self.gamma = vector_field(gamma, m, "gamma", where, 50.0, positive=True)
        self.u_min = vector_field(u_min, m, "u_min", where, -2.0)
        self.u_max = vector_field(u_max, m, "u_max", where, 2.0)
        if np.any(self.u_min >= self.u_max):
            raise RobofdiError(f"{where}: field 'u_min' must be < u_max for every actuator (projection bounds)")
        self.weights = vector_field(weights, p, "weights", where, 1.0, positive=True)
        Fc = np.diag(np.log(np.diag(d.F))) / model.dt if np.allclose(d.F, np.diag(np.diag(d.F))) else \
            scipy.linalg.logm(d.F).real / model.dt
        Ql = np.eye(n) if Q_lyap is None else np.array(Q_lyap, dtype=float)
        if Ql.shape != (n, n) or np.linalg.eigvalsh(0.5 * (Ql + Ql.T)).min() <= 0:
            raise RobofdiError(f"{where}: field 'Q_lyap' must be a positive-definite {n}x{n} matrix")
        self.P = scipy.linalg.solve_continuous_lyapunov(Fc.T, -Ql)
        self._Cpinv = np.linalg.pinv(model.C)
        self._Tb = d.T @ model.B                                          # column i: T bᵢ
        if output_form == "pinv":
            self._adapt = (self._Tb.T @ self.P @ self._Cpinv) * self.gamma[:, None]   # row i: γᵢ (T bᵢ)ᵀ P C⁺
        else:
            self._adapt = self.gamma[:, None] * spr_output_gains(self.P, self._Tb, model.C, model.input_names)
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = ["nominal"] + [f"lock_{a}" for a in self.inputs]
        self.estimate_components = list(self.inputs)
        self.estimate_modes = ["level"] * m
        self.units = {"residual": ["weighted output"] * (m + 1), "estimate": list(model.units["u"])}
        self.reset()

    def reset(self) -> None:
        self._z = None
        self._y = None
        self.lock_estimate = np.zeros(self.model.m)
        self.residuals = None

    def signatures(self) -> list:
        """Actuator i: the nominal residual must alarm; which model wins is the switching index's job."""
        from robofdi.decision import Signature

        return [Signature(a, frozenset({"nominal"}), frozenset({f"lock_{a}"})) for a in self.inputs]

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y(k), u(k−1) → [‖r₀‖, ‖r₁‖, …, ‖r_m‖] and the lock estimates ûᵢ(k)."""
        md, d = self.model, self.design
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        m = md.m
        if self._z is None:
            z0 = d.T @ np.linalg.lstsq(md.C, y, rcond=None)[0]
            self._z = np.tile(z0, (m + 1, 1))                             # row 0: nominal, row i: lock of input i
        else:
            Bu = d.T @ md.B @ u
            drive = np.empty_like(self._z)
            drive[0] = Bu
            drive[1:] = Bu - self._Tb.T * u[:, None] + self._Tb.T * self.lock_estimate[:, None]  # T Bᵢ u + T bᵢ ûᵢ
            self._z = self._z @ d.F.T + drive + d.K @ self._y
        self._y = y
        xhat = self._z + d.H @ y
        r = y[None, :] - xhat @ md.C.T                                    # (m+1) × p
        self.lock_estimate = np.clip(self.lock_estimate + np.einsum("ip,ip->i", self._adapt, r[1:]),
                                     self.u_min, self.u_max)
        if not (all_finite(r.ravel()) and all_finite(self.lock_estimate)):
            raise RobofdiError("LockInPlaceBank: the observers diverged (non-finite); check the model and gains")
        self.residuals = r
        norms = np.linalg.norm(r * self.weights, axis=1)
        return Residual(norms, self.lock_estimate.copy())
