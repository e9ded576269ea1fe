"""Sliding-mode observers for actuator-fault reconstruction — C. Edwards, H. Alwi & C. P. Tan, "Sliding mode methods
for fault detection and fault tolerant control with application to aerospace systems", Int. J. Appl. Math.
Comput. Sci. (manuscript received January 2011), §2–§3 (after Edwards, Spurgeon & Patton 2000 and Tan & Edwards
2003). Equation numbers are the paper's.

Design functions (pure):

* :func:`equivalent_injection` — the first-order SMO (3)/(7): during sliding (e_y ≡ 0) the equivalent output error
  injection is ν_eq = (C G_n)⁻¹ (C M ξ − C A e) and the error slides on ker C with the reduced matrix returned;
* :func:`canonical_form` — the canonical coordinates of (12)–(13): C = [0 T] (T orthogonal), M = [0; 0; M_o]; with
  the existence conditions A1 (rank(CM) = q) and A2 ((A, M, C) minimum phase: the unobservable modes of
  (A11, A211) are the invariant zeros) checked, a violated one refused naming it;
* :func:`reconstruction_design` — L = [L_o 0], G_l, G_n = [−L Tᵀ; Tᵀ] (the Edwards–Spurgeon sign, see below), W =
  [W_1 M_o⁻¹] Tᵀ of (14)–(15), by pole placement or by the bounded-real LMI on Ĝ(s) of (16) (``method="lmi"``,
  needs cvxpy);
* :func:`sensor_fault_system` — §5 (44)–(47): the incipient sensor fault f_o appended to the state, x_a = [x; f_o],
  A_a = [[A, 0], [0, 0]], F_a = [0; I_q], C_a = [C F]; φ = ḟ_o is the "actuator fault" of the §3 design, f̂_o = C_f z_a;
* :func:`cascade_design` — §4 (17)–(38): the cascade of fictitious systems for rank(CM) < q and its stopping rule
  (design only: the stages' ranks, L̄_o and sliding matrices);
* :func:`hinf_norm` — ‖G‖∞ of a stable state-space system (Hamiltonian iteration, Bruinsma & Steinbuch 1990):
  the L2 gain γ of (11) for a given design.

Stepping (one ``update``, Diagnoser protocol): :class:`SMOReconstructor`, the observer (7)–(8) with f̂ = W ν_eq (10),
integrated by the chapter-1 kernel (:class:`robofdi.observers.sliding_mode.CascadeSMO`, ``switching="unit"``:
ν = −ρ e_y/‖e_y‖ exactly, sub-stepped; ν_eq is the interval mean of ν).

Conventions (errata of the paper, documented): e_y = C z − y as in (8), so ν of (8) is −ν of (3) and ν_eq → +ξ in the
pendulum demo (with the printed (3) the low-pass ν tracks −ξ); (14) as printed gives the sliding matrix
A11 − L A21 while (16) has A11 + L A211: we use G_n = [−L Tᵀ; Tᵀ], with which (16) holds as printed (and which is the
form of (51)).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.signal

from robofdi.checks import is_number
from robofdi.errors import RobofdiError
from robofdi.models.linear import format_mode, unobservable_modes
from robofdi.observers.residual import Residual
from robofdi.observers.sliding_mode import CascadeSMO, SMOSettings, Stage, _mat

__all__ = ["EquivalentInjection", "CanonicalForm", "ReconstructionDesign", "equivalent_injection", "canonical_form",
           "reconstruction_design", "hinf_norm", "SMOReconstructor", "HAS_CVXPY", "SensorFaultSystem",
           "sensor_fault_system", "sensor_fault_observer", "CascadeStage", "cascade_design"]

try:                                                    # pragma: no cover - depends on the install
    import cvxpy as _cp
    HAS_CVXPY = True
except ImportError:                                     # pragma: no cover
    _cp = None
    HAS_CVXPY = False

_TOL = 1e-9


def _square(A, where: str) -> np.ndarray:
    A = _mat(A, "A", where)
    if A.shape[0] != A.shape[1]:
        raise RobofdiError(f"{where}: field 'A' must be square, got shape {A.shape}")
    return A


def _rank(X) -> int:
    return int(np.linalg.matrix_rank(X)) if X.size else 0


# ----------------------------------------------------------------------------------------------------- §2
@dataclass(frozen=True)
class EquivalentInjection:
    """Sliding on e_y = 0 of ė = (A − G_l C) e + G_n ν − M ξ: ν_eq = −``Phi`` e + ``Xi`` ξ with Phi = (C G_n)⁻¹ C A,
    Xi = (C G_n)⁻¹ C M; the reduced error motion ė_N = ``sliding`` e_N on ker C (e = N e_N, N orthonormal) with its
    ``sliding_poles`` (the invariant zeros of (A, G_n, C))."""

    Phi: np.ndarray
    Xi: np.ndarray | None
    N: np.ndarray
    sliding: np.ndarray
    sliding_poles: np.ndarray


def equivalent_injection(A, C, G_n, M=None) -> EquivalentInjection:
    """Edwards et al. §2, eqs. (1)–(3): setting ė_y = C ė = 0 in the error system gives the equivalent output error
    injection; C G_n must be invertible (the injection acts on every output)."""
    where = "equivalent_injection"
    A = _square(A, where)
    n = A.shape[0]
    C = _mat(C, "C", where, cols=n)
    G_n = _mat(G_n, "G_n", where, rows=n, cols=C.shape[0])
    CG = C @ G_n
    if _rank(CG) < C.shape[0]:
        raise RobofdiError(f"{where}: C G_n must be invertible (eq. 3: the switching term reaches every output), got "
                           f"rank {_rank(CG)} for {C.shape[0]} outputs")
    CGi = np.linalg.inv(CG)
    Xi = None
    if M is not None:
        M = _mat(M, "M", where, rows=n)
        Xi = CGi @ C @ M
    P = np.eye(n) - G_n @ CGi @ C                         # the projector along G_n onto ker C
    N = scipy.linalg.null_space(C)
    S = N.T @ P @ A @ N
    return EquivalentInjection(CGi @ C @ A, Xi, N, S, np.linalg.eigvals(S) if S.size else np.zeros(0))


# ----------------------------------------------------------------------------------------------------- §3
@dataclass(frozen=True)
class CanonicalForm:
    """Coordinates x_c = ``Tt`` x of (12)–(13): A_c = [[A11, A12], [A21, A22]] (A11 (n−p)×(n−p)), M_c = [0; 0; M_o]
    (M_o q×q nonsingular), C_c = [0 T] (T p×p orthogonal), Q_c = [Q1; Q2]; A211 / Q21 are the top p − q rows of A21
    / Q2; ``zeros`` the invariant zeros of (A, M, C) (the unobservable modes of (A11, A211))."""

    Tt: np.ndarray
    A: np.ndarray
    B: np.ndarray | None
    M: np.ndarray
    C: np.ndarray
    Q: np.ndarray | None
    T: np.ndarray
    M_o: np.ndarray
    n: int
    p: int
    q: int
    zeros: tuple[complex, ...]

    @property
    def A11(self):
        r = self.n - self.p
        return self.A[:r, :r]

    @property
    def A12(self):
        r = self.n - self.p
        return self.A[:r, r:]

    @property
    def A21(self):
        r = self.n - self.p
        return self.A[r:, :r]

    @property
    def A22(self):
        r = self.n - self.p
        return self.A[r:, r:]

    @property
    def A211(self):
        return self.A21[: self.p - self.q]

    @property
    def Q1(self):
        return None if self.Q is None else self.Q[: self.n - self.p]

    @property
    def Q2(self):
        return None if self.Q is None else self.Q[self.n - self.p:]

    @property
    def Q21(self):
        return None if self.Q is None else self.Q2[: self.p - self.q]


def canonical_form(A, M, C, Q=None, B=None) -> CanonicalForm:
    """The canonical form of Edwards et al. (12)–(13) built numerically: T_0 = [N_cᵀ; C] (N_c an orthonormal basis
    of ker C: C T_0⁻¹ = [0 I]), T_b = [[I, −M_1 M_2⁺], [0, I]] (zeroes the top block of M), T_r orthogonal from the
    complete QR of M_2 = CM with T_r M_2 = [0; M_o]; Tt = blkdiag(I, T_r) T_b T_0, T = T_rᵀ.

    Refused (RobofdiError naming the condition): C without full row rank, M without full column rank, A1
    rank(CM) < q (the fault does not act on the outputs with relative degree one: the cascade of §4 is needed), A2
    an invariant zero of (A, M, C) with Re >= 0 (not minimum phase: the sliding motion cannot be made stable)."""
    where = "canonical_form"
    A = _square(A, where)
    n = A.shape[0]
    C = _mat(C, "C", where, cols=n)
    M = _mat(M, "M", where, rows=n)
    p, q = C.shape[0], M.shape[1]
    if _rank(C) < p:
        raise RobofdiError(f"{where}: field 'C' must have full row rank (eq. 5), got rank {_rank(C)} for {p} rows")
    if _rank(M) < q:
        raise RobofdiError(f"{where}: field 'M' must have full column rank (eq. 4), got rank {_rank(M)} for {q} columns")
    rCM = _rank(C @ M)
    if rCM < q:
        raise RobofdiError(f"{where}: assumption A1 violated: rank(CM) = {rCM} < q = {q} (Edwards et al. §3; the "
                           "faults need relative degree one: use the cascade of §4)")
    Qm = None if Q is None else _mat(Q, "Q", where, rows=n)
    Bm = None if B is None else _mat(B, "B", where, rows=n)
    r = n - p
    Nc = scipy.linalg.null_space(C)
    T0 = np.vstack([Nc.T, C])
    M0 = T0 @ M
    M1, M2 = M0[:r], M0[r:]
    Tb = np.eye(n)
    Tb[:r, r:] = -M1 @ np.linalg.pinv(M2)
    Qf, _ = np.linalg.qr(M2, mode="complete")             # M2 = Qf [R; 0]
    Tr = np.vstack([Qf[:, q:].T, Qf[:, :q].T])            # Tr M2 = [0; R]
    Tt = scipy.linalg.block_diag(np.eye(r), Tr) @ Tb @ T0
    Ti = np.linalg.inv(Tt)
    Ac, Mc, Cc = Tt @ A @ Ti, Tt @ M, C @ Ti
    M_o = Mc[n - q:]
    Mc[: n - q] = 0.0                                      # exact zeros (they are round-off)
    T = Cc[:, r:].copy()
    A11, A211 = Ac[:r, :r], Ac[r:, :r][: p - q]
    if r == 0:
        zeros: tuple[complex, ...] = ()
    elif p == q:
        zeros = tuple(complex(z) for z in np.linalg.eigvals(A11))
    else:
        zeros = tuple(complex(z) for z in unobservable_modes(A11, A211))
    bad = [z for z in zeros if z.real >= -_TOL]
    if bad:
        raise RobofdiError(f"{where}: assumption A2 violated: (A, M, C) is not minimum phase, invariant zero "
                           f"{format_mode(bad[0])} has Re >= 0 (Edwards et al. §3: the unobservable modes of "
                           "(A11, A211) are the invariant zeros)")
    return CanonicalForm(Tt, Ac, None if Bm is None else Tt @ Bm, Mc, Cc, None if Qm is None else Tt @ Qm, T, M_o,
                         n, p, q, zeros)


def hinf_norm(A, B, C, D=None, tol: float = 1e-9) -> float:
    """‖C (sI − A)⁻¹ B + D‖∞ of a Hurwitz A: the Bruinsma–Steinbuch iteration (frequencies where the Hamiltonian
    H(γ) has imaginary eigenvalues raise the lower bound until none remain), relative accuracy ``tol``."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    n = A.shape[0]
    B = np.asarray(B, dtype=float).reshape(n, -1) if n else np.asarray(B, dtype=float)
    C = np.asarray(C, dtype=float).reshape(-1, n) if n else np.asarray(C, dtype=float)
    m, p = B.shape[1], C.shape[0]
    D = np.zeros((p, m)) if D is None else np.asarray(D, dtype=float).reshape(p, m)
    if n == 0 or m == 0 or p == 0:
        return float(np.linalg.norm(D, 2)) if D.size else 0.0
    ev = np.linalg.eigvals(A)
    if np.max(ev.real) >= 0:
        raise RobofdiError(f"hinf_norm: field 'A' must be Hurwitz, eigenvalue {format_mode(ev[np.argmax(ev.real)])}")

    def sigma(w: float) -> float:
        G = C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D
        return float(np.linalg.norm(G, 2))

    cands = [0.0] + [abs(e) for e in ev] + [abs(e.imag) for e in ev]
    lb = max([float(np.linalg.norm(D, 2))] + [sigma(w) for w in cands])
    if lb == 0.0:
        return 0.0
    for _ in range(60):
        g = (1 + 2 * tol) * lb
        R = g * g * np.eye(m) - D.T @ D
        Ri = np.linalg.inv(R)
        Ah = A + B @ Ri @ D.T @ C
        H = np.block([[Ah, B @ Ri @ B.T], [-C.T @ (np.eye(p) + D @ Ri @ D.T) @ C, -Ah.T]])
        lam = np.linalg.eigvals(H)
        w = np.sort(np.unique(np.round(np.abs(lam[np.abs(lam.real) < 1e-7 * max(1.0, np.abs(lam).max())].imag), 12)))
        if w.size == 0:
            return float(lb)
        pts = list(w) + [0.5 * (w[i] + w[i + 1]) for i in range(w.size - 1)]
        new = max(sigma(x) for x in pts)
        if new <= lb * (1 + tol):
            return float(lb)
        lb = new
    return float(lb)


