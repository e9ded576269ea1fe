"""Sliding-mode control with on-line control allocation — Edwards, Alwi & Tan, §6, eqs. (55)–(70) (after Alwi &
Edwards 2008). Equation numbers are the paper's.

Plant (55): ẋ = A x + B (I − K) u with B = [B1; B2] (B2 ∈ R^{l×m} of rank l, the last l states), K = diag(k_i) the
loss of effectiveness. The controller designs a virtual control ν = B2 u (56) and allocates it with the weighted
pseudo-inverse u = B2^†ν, B2^† = W B2ᵀ (B2 W B2ᵀ)⁻¹ (57), W = I − K̂ from the diagnosis (58).

* :func:`weighted_pinv` — B2^† of (57); refuses a health pattern for which B2 W B2ᵀ is singular (the remaining
  actuators cannot produce every virtual-control direction);
* :func:`smc_ca_design` — the design of §6: the state scaling that makes B2 B2ᵀ = I (erratum: the method needs
  orthonormal rows, not only ‖B2‖ = 1), T_r (59), the sliding surface σ = [N I] x̂ (61) with Ã11 = Â11 − Â12 N
  Hurwitz, γ0 (Proposition 5, sampled over W), γ1 = ‖N B1 B2^N‖ (65, "M" read as N), γ2 = ‖G̃‖∞ (64, Ã21 with the
  factor N on Â22) and the small-gain condition (66) checked — refused naming it when violated;
* :class:`SMCCAController` — the control law (67)–(70): ν̂ = −Ã21 x̂1 − Ã22 σ + Φσ − (ρ + η) σ/(‖σ‖ + δ), the
  adaptive gain ρ = r (l1‖x‖ + l2) with ṙ = a (l1‖x‖ + l2) D_ε(‖σ‖) − b r, ν from ν̂ by inverting (60), u = B2^†ν.

Saturation is not in the paper. Here: when the weighted pseudo-inverse u exceeds ``limit``, u is the bounded
least-squares solution of min ‖B2 u − ν‖² + ε uᵀ W⁻¹ u subject to |u_i| ≤ limit (the W-weighted form of
:func:`robofdi.ftc.allocation.constrained_allocation`, solved with scipy's ``lsq_linear`` because that function is
specific to the 6-row wrench map); ``last_unattained`` reports ν − B2 u.
"""
from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from scipy.optimize import lsq_linear

from robofdi.checks import is_number
from robofdi.errors import RobofdiError
from robofdi.models.linear import format_mode
from robofdi.observers.smo_reconstruction import hinf_norm
from robofdi.observers.sliding_mode import _mat

__all__ = ["weighted_pinv", "SMCCADesign", "smc_ca_design", "SMCCAController", "singular_patterns"]


def weighted_pinv(B2, w, where: str = "weighted_pinv") -> np.ndarray:
    """B2^† = W B2ᵀ (B2 W B2ᵀ)⁻¹ (57), W = diag(w); B2 B2^† = I_l for every admissible W."""
    B2 = np.asarray(B2, dtype=float)
    w = np.asarray(w, dtype=float).ravel()
    if w.shape != (B2.shape[1],) or not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w > 1):
        raise RobofdiError(f"{where}: field 'w' must hold {B2.shape[1]} weights in [0, 1] (W = I − K, eq. 58), "
                           f"got {w.tolist()}")
    G = (B2 * w) @ B2.T
    if np.linalg.matrix_rank(G) < B2.shape[0]:
        raise RobofdiError(f"{where}: B2 W B2ᵀ is singular for the health pattern w = {np.round(w, 4).tolist()} "
                           f"(eq. 57: the remaining actuators span rank {np.linalg.matrix_rank(B2 * w)} < l = "
                           f"{B2.shape[0]} virtual-control directions)")
    return (B2 * w).T @ np.linalg.inv(G)


def singular_patterns(B2, max_failures: int = 2) -> list[tuple[int, ...]]:
    """The sets of up to ``max_failures`` total failures (w_i = 0) for which B2 W B2ᵀ is singular (§8 of the
    seed digest's transfer note: the design-time redundancy check)."""
    B2 = np.asarray(B2, dtype=float)
    l, m = B2.shape
    bad = []
    for k in range(1, max_failures + 1):
        for idx in itertools.combinations(range(m), k):
            keep = [i for i in range(m) if i not in idx]
            if np.linalg.matrix_rank(B2[:, keep]) < l:
                bad.append(idx)
    return bad


