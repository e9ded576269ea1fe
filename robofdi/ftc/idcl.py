"""Inverse-dynamics control law (IDCL) with weighted minimum-effort allocation and its reconfigured variants —
Bošković & Mehra, "Failure detection, identification and reconfiguration in flight control", eqs. (4), (5),
(39)–(43), (59)–(60), (65).

Pure design functions:

* :func:`check_weights` — W diagonal positive definite (the allocation minimises uᵀWu);
* :func:`allocation_matrix` — Θ_F = W⁻¹B̄ᵀ(B̄W⁻¹B̄ᵀ)⁻¹ with the columns of the failed effectors F removed
  (eq. (39) for F = ∅, eq. (42) for F = {i}); raises when B̄W⁻¹B̄ᵀ is singular (no feasible allocation);
* :func:`allocate` — u = Θ_F(η − Σ_{k∈F} b_k û_k) (eqs. (41), (43));
* :func:`redistributed_allocation` — the position-limit-aware variant (the chapter's CIMAS task (i), no
  algorithm given: redistributed pseudo-inverse), raising when no allocation within the limits exists;
* :func:`check_isolable` — pairwise non-collinear effector columns (a bank that must isolate them needs it);
* :func:`error_feedback_design` / :func:`error_feedback_lqr` / :func:`reference_model_design` — Λ and (A_m, B_m) such that
  Λ_o = [Ā; Λ] and [Ā; A_m] are Hurwitz (eqs. (57)–(60));
* :class:`ReferenceModel` — ẋ_m1 = Ā x_m, ẋ_m2 = A_m x_m + B_m r (eqs. (57)–(58)), validated Hurwitz, exact ZOH.

Stepping classes: :class:`IDCLController` (eq. (59), optionally fed with a sensor-bias estimate x̂ = y − d̂ (the
chapter's eq. (12) in the partitioned form) and a damage estimate ρ̂ (eq. (65) with C_j = I): together the
integrated FDIR of §7), and :class:`MultipleModelReallocation`, the accommodation that reconfigures the
allocation with the effectors a diagnosis isolated and their estimated stuck positions (eqs. (41)–(43)).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, solve_continuous_are
from scipy.signal import place_poles

from robofdi.errors import RobofdiError
from robofdi.protocols import Health

__all__ = ["check_weights", "allocation_matrix", "allocate", "redistributed_allocation", "check_isolable",
           "error_feedback_design", "error_feedback_lqr", "reference_model_design", "check_hurwitz", "ReferenceModel", "idcl_eta",
           "IDCLController", "MultipleModelReallocation"]


def check_weights(W, m: int) -> np.ndarray:
    """The diagonal of W as m values > 0; W may be given as its diagonal or as an m×m diagonal matrix."""
    w = np.asarray(W, dtype=float)
    if w.ndim == 2:
        if w.shape != (m, m) or not np.all(np.isfinite(w)):
            raise RobofdiError(f"allocation: field 'W' must be a finite {m}×{m} matrix or {m} weights, got shape {w.shape}")
        if np.any(np.abs(w - np.diag(np.diag(w))) > 0):
            raise RobofdiError("allocation: field 'W' must be diagonal (the chapter's W; Θ_i's i-th row is 0 "
                               "only then)")
        w = np.diag(w).copy()
    if w.shape != (m,) or not np.all(np.isfinite(w)):
        raise RobofdiError(f"allocation: field 'W' must hold {m} finite weights, got {W!r}")
    if np.any(w <= 0):
        raise RobofdiError(f"allocation: field 'W' must be positive definite (every diagonal entry > 0), got "
                           f"min {w.min()!r}")
    return w


def _B(B) -> np.ndarray:
    B = np.asarray(B, dtype=float)
    if B.ndim != 2 or B.shape[0] < 1 or B.shape[1] < B.shape[0] or not np.all(np.isfinite(B)):
        raise RobofdiError(f"allocation: field 'B' must be a finite p×m matrix with m >= p (over-actuated), "
                           f"got shape {B.shape}")
    return B


def _failed(failed, m: int) -> list[int]:
    out = sorted({int(i) for i in failed})
    if any(i < 0 or i >= m for i in out):
        raise RobofdiError(f"allocation: field 'failed' must hold effector indices in [0, {m - 1}], got {out}")
    return out


def allocation_matrix(B, W, failed: Sequence[int] = (), names: Sequence[str] | None = None) -> np.ndarray:
    """Θ_F = W⁻¹B̄ᵀ(B̄W⁻¹B̄ᵀ)⁻¹ (m × p), B̄ = B with the columns of ``failed`` zeroed — eqs. (39), (42).

    B̄Θ_F = I_p and the rows of failed effectors are 0. It is the minimiser of uᵀWu subject to B̄u = η. Raises
    when B̄W⁻¹B̄ᵀ is singular (the remaining effectors do not span the p axes: an infeasible allocation)."""
    B = _B(B)
    p, m = B.shape
    w = check_weights(W, m)
    F = _failed(failed, m)
    Bb = B.copy()
    Bb[:, F] = 0.0
    G = (Bb / w) @ Bb.T
    cond = np.linalg.cond(G)
    if not np.isfinite(cond) or cond > 1e12:
        lost = [names[i] for i in F] if names is not None else F
        raise RobofdiError(f"allocation: infeasible allocation: B̄ W⁻¹ B̄ᵀ is singular (condition {cond:.3g}); the "
                           f"effectors left after removing {lost} do not span the {p} controlled axes")
    return (Bb.T / w[:, None]) @ np.linalg.inv(G)


def allocate(B, W, eta, failed: Sequence[int] = (), stuck=None) -> np.ndarray:
    """u = Θ_F(η − Σ_{k∈F} b_k û_k) — eqs. (41), (43): the healthy effectors produce η given the failed ones held
    at ``stuck`` (m values, only the failed entries used; None: 0, i.e. float)."""
    B = _B(B)
    eta = np.asarray(eta, dtype=float)
    if eta.shape != (B.shape[0],) or not np.all(np.isfinite(eta)):
        raise RobofdiError(f"allocation: field 'eta' must be {B.shape[0]} finite values, got {eta!r}")
    F = _failed(failed, B.shape[1])
    v = eta.copy()
    if F and stuck is not None:
        s = np.asarray(stuck, dtype=float)
        v -= B[:, F] @ s[F]
    return allocation_matrix(B, W, F) @ v


def redistributed_allocation(B, W, eta, lower, upper, failed: Sequence[int] = (), stuck=None,
                             names: Sequence[str] | None = None) -> np.ndarray:
    """Position-limit-aware allocation (CIMAS task (i), §7; the chapter gives no algorithm — redistributed
    pseudo-inverse): allocate with (41); clip every effector beyond its limit to the limit, remove it and
    re-allocate the rest of η to the others; repeat. Raises when the limits leave no allocation of η."""
    B = _B(B)
    p, m = B.shape
    lo, hi = np.broadcast_to(np.asarray(lower, float), (m,)), np.broadcast_to(np.asarray(upper, float), (m,))
    F = _failed(failed, m)
    s = np.zeros(m) if stuck is None else np.asarray(stuck, dtype=float).copy()
    held = list(F)
    u = np.zeros(m)
    u[F] = s[F]
    for _ in range(m):
        try:
            free = allocate(B, W, eta, held, u)
        except RobofdiError:
            raise RobofdiError(f"allocation: infeasible allocation: η = {np.round(eta, 6).tolist()} needs more than "
                               f"the position limits of {[names[i] for i in held] if names else held}") from None
        over = [i for i in range(m) if i not in held and not (lo[i] - 1e-12 <= free[i] <= hi[i] + 1e-12)]
        if not over:
            free[held] = u[held]
            return free
        for i in over:
            u[i] = np.clip(free[i], lo[i], hi[i])
            held.append(i)
    raise RobofdiError("allocation: infeasible allocation: every effector is at a limit")


def check_isolable(B, names: Sequence[str], tolerance: float = 1e-3) -> None:
    """Every pair of effector columns must be non-collinear (|cos ∠(b_i, b_j)| < 1 − tolerance) and non-zero,
    or a lock of one cannot be told from a lock of the other (the multiple-model bank's requirement)."""
    B = np.asarray(B, dtype=float)
    norms = np.linalg.norm(B, axis=0)
    for i, nrm in enumerate(norms):
        if nrm == 0:
            raise RobofdiError(f"effector bank: effector {names[i]!r} has a zero column in B: its failure is "
                               "not observable")
    for i in range(B.shape[1]):
        for j in range(i + 1, B.shape[1]):
            c = abs(B[:, i] @ B[:, j]) / (norms[i] * norms[j])
            if c >= 1.0 - tolerance:
                raise RobofdiError(f"effector bank: effector columns {names[i]!r} and {names[j]!r} are collinear "
                                   f"(|cos| = {c:.6f}): a failure of one cannot be isolated from the other")


def check_hurwitz(M, what: str) -> None:
    """Raise naming ``what`` unless every eigenvalue of M has a negative real part."""
    ev = np.linalg.eigvals(np.asarray(M, dtype=float))
    if np.any(ev.real >= 0):
        worst = ev[np.argmax(ev.real)]
        raise RobofdiError(f"{what} must be Hurwitz; it has the eigenvalue {worst:.4g} (real part >= 0)")


def error_feedback_design(Abar, poles) -> np.ndarray:
    """Λ (p × n) placing the eigenvalues of Λ_o = [Ā; Λ] at ``poles`` (n values) — eq. (60)."""
    Abar = np.asarray(Abar, dtype=float)
    n1, n = Abar.shape
    p = n - n1
    Aaug = np.vstack([Abar, np.zeros((p, n))])
    Baug = np.vstack([np.zeros((n1, p)), np.eye(p)])
    K = place_poles(Aaug, Baug, np.asarray(poles, dtype=float)).gain_matrix
    Lam = -K
    check_hurwitz(np.vstack([Abar, Lam]), "the error dynamics Λ_o = [Ā; Λ]")
    return Lam


def error_feedback_lqr(Abar, Q, R) -> np.ndarray:
    """Λ (p × n) making Λ_o = [Ā; Λ] Hurwitz as the LQR gain of ė₁ = Ā e, ė₂ = v, v = Λe, with state weights
    ``Q`` (n values) and input weight ``R`` > 0 — eq. (60); small weights on slow states keep Λ's gains (and the
    sensor noise they amplify) small, which pole placement does not."""
    Abar = np.asarray(Abar, dtype=float)
    n1, n = Abar.shape
    p = n - n1
    Q = np.diag(np.broadcast_to(np.asarray(Q, dtype=float), (n,)))
    if np.any(np.diag(Q) < 0) or not (np.isfinite(R) and R > 0):
        raise RobofdiError(f"error_feedback_lqr: fields 'Q' >= 0 and 'R' > 0, got {np.diag(Q)}, {R!r}")
    Aaug = np.vstack([Abar, np.zeros((p, n))])
    Baug = np.vstack([np.zeros((n1, p)), np.eye(p)])
    X = solve_continuous_are(Aaug, Baug, Q, R * np.eye(p))
    Lam = -(Baug.T @ X) / R
    check_hurwitz(np.vstack([Abar, Lam]), "the error dynamics Λ_o = [Ā; Λ]")
    return Lam


def reference_model_design(Abar, poles, tracked: Sequence[int], R: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(A_m, B_m) of ẋ_m2 = A_m x_m + B_m r with [Ā; A_m] Hurwitz and unit DC gain from r (p values) to the
    states ``tracked`` (p indices of x) — eqs. (57)–(58). ``poles``: n eigenvalues (pole placement), or, with
    ``R``, the n LQR state weights of :func:`error_feedback_lqr`."""
    Am = error_feedback_lqr(Abar, poles, R) if R is not None else error_feedback_design(Abar, poles)
    Abar = np.asarray(Abar, dtype=float)
    n1, n = Abar.shape
    M = np.vstack([Abar, Am])
    E2 = np.vstack([np.zeros((n1, n - n1)), np.eye(n - n1)])
    dc = -np.linalg.solve(M, E2)[list(tracked)]              # x_ss = −M⁻¹[0; B_m] r
    return Am, np.linalg.inv(dc)


def idcl_eta(A2, Lam, Am, Bm, x, xm, r) -> np.ndarray:
    """η = −A x + Λ(x − x_m) + A_m x_m + B_m r — eq. (59) (the error-feedback form, digest's choice)."""
    return -A2 @ x + Lam @ (x - xm) + Am @ xm + Bm @ r


@dataclass(frozen=True, eq=False)
class ReferenceModel:
    """ẋ_m1 = Ā x_m (57), ẋ_m2 = A_m x_m + B_m r (58); [Ā; A_m] must be Hurwitz (eq. (4)'s A_m Hurwitz)."""

    Abar: np.ndarray
    Am: np.ndarray
    Bm: np.ndarray

    def __post_init__(self):
        Abar, Am, Bm = (np.asarray(v, dtype=float) for v in (self.Abar, self.Am, self.Bm))
        n1, n = Abar.shape
        if Am.shape != (n - n1, n) or Bm.shape[0] != n - n1:
            raise RobofdiError(f"ReferenceModel: fields 'Am' / 'Bm' must be {(n - n1, n)} / ({n - n1}, q), got "
                               f"{Am.shape} / {Bm.shape}")
        check_hurwitz(np.vstack([Abar, Am]), "ReferenceModel: the reference dynamics [Ā; A_m]")
        object.__setattr__(self, "Abar", Abar)
        object.__setattr__(self, "Am", Am)
        object.__setattr__(self, "Bm", Bm)

    @property
    def M(self) -> np.ndarray:
        return np.vstack([self.Abar, self.Am])

    def trajectory(self, r: Callable[[float], np.ndarray], duration: float, dt: float) -> np.ndarray:
        """x_m(k dt), k = 0..round(duration/dt), from x_m(0) = 0 with r held over each period (exact ZOH)."""
        n, q = self.M.shape[0], self.Bm.shape[1]
        big = np.zeros((n + q, n + q))
        big[:n, :n] = self.M
        big[self.Abar.shape[0]:n, n:] = self.Bm
        E = expm(big * dt)
        Phi, Gam = E[:n, :n], E[:n, n:]
        steps = int(round(duration / dt))
        out = np.zeros((steps + 1, n))
        for k in range(steps):
            out[k + 1] = Phi @ out[k] + Gam @ np.asarray(r(k * dt), dtype=float)
        return out


class IDCLController:
    """Controller protocol: u = Θ(B̂)η̂, η̂ = −Â x̂ + Λ(x̂ − x_m) + A_m x_m + B_m r — eqs. (59), (65) with C_j = I.

    ``reference(t)`` gives [r (q values), x_m (n values)]: the controller reads both from it. ``A2`` / ``B2``:
    callables ρ ↦ the x₂ rows of A(ρ) / B(ρ) (the belief). Optional estimators, each a diagnoser stepped by the
    controller itself on (y, its own previous u): ``sensor`` (with ``bias``: x̂ = y − d̂, the chapter's static
    estimate, eq. (12)) and ``damage`` (with ``rho``: Â = A(ρ̂), B̂ = B(ρ̂), eq. (65)). Without them it is the
    baseline IDCL, which uses y in place of x."""

    def __init__(self, A2: Callable[[float], np.ndarray], B2: Callable[[float], np.ndarray], W, Lam, reference: ReferenceModel,
                 sensor=None, damage=None):
        self.A2, self.B2, self.ref = A2, B2, reference
        B0 = np.asarray(B2(0.0), dtype=float)
        self.W = check_weights(W, B0.shape[1])
        self.Lam = np.asarray(Lam, dtype=float)
        check_hurwitz(np.vstack([reference.Abar, self.Lam]), "IDCLController: the error dynamics Λ_o = [Ā; Λ]")
        self.q = reference.Bm.shape[1]
        self.sensor, self.damage = sensor, damage
        self._theta0 = allocation_matrix(B0, self.W)
        self._A20 = np.asarray(A2(0.0), dtype=float)
        self.reset()

    def reset(self) -> None:
        self._u = np.zeros(self._theta0.shape[0])
        for est in (self.sensor, self.damage):
            if est is not None:
                est.reset()
        self.rho = 0.0

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        ref = np.asarray(reference, dtype=float)
        r, xm = ref[: self.q], ref[self.q:]
        x = np.asarray(y, dtype=float)
        if self.sensor is not None:
            self.sensor.update(y, self._u)
            x = x - self.sensor.bias
        if self.damage is not None:
            self.damage.update(y, self._u)
            self.rho = float(self.damage.rho)
        if self.rho > 0:
            A2, theta = self.A2(self.rho), allocation_matrix(self.B2(self.rho), self.W)
        else:
            A2, theta = self._A20, self._theta0
        self._u = theta @ idcl_eta(A2, self.Lam, self.ref.Am, self.ref.Bm, x, xm, r)
        return self._u.copy()


class MultipleModelReallocation:
    """Accommodation protocol: η = B u_cmd (u_cmd is the baseline allocation Θ₀η, so Bu_cmd = η) re-allocated as
    u = Θ_F(η − Σ_{k∈F} b_k û_k) — eqs. (41)–(43) — with F the effectors the health isolates and û their
    estimated stuck positions (the health's estimate). With ``lower`` / ``upper`` the allocation respects the
    position limits, with ``rate_limit`` [1/s] and ``dt`` [s] also the reach of each surface by the next sample
    (:func:`redistributed_allocation` on the set S_u of eq. (1), CIMAS task (i)); when even that is infeasible the
    limit-free allocation is used (the plant saturates it). ``failed`` holds what the last update used."""

    def __init__(self, B, W, effectors: Sequence[str], lower=None, upper=None, rate_limit=None, dt: float | None = None):
        self.B = _B(B)
        self.effectors = list(effectors)
        if self.B.shape[1] != len(self.effectors):
            raise RobofdiError(f"MultipleModelReallocation: field 'effectors' must name the {self.B.shape[1]} columns "
                               f"of B, got {self.effectors}")
        self.W = check_weights(W, self.B.shape[1])
        self._index = {e: i for i, e in enumerate(self.effectors)}
        self._theta: dict[tuple, np.ndarray] = {}
        self.lower = None if lower is None else np.broadcast_to(np.asarray(lower, float), (len(self.effectors),))
        self.upper = None if upper is None else np.broadcast_to(np.asarray(upper, float), (len(self.effectors),))
        if (rate_limit is None) != (dt is None) or (rate_limit is not None and self.lower is None):
            raise RobofdiError("MultipleModelReallocation: fields 'rate_limit' and 'dt' go together, with the "
                               "position limits 'lower' / 'upper'")
        self.step = None if rate_limit is None else np.asarray(rate_limit, float) * float(dt)
        self.reset()

    def reset(self) -> None:
        self.failed: tuple[str, ...] = ()
        self._u = np.zeros(len(self.effectors))

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        u = self._allocate(u_cmd, health)
        self._u = u
        return u.copy()

    def _allocate(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        eta = self.B @ np.asarray(u_cmd, dtype=float)
        F = tuple(sorted(self._index[t] for t in health.isolated if t in self._index))
        self.failed = tuple(self.effectors[i] for i in F)
        stuck_all = np.zeros(len(self.effectors))
        for i in F:
            stuck_all[i] = health.estimate.get(self.effectors[i], 0.0)
        if self.lower is not None:
            boxes = [(self.lower, self.upper)]
            if self.step is not None:           # rate limits: what the surfaces can reach by the next sample
                boxes.insert(0, (np.maximum(self.lower, self._u - self.step), np.minimum(self.upper, self._u + self.step)))
            for lo, hi in boxes:                # position and rate, else position only
                try:
                    u = redistributed_allocation(self.B, self.W, eta, lo, hi, F, stuck_all, self.effectors)
                    u[list(F)] = 0.0
                    return u
                except RobofdiError:
                    continue
        if not F:
            return np.array(u_cmd, dtype=float)
        if F not in self._theta:
            self._theta[F] = allocation_matrix(self.B, self.W, F, self.effectors)
        return self._theta[F] @ (eta - self.B[:, list(F)] @ stuck_all[list(F)])