@dataclass(frozen=True)
class ReconstructionDesign:
    """The observer (7)–(10) in the original coordinates: ż = A z + B u − ``G_l`` e_y + ``G_n`` ν, f̂ = ``W`` ν;
    ``L_o`` / ``W_1`` the free parameters of (15) and W; ``sliding_poles`` = eig(A11 + L_o A211) (the reduced error
    motion, (16)); ``gamma`` = ‖Ĝ‖∞ of (16) (the L2 gain of (11), 0 without Q); ``gamma_lmi`` the LMI bound (None
    for pole placement); ``form`` the canonical form it was built in; ``method`` "place" or "lmi"."""

    G_l: np.ndarray
    G_n: np.ndarray
    W: np.ndarray
    L_o: np.ndarray
    W_1: np.ndarray
    sliding_poles: np.ndarray
    error_poles: np.ndarray
    gamma: float
    gamma_lmi: float | None
    form: CanonicalForm
    method: str

    def Ghat(self):
        """The state-space (a, b, c, d) of Ĝ(s) = W_c A21 (sI − Ã11)⁻¹ (Q1 + L Q21) + W_c Q2, eq. (16)."""
        return _ghat(self.form, self.L_o, self.W_1)


def _ghat(f: CanonicalForm, L_o, W_1):
    r, q = f.n - f.p, f.q
    Wc = np.hstack([W_1, np.linalg.inv(f.M_o)])
    a = f.A11 + L_o @ f.A211
    if f.Q is None:
        h = 0
        return a, np.zeros((r, h)), Wc @ f.A21, np.zeros((q, h))
    return a, f.Q1 + L_o @ f.Q21, Wc @ f.A21, Wc @ f.Q2