@dataclass(frozen=True)
class SMCCADesign:
    """The §6 design. Coordinates: x̂ = ``Tr`` ``Tn`` x (``Tn`` scales the last l states so that B2 B2ᵀ = I; ``Tr``
    of (59)); ``A_hat`` = Â; ``B1`` / ``B2`` in the scaled coordinates; ``N`` with σ = [N I] x̂ (61), ``S`` = [N I]
    Tr Tn (σ = S x); ``A11t`` = Ã11, ``A21t`` = Ã21, ``A22t`` = Ã22; ``gamma0/1/2`` of Proposition 5 and (64)–(65);
    ``condition`` = γ2γ0/(1 − γ1γ0) of (66) (must be < 1; 0 when B1 = 0); ``sliding_poles`` = eig(Ã11)."""

    l: int
    Tn: np.ndarray
    Tr: np.ndarray
    A_hat: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    N: np.ndarray
    S: np.ndarray
    A11t: np.ndarray
    A21t: np.ndarray
    A22t: np.ndarray
    gamma0: float
    gamma1: float
    gamma2: float
    condition: float
    sliding_poles: np.ndarray
    w_min: float

    @property
    def B2N(self) -> np.ndarray:
        """B2^N = I − B2ᵀ B2 (59): the projector onto ker B2 (B2 B2ᵀ = I)."""
        return np.eye(self.B2.shape[1]) - self.B2.T @ self.B2

    def B2_plus(self, w) -> np.ndarray:
        """B2^+ = W² B2ᵀ (B2 W² B2ᵀ)⁻¹ (59)."""
        w = np.asarray(w, dtype=float)
        return weighted_pinv(self.B2, w * w, "SMCCADesign.B2_plus")

    def reduced(self, w) -> np.ndarray:
        """The sliding-motion matrix (63) for the weights w: Ã11 − B1 B2^N B2^+ (I + N B1 B2^N B2^+)⁻¹ Ã21."""
        E = self.B1 @ self.B2N @ self.B2_plus(w)
        return self.A11t - E @ np.linalg.solve(np.eye(self.l) + self.N @ E, self.A21t)