def _lmi_design(f: CanonicalForm, margin: float, solver: str | None):
    """Minimise γ s.t. the bounded-real LMI on Ĝ(s) of (16) (variables P1 > 0, Y = P1 L_o, W_1, γ)."""
    where = "reconstruction_design"
    if not HAS_CVXPY:
        raise RobofdiError(f"{where}: method 'lmi' needs cvxpy (pip install 'robofdi[lmi]'; it brings the Clarabel/SCS solvers)"
                           "; use method='place' with scipy only")
    if f.Q is None:
        raise RobofdiError(f"{where}: method 'lmi' minimises the L2 gain from ξ (11): field 'Q' must be given")
    cp = _cp
    r, p, q, h = f.n - f.p, f.p, f.q, f.Q.shape[1]
    if r == 0:
        raise RobofdiError(f"{where}: method 'lmi' has nothing to design for n = p (no A11 block)")
    Moi = np.linalg.inv(f.M_o)
    P1 = cp.Variable((r, r), symmetric=True)
    Y = cp.Variable((r, p - q)) if p > q else None
    W1 = cp.Variable((q, p - q)) if p > q else None
    g = cp.Variable()
    A11, A21, A211, Q1, Q2, Q21 = f.A11, f.A21, f.A211, f.Q1, f.Q2, f.Q21
    PA = P1 @ A11 + (Y @ A211 if Y is not None else 0)
    PB = P1 @ Q1 + (Y @ Q21 if Y is not None else 0)
    Wc_A21 = Moi @ A21[p - q:] + (W1 @ A21[: p - q] if W1 is not None else 0)
    Wc_Q2 = Moi @ Q2[p - q:] + (W1 @ Q2[: p - q] if W1 is not None else 0)
    blk = cp.bmat([[PA + PA.T, PB, Wc_A21.T], [PB.T, -g * np.eye(h), Wc_Q2.T], [Wc_A21, Wc_Q2, -g * np.eye(q)]])
    size = r + h + q
    cons = [P1 >> margin * np.eye(r), 0.5 * (blk + blk.T) << -margin * np.eye(size)]
    prob = cp.Problem(cp.Minimize(g), cons)
    try:
        prob.solve(solver=solver or ("CLARABEL" if "CLARABEL" in cp.installed_solvers() else None))
    except cp.SolverError as exc:
        raise RobofdiError(f"{where}: the L2 design LMI could not be solved: {exc}") from None
    if prob.status not in ("optimal", "optimal_inaccurate") or g.value is None:
        raise RobofdiError(f"{where}: the L2 design LMI (bounded-real lemma on Ĝ(s), eq. 16) is infeasible: solver "
                           f"status {prob.status!r}")
    P = np.array(P1.value)
    L_o = np.linalg.solve(P, np.array(Y.value)) if Y is not None else np.zeros((r, 0))
    W_1 = np.array(W1.value) if W1 is not None else np.zeros((q, 0))
    return L_o, W_1, float(g.value)


def reconstruction_design(A, C, M, B=None, Q=None, poles: Sequence[complex] | None = None, A_s=None, W_1=None,
                          method: str = "place", margin: float = 1e-7, solver: str | None = None) -> ReconstructionDesign:
    """Edwards et al. §3, eqs. (12)–(16) (the recipe of Edwards, Spurgeon & Patton 2000):

    1. canonical form (:func:`canonical_form`, A1 and A2 checked);
    2. L_o with A11 + L_o A211 Hurwitz: ``poles`` placed on (A11ᵀ, A211ᵀ) (method "place"; p = q: A11 is already the
       zero dynamics), the Kalman-type gain L_o = −X A211ᵀ of the Riccati equation on (A11ᵀ, A211ᵀ) (method
       "riccati": needs only detectability, so it leaves the invariant zeros where they are), or the bounded-real
       LMI minimising ‖Ĝ‖∞ over (L_o, W_1) (method "lmi", cvxpy);
    3. G_l = Tt⁻¹ T_L⁻¹ [Ã12; Ã22 − A_s] Tᵀ with T_L = [[I, L], [0, I]], Ã = T_L A_c T_L⁻¹ (A_s Hurwitz, default −5 I):
       then A − G_l C has the eigenvalues eig(Ã11) ∪ eig(A_s);
    4. G_n = Tt⁻¹ [−L Tᵀ; Tᵀ] (erratum: the printed (14) has +L), W = [W_1 M_o⁻¹] Tᵀ (W_1 = 0 by default, eq. 10)."""
    where = "reconstruction_design"
    if method not in ("place", "lmi", "riccati"):
        raise RobofdiError(f"{where}: field 'method' must be 'place', 'lmi' or 'riccati', got {method!r}")
    f = canonical_form(A, M, C, Q=Q, B=B)
    n, p, q = f.n, f.p, f.q
    r = n - p
    gamma_lmi = None
    if method == "lmi":
        if poles is not None or W_1 is not None:
            raise RobofdiError(f"{where}: method 'lmi' designs L_o and W_1 itself: leave 'poles' and 'W_1' unset")
        L_o, W1, gamma_lmi = _lmi_design(f, margin, solver)
    elif method == "riccati":
        if poles is not None:
            raise RobofdiError(f"{where}: method 'riccati' designs L_o itself: leave 'poles' unset")
        L_o = np.zeros((r, p - q))
        if r and p > q:                                   # a Kalman-type gain: works for detectable (A11, A211)
            X = scipy.linalg.solve_continuous_are(f.A11.T, f.A211.T, np.eye(r), np.eye(p - q))
            L_o = -X @ f.A211.T
        W1 = np.zeros((q, p - q)) if W_1 is None else _mat(W_1, "W_1", where, rows=q, cols=p - q)
    else:
        if p == q or r == 0:
            L_o = np.zeros((r, p - q))
            if poles is not None and len(poles):
                raise RobofdiError(f"{where}: field 'poles' must be empty for p = q (A11 + L A211 = A11: its "
                                   f"eigenvalues are the invariant zeros {list(np.round(f.zeros, 6))})")
        else:
            if poles is None:
                raise RobofdiError(f"{where}: field 'poles' must give {r} eigenvalues of A11 + L_o A211 (Re < 0)")
            s = np.array(poles, dtype=complex).ravel()
            if s.shape != (r,) or np.any(s.real >= 0):
                raise RobofdiError(f"{where}: field 'poles' must be {r} eigenvalues with Re < 0 of A11 + L_o A211 "
                                   f"(eq. 16), got {poles!r}")
            try:
                L_o = -np.real(scipy.signal.place_poles(f.A11.T, f.A211.T, s).gain_matrix.T)
            except ValueError as exc:
                raise RobofdiError(f"{where}: field 'poles' cannot be placed on (A11, A211) (its unobservable modes "
                                   f"are the invariant zeros {list(np.round(f.zeros, 6))}): {exc}") from None
        W1 = np.zeros((q, p - q)) if W_1 is None else _mat(W_1, "W_1", where, rows=q, cols=p - q)
    As = -5.0 * np.eye(p) if A_s is None else _mat(A_s, "A_s", where, rows=p, cols=p)
    if np.max(np.linalg.eigvals(As).real) >= 0:
        raise RobofdiError(f"{where}: field 'A_s' must be Hurwitz (the e_y dynamics during the reaching phase)")
    L = np.hstack([L_o, np.zeros((r, q))])
    TL = np.eye(n)
    TL[:r, r:] = L
    TLi = np.linalg.inv(TL)
    At = TL @ f.A @ TLi
    T = f.T
    Glc = TLi @ np.vstack([At[:r, r:], At[r:, r:] - As]) @ T.T
    Gnc = np.vstack([-L @ T.T, T.T])
    Ti = np.linalg.inv(f.Tt)
    G_l, G_n = Ti @ Glc, Ti @ Gnc
    W = np.hstack([W1, np.linalg.inv(f.M_o)]) @ T.T
    sl = np.linalg.eigvals(f.A11 + L_o @ f.A211) if r else np.zeros(0)
    if r and np.max(sl.real) >= 0:
        raise RobofdiError(f"{where}: the sliding motion A11 + L_o A211 is not stable (eigenvalue "
                           f"{format_mode(sl[np.argmax(sl.real)])})")
    a, b, c, d = _ghat(f, L_o, W1)
    gamma = hinf_norm(a, b, c, d) if b.shape[1] else 0.0
    Ao = np.asarray(A, dtype=float) - G_l @ np.asarray(C, dtype=float)
    return ReconstructionDesign(G_l, G_n, W, L_o, W1, sl, np.linalg.eigvals(Ao), gamma, gamma_lmi, f, method)