def smc_ca_design(A, B, l: int, poles: Sequence[complex], w_min: float = 0.05, samples: int = 2000, seed: int = 0,
                  patterns: Sequence[Sequence[float]] = ()) -> SMCCADesign:
    """Edwards, Alwi & Tan §6 design steps 1–4 (eqs. 56–66).

    ``l``: the number of virtual controls (B2 = the last l rows of B, rank l); ``poles``: the n − l eigenvalues of
    Ã11 = Â11 − Â12 N (61); γ0 = max ‖B2^+‖ over ``samples`` random W = diag(w), w_i ∈ [w_min, 1] (Proposition 5
    needs w_i > 0: w_min is the floor used on-line, erratum 11), plus W = I and the given ``patterns``. Refused: B2
    without rank l, (Â11, Â12) not controllable for ``poles``, and condition (66) γ2γ0/(1 − γ1γ0) < 1 violated."""
    where = "smc_ca_design"
    A = _mat(A, "A", where)
    n = A.shape[0]
    if A.shape != (n, n):
        raise RobofdiError(f"{where}: field 'A' must be square, got shape {A.shape}")
    B = _mat(B, "B", where, rows=n)
    m = B.shape[1]
    if not (isinstance(l, (int, np.integer)) and 0 < l < n and l <= m):
        raise RobofdiError(f"{where}: field 'l' must be an integer in [1, min(n − 1, m)] = [1, {min(n - 1, m)}], got {l!r}")
    if not (is_number(w_min) and 0 < w_min <= 1):
        raise RobofdiError(f"{where}: field 'w_min' must be in (0, 1] (Proposition 5 needs w_i > 0), got {w_min!r}")
    r = n - l
    B1, B2 = B[:r], B[r:]
    if np.linalg.matrix_rank(B2) < l:
        raise RobofdiError(f"{where}: B2 (the last l = {l} rows of B) must have rank l (eq. 56), got rank "
                           f"{np.linalg.matrix_rank(B2)}")
    U, s, _ = np.linalg.svd(B2, full_matrices=False)
    Sc = np.diag(1.0 / s) @ U.T                               # x2 ← Sc x2: B2 ← Sc B2 has orthonormal rows
    Tn = np.eye(n)
    Tn[r:, r:] = Sc
    An = Tn @ A @ np.linalg.inv(Tn)
    B2n = Sc @ B2
    Tr = np.eye(n)
    Tr[:r, r:] = -B1 @ B2n.T
    Ah = Tr @ An @ np.linalg.inv(Tr)
    A11, A12, A21, A22 = Ah[:r, :r], Ah[:r, r:], Ah[r:, :r], Ah[r:, r:]
    p = np.array(poles, dtype=complex).ravel()
    if p.shape != (r,) or np.any(p.real >= 0):
        raise RobofdiError(f"{where}: field 'poles' must be {r} eigenvalues with Re < 0 of Â11 − Â12 N (eq. 61), "
                           f"got {poles!r}")
    try:
        N = np.real(scipy.signal.place_poles(A11, A12, p).gain_matrix)
    except ValueError as exc:
        raise RobofdiError(f"{where}: field 'poles' cannot be placed on (Â11, Â12) (eq. 61: (A, B_ν) must be "
                           f"controllable): {exc}") from None
    A11t = A11 - A12 @ N
    A21t = N @ A11t + A21 - A22 @ N                          # erratum: the factor N on Â22
    A22t = A22 + N @ A12
    B2N = np.eye(m) - B2n.T @ B2n
    rng = np.random.default_rng(seed)
    ws = [np.ones(m)] + [np.clip(np.asarray(w, dtype=float), w_min, 1.0) for w in patterns]
    ws += list(rng.uniform(w_min, 1.0, size=(int(samples), m)))
    g0 = 0.0
    for w in ws:
        g0 = max(g0, float(np.linalg.norm(weighted_pinv(B2n, w * w, where), 2)))
    E = B1 @ B2N
    g1 = float(np.linalg.norm(N @ E, 2)) if E.size else 0.0
    g2 = hinf_norm(A11t, E, A21t) if np.linalg.norm(E) > 1e-12 else 0.0
    if g1 * g0 >= 1:
        raise RobofdiError(f"{where}: condition (66) violated: γ1γ0 = {g1 * g0:.4g} >= 1 (γ0 = {g0:.4g}, γ1 = "
                           f"{g1:.4g}; Proposition 6 needs γ2γ0/(1 − γ1γ0) < 1)")
    cond = g2 * g0 / (1 - g1 * g0)
    if cond >= 1:
        raise RobofdiError(f"{where}: condition (66) violated: γ2γ0/(1 − γ1γ0) = {cond:.4g} >= 1 (γ0 = {g0:.4g}, "
                           f"γ1 = {g1:.4g}, γ2 = {g2:.4g}): stability of the sliding motion under every W is not "
                           "guaranteed; choose other poles or reduce ‖B1‖")
    sl = np.linalg.eigvals(A11t)
    S = np.hstack([N, np.eye(l)]) @ Tr @ Tn
    return SMCCADesign(l, Tn, Tr, Ah, B1, B2n, N, S, A11t, A21t, A22t, g0, g1, g2, float(cond), sl, float(w_min))