# ----------------------------------------------------------------------------------------------------- stepping
class SMOReconstructor:
    """Diagnoser protocol: the actuator-fault reconstruction SMO (7)–(10) of Edwards et al. §3.

    ż = (A − G_l C) z + G_l y + B u + G_n ν, ν = −ρ e_y/‖e_y‖, e_y = C z − y, integrated by the chapter-1 kernel
    (:class:`~robofdi.observers.sliding_mode.CascadeSMO`, one output stage per measurement, ``switching="unit"``,
    sub-stepped at ``settings.substep``). Residual: ν_eq (p entries ``nu_<measurement>``), the interval mean of ν
    over the diagnosis sample (the equivalent output error injection); estimate: f̂ = W ν_eq (10), one entry per
    fault channel — or, with ``readout`` (q×n), readout·z (the §5 sensor-fault estimate f̂_o = C_f z_a). ``rho``
    [fault units × ‖M_o‖] must exceed the bound (9) on the fault."""

    def __init__(self, A, B, C, G_l, G_n, W, rho: float, settings: SMOSettings, inputs: Sequence[str],
                 measurements: Sequence[str], faults: Sequence[str], measurement_units: Sequence[str] | None = None,
                 fault_units: Sequence[str] | None = None, x0=None, readout=None):
        where = "SMOReconstructor"
        A = _square(A, where)
        n = A.shape[0]
        C = _mat(C, "C", where, cols=n)
        B = _mat(B, "B", where, rows=n) if np.size(B) else np.zeros((n, 0))
        p = C.shape[0]
        G_l = _mat(G_l, "G_l", where, rows=n, cols=p)
        G_n = _mat(G_n, "G_n", where, rows=n, cols=p)
        W = _mat(W, "W", where, cols=p)
        self.readout = None if readout is None else _mat(readout, "readout", where, cols=n)
        q = W.shape[0] if self.readout is None else self.readout.shape[0]
        if not (is_number(rho) and rho > 0):
            raise RobofdiError(f"{where}: field 'rho' must be a gain > 0 (eq. 9: ρ ≥ k_1 + α + η), got {rho!r}")
        if settings.switching != "unit":
            raise RobofdiError(f"{where}: settings field 'switching' must be 'unit' (ν = −ρ e_y/‖e_y‖, eq. 8), got "
                               f"{settings.switching!r}")
        for field, names, size in (("inputs", inputs, B.shape[1]), ("measurements", measurements, p),
                                   ("faults", faults, q)):
            if len(list(names)) != size:
                raise RobofdiError(f"{where}: field {field!r} must hold {size} names, got {len(list(names))}")
        self.rho, self.W, self.G_l, self.G_n, self.C = float(rho), W, G_l, G_n, C
        Mx = A - G_l @ C
        Gl = G_l.copy()

        def affine(y, u):
            return Mx, Gl @ y + B @ u

        stages = [Stage(self.rho, self.rho * G_n[:, j], Wy=np.eye(p)[j], Cx=C[j], name=f"nu_{m}")
                  for j, m in enumerate(measurements)]
        mu = list(measurement_units or ["1"] * p)
        self._smo = CascadeSMO(n, affine, stages, settings, inputs, measurements, x0=x0, residual_units=mu,
                               where=where)
        self.inputs, self.measurements = list(inputs), list(measurements)
        self.components = list(self._smo.components)
        self.estimate_components = list(faults)
        self.estimate_modes = ["level"] * q
        self.units = {"residual": mu, "estimate": list(fault_units or ["1"] * q)}

    @classmethod
    def from_design(cls, A, B, C, design: ReconstructionDesign, rho: float, settings: SMOSettings, **names):
        """The observer of a :func:`reconstruction_design` (its G_l, G_n and W)."""
        return cls(A, B, C, design.G_l, design.G_n, design.W, rho, settings, **names)

    def reset(self) -> None:
        self._smo.reset()

    def signatures(self) -> list:
        return []

    @property
    def state_estimate(self) -> np.ndarray:
        return self._smo.state_estimate

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        # e_y = C z − y: the kernel's ē = y − C z, and ψ = ē/‖ē‖, so ρψ = ν of (8) and the injection is G_n ν
        res = self._smo.update(y, u)
        nu = res.r
        est = self.W @ nu if self.readout is None else self.readout @ self._smo.state_estimate
        return Residual(nu.copy(), est)


# ----------------------------------------------------------------------------------------------------- §5
@dataclass(frozen=True)
class SensorFaultSystem:
    """§5 (44)–(47): x_a = [x; f_o], ẋ_a = ``A_a`` x_a + ``B_a`` u + ``F_a`` φ, y = ``C_a`` x_a, f_o = ``C_f`` x_a;
    ``observable``: (A_a, C_a) observable (Proposition 2)."""

    A_a: np.ndarray
    B_a: np.ndarray
    C_a: np.ndarray
    F_a: np.ndarray
    C_f: np.ndarray
    observable: bool


def sensor_fault_system(A, B, C, F) -> SensorFaultSystem:
    """Edwards et al. §5, eqs. (44)–(47): y = C x + F f_o with F (p×q, full column rank, q < p) the faulty sensors'
    directions. The invariant zeros of (A_a, F_a, C_a) are the unobservable modes of (A, C1), C1 the healthy
    outputs (seed digest §4, checked): the §3 design on it (A2) needs (A, C1) detectable."""
    where = "sensor_fault_system"
    A = _square(A, where)
    n = A.shape[0]
    C = _mat(C, "C", where, cols=n)
    p = C.shape[0]
    B = _mat(B, "B", where, rows=n) if np.size(B) else np.zeros((n, 0))
    F = _mat(F, "F", where, rows=p)
    q = F.shape[1]
    if _rank(F) < q or q >= p:
        raise RobofdiError(f"{where}: field 'F' must have full column rank q < p = {p} (eq. 39: n >= p > q), got rank "
                           f"{_rank(F)} for {q} columns")
    Aa = scipy.linalg.block_diag(A, np.zeros((q, q)))
    Ba = np.vstack([B, np.zeros((q, B.shape[1]))])
    Ca = np.hstack([C, F])
    Fa = np.vstack([np.zeros((n, q)), np.eye(q)])
    Cf = np.hstack([np.zeros((q, n)), np.eye(q)])
    return SensorFaultSystem(Aa, Ba, Ca, Fa, Cf, not unobservable_modes(Aa, Ca))