class SMCCAController:
    """The §6 control law (67)–(70) with on-line allocation: ``update(x, w_hat)`` → u.

    x: the state error (regulation to 0, as in the paper; for tracking pass x − x_ref of an equilibrium reference);
    w_hat: the diagnosed effectiveness 1 − k̂_i (clipped to [w_min, 1]); dt: the control period [s] (the adaptive
    gain (70) is integrated with explicit Euler); Phi: the stable design matrix on σ (not in the paper, default −I);
    eta: η of (68); l1, l2, a, b, eps: the adaptation (69)–(70); delta: the boundary layer of σ/‖σ‖ (Remark 4's
    sigmoid); limit: the actuator bound (None: none)."""

    def __init__(self, design: SMCCADesign, dt: float, Phi=None, eta: float = 0.1, l1: float = 1.0, l2: float = 0.1,
                 a: float = 1.0, b: float = 0.1, eps: float = 0.01, delta: float = 0.01, limit: float | None = None,
                 regularisation: float = 1e-6):
        where = "SMCCAController"
        for name, v in (("dt", dt), ("eta", eta), ("l1", l1), ("l2", l2), ("a", a), ("b", b), ("eps", eps),
                        ("delta", delta)):
            if not (is_number(v) and v >= 0) or (name in ("dt", "delta") and v <= 0):
                raise RobofdiError(f"{where}: field {name!r} must be a number >= 0 (dt, delta > 0), got {v!r}")
        if limit is not None and not (is_number(limit) and limit > 0):
            raise RobofdiError(f"{where}: field 'limit' must be an actuator bound > 0, got {limit!r}")
        self.d, self.dt = design, float(dt)
        l = design.l
        self.Phi = -np.eye(l) if Phi is None else _mat(Phi, "Phi", where, rows=l, cols=l)
        ev = np.linalg.eigvals(self.Phi)
        if np.max(ev.real) >= 0:
            raise RobofdiError(f"{where}: field 'Phi' must be Hurwitz, eigenvalue {format_mode(ev[np.argmax(ev.real)])}")
        self.eta, self.l1, self.l2, self.a, self.b = float(eta), float(l1), float(l2), float(a), float(b)
        self.eps, self.delta = float(eps), float(delta)
        self.limit = None if limit is None else float(limit)
        self.regularisation = float(regularisation)
        self._T = design.Tr @ design.Tn
        # u acts through the original B2; ν is the virtual control of the scaled B2 (= Sc B2 u)
        self.reset()

    def reset(self) -> None:
        self.r = 0.0
        self.sigma = np.zeros(self.d.l)
        self.last_unattained = np.zeros(self.d.l)

    def update(self, x, w_hat) -> np.ndarray:
        """u for the state error x and the diagnosed effectiveness ``w_hat``: :meth:`allocate` of :meth:`virtual`."""
        return self.allocate(self.virtual(x), w_hat)

    def virtual(self, x) -> np.ndarray:
        """ν̂ of (67)–(69) in the scaled coordinates (B2 B2ᵀ = I) for the state error x; steps the adaptive gain
        (70) by ``dt`` and keeps σ."""
        d = self.d
        n = self._T.shape[0]
        x = np.asarray(x, dtype=float)
        if x.shape != (n,) or not np.all(np.isfinite(x)):
            raise RobofdiError(f"SMCCAController: input 'x' must be {n} finite state errors, got {x!r}")
        xh = self._T @ x
        r = n - d.l
        x1 = xh[:r]
        sigma = d.N @ x1 + xh[r:]
        ns = float(np.linalg.norm(sigma))
        gain = self.l1 * float(np.linalg.norm(x)) + self.l2
        rho = self.r * gain
        nu_hat = -d.A21t @ x1 - d.A22t @ sigma + self.Phi @ sigma - (rho + self.eta) * sigma / (ns + self.delta)
        self.r += self.dt * (self.a * gain * (ns if ns >= self.eps else 0.0) - self.b * self.r)   # (70)
        self.sigma = sigma
        return nu_hat

    def allocate(self, nu_hat, w_hat) -> np.ndarray:
        """u = B2^† ν with ν = (B2 W B2ᵀ)(B2 W² B2ᵀ)⁻¹ ν̂ (inverting (60)), W = diag(ŵ) clipped to [w_min, 1] (57);
        the W-weighted bounded least squares when u exceeds ``limit``."""
        d = self.d
        w = np.clip(np.asarray(w_hat, dtype=float), d.w_min, 1.0)
        B2 = d.B2
        G1, G2 = (B2 * w) @ B2.T, (B2 * (w * w)) @ B2.T
        nu = G1 @ np.linalg.solve(G2, nu_hat)                 # inverts ν̂ = (B2 W² B2ᵀ)(B2 W B2ᵀ)⁻¹ ν (60)
        u = weighted_pinv(B2, w, "SMCCAController") @ nu      # (57)
        if self.limit is not None and np.any(np.abs(u) > self.limit):
            Wi = np.sqrt(self.regularisation / w)
            Aq = np.vstack([B2, np.diag(Wi)])
            bq = np.concatenate([nu, np.zeros(B2.shape[1])])
            u = lsq_linear(Aq, bq, bounds=(-self.limit, self.limit), method="bvls").x
        self.last_unattained = nu - B2 @ u
        return u