def sensor_fault_observer(A, B, C, F, rho: float, settings: SMOSettings, poles=None, A_s=None,
                          inputs: Sequence[str] = (), measurements: Sequence[str] = (), faults: Sequence[str] = (),
                          measurement_units: Sequence[str] | None = None, x0=None):
    """§5 (48)–(54): the §3 reconstruction SMO on the augmented system of :func:`sensor_fault_system`, with the
    estimate f̂_o = C_f z_a. In the canonical coordinates of (48) the fault rate φ does not enter the sliding-motion
    error ẽ1 (M_c = [0; 0; M_o]), so f̂_o → f_o at the rate of eig(A11 + L_o A211) for any |φ| < ρ (Propositions
    3–4). Returns (observer, design, augmented system); a non-minimum-phase (A_a, F_a, C_a) (an undetectable
    (A, C1)) is refused naming A2 — the H∞ design of Remark 5 is not implemented."""
    s = sensor_fault_system(A, B, C, F)
    d = reconstruction_design(s.A_a, s.C_a, s.F_a, B=s.B_a, poles=poles, A_s=A_s)
    fault_units = None
    if measurement_units is not None:                 # f_o is in the unit of the sensor it corrupts most
        fault_units = [list(measurement_units)[int(np.argmax(np.abs(s.C_a[:, s.C_a.shape[1] - s.C_f.shape[0] + j])))]
                       for j in range(s.C_f.shape[0])]
    obs = SMOReconstructor.from_design(s.A_a, s.B_a, s.C_a, d, rho, settings, inputs=list(inputs),
                                       measurements=list(measurements), faults=list(faults),
                                       measurement_units=measurement_units, fault_units=fault_units, x0=x0,
                                       readout=s.C_f)
    return obs, d, s


# ----------------------------------------------------------------------------------------------------- §4
@dataclass(frozen=True)
class CascadeStage:
    """Stage i of the §4 cascade (17)–(38): its system's sizes (n, p, q, h), r̄ = rank(C M), the augmented
    (Ā, M̄, Q̄, C̄) with the disturbance filter (23)–(25), L̄_o, the sliding matrix Ā_1 + L̄_o Ā_31 of (31) and its
    eigenvalues; ``last``: rank(C M) = rank(M), the §3 design applies (the stopping rule)."""

    n: int
    p: int
    q: int
    h: int
    rbar: int
    m_next: int
    A: np.ndarray
    M: np.ndarray
    Q: np.ndarray
    C: np.ndarray
    L_o: np.ndarray | None
    sliding: np.ndarray | None
    sliding_poles: np.ndarray | None
    last: bool
    #: the state map of this stage: its final coordinates = ``T`` × [x^i; ξ^i] (x^i in the coordinates the stage
    #: was given; for the last stage x^i alone)
    T: np.ndarray | None = None


def _output_coordinates(A, M, Q, C, with_T: bool = False):
    """x ↦ [N_cᵀ; C] x: C = [0 I_p] (the form (17) assumes)."""
    Nc = scipy.linalg.null_space(C)
    T0 = np.vstack([Nc.T, C])
    Ti = np.linalg.inv(T0)
    out = (T0 @ A @ Ti, T0 @ M, T0 @ Q, C @ Ti)
    return (*out, T0) if with_T else out


def _proposition1(A, M, Q, p: int, rbar: int):
    """Proposition 1 (19)–(22) for C = [0 I_p]: a fault scaling (column compression of CM) and an output rotation
    with M = [[M11, 0], [0, 0], [0, M̄22]] (rows n − p, p − r̄, r̄; columns q − r̄, r̄); C stays [0 C2], C2 orthogonal."""
    n, q = M.shape
    r = n - p
    Mb = M[r:]
    if rbar:
        _, _, Vt = np.linalg.svd(Mb)
        T2i = np.hstack([Vt[rbar:].T, Vt[:rbar].T])               # columns: null(Mb) first, then the range part
    else:
        T2i = np.eye(q)
    Ms = M @ T2i                                                   # fault scaling f' = T2 f
    Mb2 = Ms[r:, q - rbar:]
    Tr = np.eye(p)
    if rbar:
        Qf, _ = np.linalg.qr(Mb2, mode="complete")
        Tr = np.vstack([Qf[:, rbar:].T, Qf[:, :rbar].T])
    Tb = np.eye(n)
    if rbar:
        Tb[:r, r:] = -Ms[:r, q - rbar:] @ np.linalg.pinv(Ms[r:, q - rbar:])
    T = scipy.linalg.block_diag(np.eye(r), Tr) @ Tb
    Ti = np.linalg.inv(T)
    return T @ A @ Ti, T @ Ms, T @ Q, np.hstack([np.zeros((p, r)), Tr.T]), T, T2i


def cascade_design(A, M, C, Q, filters: Sequence[tuple], alpha: float = 10.0, max_stages: int = 6,
                   tol: float = 1e-7) -> list[CascadeStage]:
    """Edwards et al. §4 (Tan & Edwards 2010), the design recursion (17)–(38) and its stopping rule, for
    rank(CM) < q: stage i augments its system with the disturbance filter (A_Ω^i, B_Ω^i) of ``filters[i−1]``
    (23)–(25), brings it to the form of Proposition 1, chooses L̄_o (a Kalman-type gain: Ā_1 + L̄_o Ā_31 Hurwitz,
    the sliding motion (31)), and builds the next fictitious system (35)–(38): x^{i+1} = [w; z_f],
    y^{i+1} = [z_1; z_f], A^{i+1} = [[Ā_1 + L̄_o Ā_31, 0], [α Ā_32, −α I]], M^{i+1} = [M̄_1; [0 α M̄22]],
    Q^{i+1} = [Q̄_1; 0] (errata 4–5: z_1 algebraic, index i throughout). It stops at the first stage with
    rank(C^i M^i) = rank(M^i), where the §3 design applies (reported, not run). Design only: no observer is stepped.
    ``m_next`` = p − r̄ is the size of z_1 (the outputs of the next system that the fault does not reach).

    Refused (naming the condition): M without full column rank, a stage whose (Ā_1, Ā_31) is not detectable (the
    sliding motion (31) cannot be made stable), too few ``filters``, or no stopping stage within ``max_stages``."""
    where = "cascade_design"
    A = _square(A, where)
    n = A.shape[0]
    C = _mat(C, "C", where, cols=n)
    M = _mat(M, "M", where, rows=n)
    Q = _mat(Q, "Q", where, rows=n)
    if _rank(M) < M.shape[1]:
        raise RobofdiError(f"{where}: field 'M' must have full column rank, got rank {_rank(M)} for {M.shape[1]}")
    stages: list[CascadeStage] = []
    for i in range(max_stages):
        p, q = C.shape[0], _rank(M)
        A, M, Q, C, T0 = _output_coordinates(A, M, Q, C, with_T=True)
        rbar = _rank(np.where(np.abs(C @ M) > tol * max(1.0, np.abs(M).max()), C @ M, 0.0))
        n = A.shape[0]
        if rbar == q:
            stages.append(CascadeStage(n, p, q, Q.shape[1], rbar, p - rbar, A, M, Q, C, None, None, None, True, T0))
            return stages
        if i >= len(filters):
            raise RobofdiError(f"{where}: field 'filters' must give a disturbance filter (A_Ω, B_Ω) for stage {i + 1} "
                               f"(rank(C M) = {rbar} < q = {q} there)")
        AO, BO = (np.atleast_2d(np.asarray(f, dtype=float)) for f in filters[i])
        h = Q.shape[1]
        if AO.shape != (h, h) or BO.shape[0] != h or np.max(np.linalg.eigvals(AO).real) >= 0:
            raise RobofdiError(f"{where}: filters[{i}] must be (A_Ω Hurwitz {h}×{h}, B_Ω with {h} rows) (eq. 24), got "
                               f"shapes {AO.shape}, {BO.shape}")
        Ab = np.block([[A, Q], [np.zeros((h, n)), AO]])
        Mb = np.vstack([M, np.zeros((h, M.shape[1]))])
        Qb = np.vstack([np.zeros((n, BO.shape[1])), BO])
        Cb = np.hstack([C, np.zeros((p, h))])
        # put the filter states among the unmeasured ones: C̄ = [0 I_p]
        nb = n + h
        perm = list(range(n - p)) + list(range(n, nb)) + list(range(n - p, n))
        P = np.eye(nb)[perm]
        Ab, Mb, Qb, Cb = P @ Ab @ P.T, P @ Mb, P @ Qb, Cb @ P.T
        Ab, Mb, Qb, Cb, T1, _ = _proposition1(Ab, Mb, Qb, p, rbar)
        r = nb - p
        m_next = p - rbar
        A1, A3 = Ab[:r, :r], Ab[r:, :r]
        A31, A32 = A3[:m_next], A3[m_next:]
        X = scipy.linalg.solve_continuous_are(A1.T, A31.T, np.eye(r), np.eye(m_next)) if m_next else np.zeros((r, r))
        L_o = -X @ A31.T
        S = A1 + L_o @ A31
        poles = np.linalg.eigvals(S)
        if np.max(poles.real) >= 0:
            raise RobofdiError(f"{where}: stage {i + 1}: (Ā_1, Ā_31) is not detectable, the sliding motion (31) cannot "
                               f"be made stable (eigenvalue {format_mode(poles[np.argmax(poles.real)])})")
        stages.append(CascadeStage(nb, p, q, h, rbar, m_next, Ab, Mb, Qb, Cb, L_o, S, poles, False,
                                   T1 @ P @ scipy.linalg.block_diag(T0, np.eye(h))))
        M1 = Mb[:r]
        M22 = Mb[r + m_next:, q - rbar:]
        A = np.block([[S, np.zeros((r, rbar))], [alpha * A32, -alpha * np.eye(rbar)]])
        M = np.vstack([M1, np.hstack([np.zeros((rbar, q - rbar)), alpha * M22])])
        Q = np.vstack([Qb[:r], np.zeros((rbar, Qb.shape[1]))])
        C = scipy.linalg.block_diag(A31, np.eye(rbar))
    raise RobofdiError(f"{where}: no stage with rank(C M) = rank(M) within {max_stages} stages (the fault never reaches "
                       "the outputs with relative degree one)")
