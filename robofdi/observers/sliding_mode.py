"""Sliding-mode observers for state estimation and fault diagnosis — M. Saif & Y. Xiong, "Sliding mode observers
and their application in fault diagnosis", ch. 1 of Caccavale & Villani (eds.), *Fault Diagnosis and Fault
Tolerance for Mechatronic Systems*, Springer STAR 1, 2003. Equation numbers are the chapter's.

Design functions (pure):

* :func:`utkin_design` — Utkin's equivalent-control SMO, eqs. (3)–(10): T, the (A11, A21) pair and L2;
* :func:`walcott_zak_existence` — Theorem 2 / Lemma 4: a W–Z observer exists iff rank(CG) = rank(G) and (A, G, C)
  is minimum phase; a :class:`Verdict` with the reasons, never only an exception;
* :func:`walcott_zak_design` — the Lyapunov design of Sec. 2.4 in the coordinates of Lemma 5 (36): K, P, Q, W
  with W C = Gᵀ P (15), W by Lemma 2 (27);
* :func:`relative_degree_chain` — CAᵏG, the relative degree and, when it equals n (SISO), the chain coordinates
  Γ1⁻¹ = [C; CA; …; CA^{n−1}] of the SCB (19)–(25) (the structure all five examples have: we build the chains
  from the relative degree instead of a general SCB decomposition, which the chapter does not give);
* :func:`boundary_layer_routh` — the guard of the digest's E2.5: a saturation (boundary-layer) cascade without
  filtering is the linear high-gain observer s^q + k1 s^{q−1} + k1k2 s^{q−2} + … (k_j = λ_j/ε); Routh–Hurwitz
  on it (λ1λ2 > λ2λ3 + λ1λ4 for four stages; ε cancels).

Stepping (one ``update``, Diagnoser protocol): :class:`CascadeSMO`, the general sub-stepped observer every
observer of the chapter is an instance of (:mod:`robofdi.observers.smo_kernel` integrates it); the factories
:func:`utkin_smo`, :func:`walcott_zak_smo`, :func:`chain_smo` (eq. 38/70 on a relative-degree chain) and
:func:`output_observer` (the SMOO (54)/(60)) build it.

Numerics (documented choices, the chapter gives none): the equivalent control (v)_eq is a first-order low-pass
filter τ z' + z = v of the switching term (the chapter: "low pass filtering the signal v"); ψ is the sign (the
default), or the boundary layer sat(ē/ε) ("saturation with upper limit 0.02" read as ε = 0.02); the anti-peaking
activation is a schedule of switch-on times (Example 2: 0.2, 0.8, 1.8 s) or a sliding detector
(:class:`SlidingDetector`: a cascade stage switches on once the stage it reads has slid for a dwell time). Between
two diagnosis samples the measurement is a cubic Hermite interpolant (slopes by central and backward differences:
no look-ahead), the input is held; the observer is integrated with explicit Euler at ``substep`` (must be below
every τ: the switching must be faster than its filter). Saif & Xiong eq. (13)'s "+L2 G2" is derived as "−L2 G2"
here (the decoupling condition G1 − L2 G2 = 0), eq. (16)'s K(y − x) is K(y − C x̂).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.signal

from robofdi.checks import check_fields, is_number
from robofdi.errors import RobofdiError
from robofdi.models.linear import format_mode, unobservable_modes
from robofdi.observers.residual import Residual, check_measurement
from robofdi.observers.smo_kernel import SAT, SIGN, UNIT, integrate_interval

__all__ = ["Verdict", "UtkinDesign", "WalcottZakDesign", "ChainStructure", "RouthVerdict", "SMOSettings",
           "SlidingDetector", "Stage", "CascadeSMO", "utkin_design", "walcott_zak_existence", "walcott_zak_design",
           "relative_degree_chain",
           "boundary_layer_routh", "utkin_smo", "walcott_zak_smo", "chain_smo", "output_observer", "SWITCHING"]

SWITCHING = {"sign": SIGN, "sat": SAT, "unit": UNIT}


def _mat(a, name: str, where: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        m = np.array(a, dtype=float)
    except (TypeError, ValueError):
        raise RobofdiError(f"{where}: field {name!r} must be a numeric matrix, got {a!r}") from None
    if m.ndim == 1:
        m = m[:, None] if rows is not None and m.shape[0] == rows and cols != m.shape[0] else m[None, :]
    if m.ndim != 2 or (rows is not None and m.shape[0] != rows) or (cols is not None and m.shape[1] != cols):
        want = f"{rows or 'any'}x{cols or 'any'}"
        raise RobofdiError(f"{where}: field {name!r} must be a {want} matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise RobofdiError(f"{where}: field {name!r} must be finite")
    return m


def _abc(A, C, where: str, G=None):
    A = _mat(A, "A", where)
    n = A.shape[0]
    if A.shape != (n, n):
        raise RobofdiError(f"{where}: field 'A' must be square, got shape {A.shape}")
    C = _mat(C, "C", where, cols=n)
    out = [A, C]
    if G is not None:
        G = _mat(G, "G", where, rows=n)
        if np.linalg.matrix_rank(G) < G.shape[1]:
            raise RobofdiError(f"{where}: field 'G' must have full column rank (eq. 2), got rank "
                               f"{np.linalg.matrix_rank(G)} for {G.shape[1]} columns")
        out.append(G)
    return out


def _require_observable(A, C, where: str) -> None:
    bad = unobservable_modes(A, C)
    if bad:
        raise RobofdiError(f"{where}: (A, C) must be observable (Saif & Xiong Sec. 2.1), mode λ={format_mode(bad[0])} "
                           "is unobservable")


# ----------------------------------------------------------------------------------------------------- Utkin
@dataclass(frozen=True)
class UtkinDesign:
    """Eqs. (3)–(10): x̄ = T x = [x1; y], T A T⁻¹ = [A11 A12; A21 A22], T B = [B1; B2], L2 with A11 − L2 A21
    Hurwitz; ``decoupling`` = ‖G1 − L2 G2‖ when G is given (0: e1 is insensitive to d, eq. (13) corrected)."""

    T: np.ndarray
    A11: np.ndarray
    A12: np.ndarray
    A21: np.ndarray
    A22: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    L2: np.ndarray
    poles: np.ndarray
    decoupling: float | None = None


def utkin_design(A, B, C, poles: Sequence[complex], G=None) -> UtkinDesign:
    """T of eq. (3) (C = [C1 C2], det C2 ≠ 0; otherwise T = [N; C] with N an orthonormal basis of ker(C)ᵀ, which
    gives the same C T⁻¹ = [0 I]), and L2 placing eig(A11 − L2 A21) at ``poles`` (eq. 10)."""
    where = "utkin_design"
    A, C = _abc(A, C, where)
    n, p = A.shape[0], C.shape[0]
    B = _mat(B, "B", where, rows=n)
    if np.linalg.matrix_rank(C) < p:
        raise RobofdiError(f"{where}: field 'C' must have full row rank, got rank {np.linalg.matrix_rank(C)} for {p} rows")
    _require_observable(A, C, where)
    C2 = C[:, n - p:]
    if abs(np.linalg.det(C2)) > 1e-9 * max(1.0, np.linalg.norm(C2)) ** p:
        T = np.block([[np.eye(n - p), np.zeros((n - p, p))], [C[:, :n - p], C2]])
    else:
        T = np.vstack([scipy.linalg.null_space(C).T, C])
    Ti = np.linalg.inv(T)
    Ab, Bb = T @ A @ Ti, T @ B
    r = n - p
    A11, A12, A21, A22 = Ab[:r, :r], Ab[:r, r:], Ab[r:, :r], Ab[r:, r:]
    s = np.array(poles, dtype=complex).ravel()
    if s.shape != (r,) or np.any(s.real >= 0):
        raise RobofdiError(f"{where}: field 'poles' must be {r} poles with Re < 0 (eig(A11 − L2 A21), eq. 10), got {poles!r}")
    if r == 0:
        L2 = np.zeros((0, p))
    else:
        try:
            L2 = np.real(scipy.signal.place_poles(A11.T, A21.T, s).gain_matrix.T)
        except ValueError as exc:
            raise RobofdiError(f"{where}: field 'poles' cannot be placed for (A11, A21): {exc}") from None
    dec = None
    if G is not None:
        G = _mat(G, "G", where, rows=n)
        Gb = T @ G
        dec = float(np.linalg.norm(Gb[:r] - L2 @ Gb[r:]))
    return UtkinDesign(T, A11, A12, A21, A22, Bb[:r], Bb[r:], L2, np.linalg.eigvals(A11 - L2 @ A21), dec)


# ----------------------------------------------------------------------------------------------------- W–Z
@dataclass(frozen=True)
class Verdict:
    """Whether an observer exists, and why (or why not): ``reasons`` names every condition that failed."""

    exists: bool
    reasons: tuple[str, ...]
    rank_CG: int
    rank_G: int
    observable: bool
    invariant_zeros: tuple[complex, ...] | None = None

    def __bool__(self) -> bool:
        return self.exists

    def require(self, where: str) -> None:
        if not self.exists:
            raise RobofdiError(f"{where}: no Walcott–Zak observer exists (Saif & Xiong Theorem 2): " + "; ".join(self.reasons))


def walcott_zak_existence(A, G, C) -> Verdict:
    """Theorem 2 (Lemma 4, Corless & Tu): {A, C} observable, and a W–Z SMO (16) exists iff rank(CG) = rank(G) and
    (A, G, C) is minimum phase. With rank(CG) = rank(G) the invariant zeros are the unobservable modes of
    ((I − G(CG)⁺C) A, C) (the UIO condition, Remark 1); minimum phase: all in Re < 0."""
    A, C, G = _abc(A, C, "walcott_zak_existence", G)
    reasons = []
    observable = not unobservable_modes(A, C)
    if not observable:
        reasons.append("(A, C) is not observable")
    rCG, rG = int(np.linalg.matrix_rank(C @ G)), int(np.linalg.matrix_rank(G))
    zeros = None
    if rCG != rG:
        reasons.append(f"rank(CG) = {rCG} differs from rank(G) = {rG} (the unknown input is not matched to the "
                       "outputs: relative degree > 1)")
    else:
        A1 = (np.eye(A.shape[0]) - G @ np.linalg.pinv(C @ G) @ C) @ A
        zeros = tuple(complex(z) for z in unobservable_modes(A1, C))
        bad = [z for z in zeros if z.real >= -1e-9]
        if bad:
            reasons.append(f"(A, G, C) is not minimum phase: invariant zero {format_mode(bad[0])} has Re >= 0")
    return Verdict(not reasons, tuple(reasons), rCG, rG, observable, zeros)


@dataclass(frozen=True)
class WalcottZakDesign:
    """K (A − KC Hurwitz), P > 0 and Q = −(P A0 + A0ᵀ P) > 0 of (14), W with W C = Gᵀ P (15); ``alpha`` and
    ``rho_d`` of the Sec. 2.4 algorithm (α > ρ_d); ``Gamma`` the Lemma 5 state coordinates x = Γ [x_ab; x_d]."""

    K: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    W: np.ndarray
    alpha: float
    rho_d: float
    Gamma: np.ndarray


def lemma2_W(P, G, C, Z=None) -> np.ndarray:
    """Eq. (27): W = Gᵀ P C⁺ + Z − Z C C⁺ (Moore–Penrose C⁺); Lemma 2: it solves W C = Gᵀ P iff Gᵀ P (I − C⁺C) = 0."""
    Cp = np.linalg.pinv(C)
    W = G.T @ P @ Cp
    if Z is not None:
        W = W + Z - Z @ C @ Cp
    return W


def walcott_zak_design(A, G, C, d_pole: float = -1.0, alpha_margin: float = 2.0) -> WalcottZakDesign:
    """The Lyapunov W–Z design (Sec. 2.4 algorithm) in the coordinates of Lemma 5 (36), built numerically:
    ȳ_d = (CG)⁺y, ȳ_b = S2 y (S2: left null space of CG), x = N x_ab + G x_d (N: ker((CG)⁺C)). Then
    K̄ = [L_d K_ab; K_d 0] (eq. 32) makes A0 block-triangular (33) with Â_d = d_pole·I and K_ab a Kalman-type
    gain for the detectable (A_ab, C_ab); P_d Â_d + Â_dᵀP_d = −I, α = margin·ρ((P_d E_ab)ᵀP_d E_ab) (+1e-6),
    P_ab A_ab + A_abᵀ P_ab = −αI, P = Γ⁻ᵀ diag(P_ab, P_d) Γ⁻¹ (35), K = Γ K̄ Γ2⁻¹, W = P_d (CG)⁺ (= eq. 27)."""
    where = "walcott_zak_design"
    A, C, G = _abc(A, C, where, G)
    walcott_zak_existence(A, G, C).require(where)
    if not (is_number(d_pole) and d_pole < 0):
        raise RobofdiError(f"{where}: field 'd_pole' must be a number < 0, got {d_pole!r}")
    if not (is_number(alpha_margin) and alpha_margin > 1):
        raise RobofdiError(f"{where}: field 'alpha_margin' must be a number > 1 (α > ρ_d), got {alpha_margin!r}")
    n, q, p = A.shape[0], G.shape[1], C.shape[0]
    CG = C @ G
    S1 = np.linalg.pinv(CG)                                    # q×p, S1 C G = I
    S2 = scipy.linalg.null_space(CG.T).T                       # (p−q)×p, S2 C G = 0
    Gi2 = np.vstack([S1, S2])                                  # Γ2⁻¹
    N = scipy.linalg.null_space(S1 @ C)                        # n×(n−q)
    Gam = np.hstack([N, G])
    Gi = np.linalg.inv(Gam)
    Ab = Gi @ A @ Gam
    r = n - q
    A_ab, L_d, E_ab, A_d = Ab[:r, :r], Ab[:r, r:], Ab[r:, :r], Ab[r:, r:]
    C_ab = S2 @ C @ N                                          # (p−q)×r
    if C_ab.shape[0] and r:
        Xr = scipy.linalg.solve_continuous_are(A_ab.T, C_ab.T, np.eye(r), np.eye(C_ab.shape[0]))
        K_ab = Xr @ C_ab.T
    else:
        K_ab = np.zeros((r, C_ab.shape[0]))
    Ahat_ab = A_ab - K_ab @ C_ab
    if r and np.max(np.linalg.eigvals(Ahat_ab).real) >= 0:
        raise RobofdiError(f"{where}: (A_ab, C_ab) is not detectable (the system is not minimum phase)")
    K_d = A_d - d_pole * np.eye(q)
    Ahat_d = A_d - K_d
    P_d = scipy.linalg.solve_continuous_lyapunov(Ahat_d.T, -np.eye(q))
    M = P_d @ E_ab
    rho_d = float(np.max(np.linalg.eigvalsh(M.T @ M))) if r else 0.0
    alpha = alpha_margin * rho_d + 1e-6
    P_ab = scipy.linalg.solve_continuous_lyapunov(Ahat_ab.T, -alpha * np.eye(r)) if r else np.zeros((0, 0))
    Pb = scipy.linalg.block_diag(P_ab, P_d)
    Kb = np.block([[L_d, K_ab], [K_d, np.zeros((q, p - q))]])
    P = Gi.T @ Pb @ Gi
    P = 0.5 * (P + P.T)
    K = Gam @ Kb @ Gi2
    A0 = A - K @ C
    Q = -(P @ A0 + A0.T @ P)
    W = P_d @ S1
    return WalcottZakDesign(K, P, 0.5 * (Q + Q.T), W, float(alpha), rho_d, Gam)


# ----------------------------------------------------------------------------------------------------- chains
@dataclass(frozen=True)
class ChainStructure:
    """Markov parameters CAᵏG (k = 0..n−1), the relative degree r of (A, G, C) (SISO: the first k with CAᵏG ≠ 0,
    plus one), and for r = n the chain coordinates x̄ = Γ1⁻¹ x, Γ1⁻¹ = [C; CA; …; CA^{n−1}] (Example 2's Γ1,
    exactly) with Ā = Γ1⁻¹AΓ1 (companion), B̄ = Γ1⁻¹B, Ḡ = Γ1⁻¹G, Γ3 = 1/CA^{r−1}G (then Ḡ Γ3 = e_n)."""

    markov: np.ndarray
    relative_degree: int
    Gamma1: np.ndarray | None
    Abar: np.ndarray | None
    Bbar: np.ndarray | None
    Gbar: np.ndarray | None
    Gamma3: float | None


def relative_degree_chain(A, G, C, B=None, tol: float = 1e-9) -> ChainStructure:
    """The relative-degree chain structure of a single-output, single-unknown-input (A, G, C) — SCB (20)–(23)."""
    where = "relative_degree_chain"
    A, C, G = _abc(A, C, where, G)
    n = A.shape[0]
    if C.shape[0] != 1 or G.shape[1] != 1:
        raise RobofdiError(f"{where}: expected one output and one unknown input, got C {C.shape}, G {G.shape} "
                           "(several chains: build each chain's stages with CascadeSMO)")
    mk, row = [], C.copy()
    for _ in range(n):
        mk.append(float((row @ G)[0, 0]))
        row = row @ A
    scale = max(1.0, float(np.abs(mk).max()))
    nz = [k for k, v in enumerate(mk) if abs(v) > tol * scale]
    if not nz:
        raise RobofdiError(f"{where}: CAᵏG = 0 for every k < n: the unknown input never reaches the output")
    r = nz[0] + 1
    if r < n:
        return ChainStructure(np.array(mk), r, None, None, None, None, 1.0 / mk[r - 1])
    O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(n)])
    _require_observable(A, C, where)
    Gam1 = np.linalg.inv(O)
    Bb = None if B is None else O @ _mat(B, "B", where, rows=n)
    return ChainStructure(np.array(mk), r, Gam1, O @ A @ Gam1, Bb, O @ G, 1.0 / mk[r - 1])


@dataclass(frozen=True)
class RouthVerdict:
    """Routh–Hurwitz of the boundary-layer cascade's polynomial: ``stable``, the coefficients (with ε = 1) and, for
    three and four stages, the inequality the gains must satisfy with both sides' numbers."""

    stable: bool
    coefficients: tuple[float, ...]
    condition: str
    lhs: float
    rhs: float

    def require(self, where: str) -> None:
        if not self.stable:
            raise RobofdiError(f"{where}: a boundary-layer (sat) cascade with these gains is unstable: Routh–Hurwitz needs "
                               f"{self.condition}, got {self.lhs:,.0f} vs {self.rhs:,.0f}; use sign switching with a "
                               "low-pass equivalent control, or other gains")


def boundary_layer_routh(gains: Sequence[float], eps: float = 1.0) -> RouthVerdict:
    """The E2.5 guard: inside the boundary layer ψ = ē/ε the q-stage cascade is linear with characteristic
    polynomial s^q + k1 s^{q−1} + k1k2 s^{q−2} + … + k1⋯kq, k_j = λ_j/ε; its Routh array decides stability."""
    lam = np.array(gains, dtype=float).ravel()
    if lam.size < 1 or not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise RobofdiError(f"boundary_layer_routh: field 'gains' must be positive numbers, got {gains!r}")
    k = lam / eps
    coeffs = np.concatenate([[1.0], np.cumprod(k)])
    q = lam.size
    # Routh array: first column positive
    rows = [coeffs[0::2].copy(), coeffs[1::2].copy()]
    width = len(rows[0])
    rows = [np.pad(r, (0, width - len(r))) for r in rows]
    stable = True
    for _ in range(q - 1):
        a, b = rows[-2], rows[-1]
        if b[0] <= 0:
            stable = False
            break
        new = np.zeros(width)
        for j in range(width - 1):
            new[j] = (b[0] * a[j + 1] - a[0] * b[j + 1]) / b[0]
        rows.append(new)
    if stable:
        stable = all(r[0] > 0 for r in rows[: q + 1])
    l1 = lam
    if q == 4:
        cond, lhs, rhs = "λ1λ2 > λ2λ3 + λ1λ4", l1[0] * l1[1], l1[1] * l1[2] + l1[0] * l1[3]
    elif q == 3:
        cond, lhs, rhs = "λ1 > λ3", l1[0], l1[2]
    else:
        cond, lhs, rhs = "every first-column entry of the Routh array > 0", float(min(r[0] for r in rows)), 0.0
    return RouthVerdict(bool(stable), tuple(float(c) for c in np.concatenate([[1.0], np.cumprod(lam)])), cond,
                        float(lhs), float(rhs))


# ----------------------------------------------------------------------------------------------------- stepping
@dataclass(frozen=True)
class SlidingDetector:
    """The staging by detection instead of a schedule (Saif & Xiong Sec. 4, anti-peaking: "we do not inject the
    observation error information before reaching the sliding manifold linked with this information … we reach
    the manifold one by one"): a cascade stage j (``after`` = i) switches on, and stays on, once stage i is on and
    the interval mean of its error |ē_i| (chattering averages out over a diagnosis period) has stayed within
    ``band`` (one value, or one per stage, in the stage's error unit) for ``dwell`` [s]. Output stages are on from
    the start. Checked once per diagnosis sample, so a stage switches on at a sample instant."""

    band: float | Sequence[float]
    dwell: float

    def __post_init__(self):
        band = np.atleast_1d(np.array(self.band, dtype=float))
        if band.ndim != 1 or not np.all(np.isfinite(band)) or np.any(band <= 0):
            raise RobofdiError(f"SlidingDetector: field 'band' must be error bands > 0 (one, or one per stage), "
                               f"got {self.band!r}")
        if not (is_number(self.dwell) and self.dwell >= 0):
            raise RobofdiError(f"SlidingDetector: field 'dwell' must be a time >= 0 s, got {self.dwell!r}")
        object.__setattr__(self, "band", tuple(float(b) for b in band) if band.size > 1 else float(band[0]))


@dataclass(frozen=True)
class SMOSettings:
    """How a sliding-mode observer is integrated (the chapter gives none of it; digest-calibrated defaults).

    sample_time: the diagnosis period T [s]; substep: the Euler step h [s] (< every filter constant τ);
    tau: the equivalent-control low-pass time constant τ [s] (one value, or one per stage); switching: "sign",
    "sat" (boundary layer ε = ``boundary``) or "unit" (eq. 17); activation: switch-on time [s] per stage (None: 0);
    detector: a :class:`SlidingDetector` that switches the cascade stages on instead (exclusive with activation)."""

    sample_time: float = 1e-3
    substep: float = 1e-7
    tau: float | Sequence[float] = 1e-4
    switching: str = "sign"
    boundary: float = 0.02
    activation: Sequence[float] | None = None
    detector: SlidingDetector | None = None

    def __post_init__(self):
        w = "SMOSettings"
        if self.detector is not None and not isinstance(self.detector, SlidingDetector):
            raise RobofdiError(f"{w}: field 'detector' must be None or a SlidingDetector, got {self.detector!r}")
        if self.detector is not None and self.activation is not None:
            raise RobofdiError(f"{w}: fields 'activation' and 'detector' exclude each other (a schedule or a sliding "
                               "detector switches the stages on, not both)")
        check_fields(w, self, [("sample_time", is_number(self.sample_time) and self.sample_time > 0, "a period > 0 s"),
                               ("substep", is_number(self.substep) and 0 < self.substep <= self.sample_time,
                                "a step in (0, sample_time] s"),
                               ("switching", self.switching in SWITCHING, f"one of {sorted(SWITCHING)}"),
                               ("boundary", is_number(self.boundary) and self.boundary > 0, "a boundary layer ε > 0")])
        tau = np.atleast_1d(np.array(self.tau, dtype=float))
        if tau.ndim != 1 or not np.all(np.isfinite(tau)) or np.any(tau <= 0):
            raise RobofdiError(f"{w}: field 'tau' must be time constants > 0 s, got {self.tau!r}")
        if np.any(self.substep >= tau):
            raise RobofdiError(f"{w}: field 'substep' ({self.substep:g} s) must be smaller than the equivalent-control "
                               f"filter constant tau ({tau.min():g} s): the switching must be faster than its filter")
        object.__setattr__(self, "tau", tuple(float(t) for t in tau) if tau.size > 1 else float(tau[0]))
        if self.activation is not None:
            act = tuple(float(a) for a in self.activation)
            if not all(np.isfinite(a) and a >= 0 for a in act):
                raise RobofdiError(f"{w}: field 'activation' must be switch-on times >= 0 s, got {self.activation!r}")
            object.__setattr__(self, "activation", act)


@dataclass(frozen=True)
class Stage:
    """One switching stage. ``inject``: the column V_j added to x̂' times ψ(ē_j) (a state index i means λ e_i);
    ``lam``: λ_j (the amplitude whose filtered value is the stage's equivalent control z_j); source: an output
    stage has ``Wy`` (p) and ``Cx`` (n) with ē_j = Wy·y − Cx·x̂; a cascade stage has ``after`` (the index of the
    stage whose z it reads) and ``gain`` (g(y) → ē_j = g(y) z_after; default 1; 0 disables the stage, E4.3)."""

    lam: float
    inject: int | Sequence[float]
    Wy: Sequence[float] | None = None
    Cx: Sequence[float] | None = None
    after: int | None = None
    gain: Callable[[np.ndarray], float] | None = None
    name: str = ""


class CascadeSMO:
    """Diagnoser protocol: a sub-stepped sliding-mode observer (module docstring, :mod:`robofdi.observers.smo_kernel`).

    ``affine(y, u) -> (M, c)``: the observer's known dynamics x̂' = M(y) x̂ + c(y, u) (no injection); ``stages``:
    the switching stages in order. Residual components: each stage's equivalent control at the diagnosis rate, the
    mean of λ_j ψ(ē_j) over the sample interval (named by ``residual_names``, default the stage names) — the SMFO
    residuals r_k of eq. (71) and the SMOO r_eq. (The cascade itself uses the low-pass z_j; sampling z_j instead
    aliases its switching ripple: measured on Example 5, 2 s means of r2 of 0.68–1.89 for f_a2 = 1 against
    0.93–1.01 for the interval means.) Estimate:
    none unless ``estimate`` (indices of stages whose z is a fault estimate, e.g. r1 = f_a2). ``state_estimate``:
    x̂ (mapped by ``output_map`` when the observer runs in other coordinates, x = Γ1 x̄). ``mean_injection`` /
    ``peak``: the interval mean of λψ and the max |z| inside the last interval; ``history`` (with
    ``keep_history``): x (``state_estimate``) after every update since the last reset."""

    def __init__(self, n: int, affine: Callable, stages: Sequence[Stage], settings: SMOSettings,
                 inputs: Sequence[str], measurements: Sequence[str], x0=None, state_names: Sequence[str] | None = None,
                 residual_names: Sequence[str] | None = None, residual_units: Sequence[str] | None = None,
                 estimate: Sequence[int] = (), estimate_names: Sequence[str] = (), estimate_units: Sequence[str] = (),
                 output_map: np.ndarray | None = None, signatures: Sequence = (), where: str = "CascadeSMO",
                 initial: Callable[[np.ndarray], np.ndarray] | None = None, keep_history: bool = False):
        self.where = where
        self.n, self.settings, self.affine = int(n), settings, affine
        self.inputs, self.measurements = list(inputs), list(measurements)
        p, S = len(self.measurements), len(stages)
        if S == 0:
            raise RobofdiError(f"{where}: field 'stages' must hold at least one stage")
        self.stages = tuple(stages)
        self.V = np.zeros((self.n, S))
        self.Wy, self.Cx = np.zeros((S, p)), np.zeros((S, self.n))
        self.kind, self.src = np.zeros(S, dtype=np.int64), np.zeros(S, dtype=np.int64)
        self.lam = np.zeros(S)
        for j, st in enumerate(self.stages):
            if not (is_number(st.lam) and st.lam > 0):
                raise RobofdiError(f"{where}: stage {j}: field 'lam' must be a gain > 0, got {st.lam!r}")
            self.lam[j] = st.lam
            if isinstance(st.inject, (int, np.integer)):
                if not 0 <= st.inject < self.n:
                    raise RobofdiError(f"{where}: stage {j}: field 'inject' must be a state index in [0, {self.n}), "
                                       f"got {st.inject}")
                self.V[st.inject, j] = st.lam
            else:
                self.V[:, j] = _mat(st.inject, "inject", where, rows=self.n, cols=1)[:, 0]
            if st.after is None:
                if st.Wy is None or st.Cx is None:
                    raise RobofdiError(f"{where}: stage {j}: an output stage needs 'Wy' and 'Cx' (or give 'after')")
                self.Wy[j] = _mat(st.Wy, "Wy", where, rows=1, cols=p)[0]
                self.Cx[j] = _mat(st.Cx, "Cx", where, rows=1, cols=self.n)[0]
            else:
                if not (isinstance(st.after, (int, np.integer)) and 0 <= st.after < S and st.after != j):
                    raise RobofdiError(f"{where}: stage {j}: field 'after' must be another stage's index, got {st.after!r}")
                self.kind[j], self.src[j] = 1, st.after
        tau = np.broadcast_to(np.array(settings.tau, dtype=float), (S,)) if np.ndim(settings.tau) == 0 or \
            len(np.atleast_1d(settings.tau)) == S else None
        if tau is None:
            raise RobofdiError(f"{where}: settings field 'tau' must be one value or one per stage ({S}), got {settings.tau!r}")
        self.tau = np.array(tau)
        act = settings.activation
        if act is not None and len(act) != S:
            raise RobofdiError(f"{where}: settings field 'activation' must hold one switch-on time per stage ({S}), "
                               f"got {len(act)}")
        self.activation = np.zeros(S) if act is None else np.array(act)
        det = settings.detector
        if det is not None:
            band = np.atleast_1d(np.array(det.band, dtype=float))
            if band.size not in (1, S):
                raise RobofdiError(f"{where}: settings field 'detector': 'band' must be one value or one per stage ({S}), "
                                   f"got {len(band)}")
            self.band = np.broadcast_to(band, (S,)).copy()
        T, h = settings.sample_time, settings.substep
        self.nsub = max(1, int(np.ceil(T / h - 1e-9)))
        self.h = T / self.nsub
        self.alpha = 1.0 - np.exp(-self.h / self.tau)
        self.sw = SWITCHING[settings.switching]
        if self.sw == SAT:
            self._routh_guard()
        self.x0 = np.zeros(self.n) if x0 is None else _mat(x0, "x0", where, rows=self.n, cols=1)[:, 0]
        names = [st.name or f"stage{j + 1}" for j, st in enumerate(self.stages)]
        self.components = list(residual_names) if residual_names is not None else names
        if len(self.components) != S:
            raise RobofdiError(f"{where}: field 'residual_names' must hold {S} names, got {len(self.components)}")
        self.estimate_index = [int(i) for i in estimate]
        self.estimate_components = list(estimate_names) if estimate_names else [self.components[i] for i in
                                                                               self.estimate_index]
        self.estimate_modes = ["level"] * len(self.estimate_index)
        self.units = {"residual": list(residual_units or ["1"] * S),
                      "estimate": list(estimate_units or ["1"] * len(self.estimate_index))}
        self.state_names = list(state_names or [f"x{i + 1}" for i in range(self.n)])
        self.output_map = None if output_map is None else np.array(output_map, dtype=float)
        self._signatures = list(signatures)
        self.initial = initial
        self.keep_history = bool(keep_history)
        self.reset()

    def _routh_guard(self) -> None:
        """A chain of ≥ 3 cascaded sat stages is the linear observer of :func:`boundary_layer_routh` inside the
        boundary layer: refused when Routh–Hurwitz fails (Saif & Xiong's Example 2 gains, digest E2.5)."""
        S = len(self.stages)
        for j in range(S):
            if self.kind[j] != 0:
                continue
            chain, k = [j], j
            while True:
                nxt = [i for i in range(S) if self.kind[i] == 1 and self.src[i] == k]
                if not nxt:
                    break
                k = nxt[0]
                chain.append(k)
            if len(chain) >= 3:
                boundary_layer_routh(self.lam[chain], self.settings.boundary).require(self.where)

    def reset(self) -> None:
        self.x = self.x0.copy()
        self.z = np.zeros(len(self.stages))
        self._y: list[np.ndarray] = []
        self._ends = None
        self.k = -1
        self.mean_injection = np.zeros(len(self.stages))
        self.peak = np.zeros(len(self.stages))
        self.history: list[np.ndarray] = []
        #: switch-on time [s] per stage (inf: still off); the schedule's, or what the sliding detector decided
        self.switched_on = np.where(self.kind == 0, 0.0, np.inf) if self.settings.detector is not None else \
            self.activation.copy()
        self._slid_for = np.zeros(len(self.stages))

    def signatures(self) -> list:
        return list(self._signatures)

    def _detect(self, active: np.ndarray, emean: np.ndarray, T: float) -> None:
        """:class:`SlidingDetector`: time each on-stage has slid (|mean ē| within its band); switch on the stages
        reading one that has slid for the dwell time, at this sample instant."""
        inside = (active == 1) & (np.abs(emean) <= self.band)
        self._slid_for = np.where(inside, self._slid_for + T, 0.0)
        ready = self._slid_for >= self.settings.detector.dwell - 1e-12
        for j in range(len(self.stages)):
            if self.kind[j] == 1 and not np.isfinite(self.switched_on[j]) and ready[self.src[j]]:
                self.switched_on[j] = self.k * T

    @property
    def time(self) -> float:
        return max(self.k, 0) * self.settings.sample_time

    @property
    def state_estimate(self) -> np.ndarray:
        return self.x.copy() if self.output_map is None else self.output_map @ self.x

    def _gains(self, y: np.ndarray) -> np.ndarray:
        return np.array([1.0 if st.gain is None else float(st.gain(y)) for st in self.stages])

    def _ycoef(self, T: float) -> np.ndarray:
        """Cubic Hermite y(s) on [t_{k−1}, t_k] (s from 0): slopes by central (start) and backward (end) differences."""
        ys = self._y
        y1, y0 = ys[-1], ys[-2]
        if len(ys) >= 3:
            ym = ys[-3]
            m0, m1 = (y1 - ym) / (2 * T), (3 * y1 - 4 * y0 + ym) / (2 * T)
        else:
            m0 = m1 = (y1 - y0) / T
        d = y1 - y0
        c2 = (3 * d - (2 * m0 + m1) * T) / T ** 2
        c3 = (-2 * d + (m0 + m1) * T) / T ** 3
        return np.ascontiguousarray(np.stack([y0, m0, c2, c3], axis=1))

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        y = check_measurement(y, len(self.measurements), "y")
        u = check_measurement(u, len(self.inputs), "u")
        self.k += 1
        self._y.append(y)
        if len(self._y) > 3:
            self._y.pop(0)
        if self.k == 0 and self.initial is not None:
            self.x = np.array(self.initial(y), dtype=float)
        if self.k > 0:
            T = self.settings.sample_time
            y0 = self._y[-2]
            M0, c0 = self.affine(y0, u)
            M1, c1 = self.affine(y, u)
            g0, g1 = self._gains(y0), self._gains(y)
            t0 = (self.k - 1) * T
            active = (self.switched_on <= t0 + 1e-12).astype(np.int64)
            self.mean_injection, self.peak, emean = integrate_interval(
                self.x, self.z, self.nsub, self.h, self._ycoef(T), np.ascontiguousarray(M0, dtype=float),
                np.ascontiguousarray(M1, dtype=float), np.asarray(c0, dtype=float), np.asarray(c1, dtype=float),
                self.V, self.Wy, self.Cx, self.kind, self.src, g0, g1, self.lam, active, self.sw,
                self.settings.boundary, self.alpha)
            if not (np.all(np.isfinite(self.x)) and np.all(np.isfinite(self.z))):
                raise RobofdiError(f"{self.where}: the observer diverged at t = {self.time:.4g} s (non-finite state); "
                                   "check the gains, the substep and the filter constant")
            if self.settings.detector is not None:
                self._detect(active, emean, T)
        if self.keep_history:
            self.history.append(self.state_estimate)
        r = self.mean_injection.copy()
        return Residual(r, r[self.estimate_index].copy())


# ----------------------------------------------------------------------------------------------------- factories
def _names(names, size, prefix):
    return list(names) if names is not None else [f"{prefix}{i + 1}" for i in range(size)]


def utkin_smo(A, B, C, L1, poles, settings: SMOSettings, x0=None, inputs=None, measurements=None) -> CascadeSMO:
    """Utkin's SMO (5), (7) in the coordinates x̄ = T x of (3): ŷ' = A22ŷ + A21x̂1 + B2u + L1 sign(y − ŷ),
    x̂1' = A11x̂1 + A12y + B1u + L2L1 sign(y − ŷ); L1 diagonal (one stage per output), L2 from :func:`utkin_design`.
    ``state_estimate`` is x = T⁻¹ x̄."""
    d = utkin_design(A, B, C, poles)
    A = np.array(A, dtype=float)
    n, p = A.shape[0], d.A22.shape[0]
    r = n - p
    l1 = np.atleast_1d(np.array(L1, dtype=float))
    if l1.shape != (p,) or np.any(l1 <= 0):
        raise RobofdiError(f"utkin_smo: field 'L1' must be {p} positive gains (L1 diagonal), got {L1!r}")
    Bb = np.vstack([d.B1, d.B2])
    Mx = np.block([[d.A11, np.zeros((r, p))], [d.A21, d.A22]])
    Ny = np.vstack([d.A12, np.zeros((p, p))])

    def affine(y, u):
        return Mx, Ny @ y + Bb @ u

    stages = []
    for i in range(p):
        inj = np.zeros(n)
        inj[:r] = d.L2[:, i] * l1[i]
        inj[r + i] = l1[i]
        stages.append(Stage(l1[i], inj, Wy=np.eye(p)[i], Cx=np.eye(n)[r + i], name=f"eq{i + 1}"))
    Ti = np.linalg.inv(d.T)
    xb0 = None if x0 is None else d.T @ np.array(x0, dtype=float)
    return CascadeSMO(n, affine, stages, settings, _names(inputs, Bb.shape[1], "u"), _names(measurements, p, "y"),
                      x0=xb0, output_map=Ti, where="utkin_smo")


def walcott_zak_smo(A, B, C, G, rho: float, settings: SMOSettings, design: WalcottZakDesign | None = None, x0=None,
                    inputs=None, measurements=None) -> CascadeSMO:
    """The W–Z SMO (16): x̂' = A x̂ + B u + K(y − C x̂) + ν with ν = ρ G sign(W C e) (18) for switching "sign" or
    ν = ρ G W C e/‖W C e‖ (17) for "unit"; W C e = W (y − C x̂). Residuals: the filtered ν components (q)."""
    A, C, G = _abc(A, C, "walcott_zak_smo", G)
    d = design or walcott_zak_design(A, G, C)
    n, q = A.shape[0], G.shape[1]
    B = _mat(B, "B", "walcott_zak_smo", rows=n)
    if not (is_number(rho) and rho > 0):
        raise RobofdiError(f"walcott_zak_smo: field 'rho' must be > 0 (ρ ≥ sup‖d‖), got {rho!r}")
    Mx = A - d.K @ C

    def affine(y, u):
        return Mx, d.K @ y + B @ u

    stages = [Stage(rho, rho * G[:, i], Wy=d.W[i], Cx=d.W[i] @ C, name=f"nu{i + 1}") for i in range(q)]
    return CascadeSMO(n, affine, stages, settings, _names(inputs, B.shape[1], "u"), _names(measurements, C.shape[0], "y"),
                      x0=x0, where="walcott_zak_smo")


def chain_smo(A, B, C, G, gains: Sequence[float], settings: SMOSettings, x0=None, inputs=None, measurements=None,
              names: Sequence[str] | None = None) -> CascadeSMO:
    """The new SMO (38) (and SMFO (70)) on a SISO chain of relative degree n, in the chain coordinates of
    :func:`relative_degree_chain`: x̄̂_k' = x̄̂_{k+1} + B̄_k u + λ_k ψ(ē_k), x̄̂_n' = Ā_n x̄̂ + B̄_n u + λ_n ψ(ē_n),
    ē_1 = y − x̄̂_1, ē_{k+1} = (λ_k ψ(ē_k))_eq (39). ``state_estimate`` is x = Γ1 x̄̂; residuals r_k (71)."""
    ch = relative_degree_chain(A, G, C, B)
    n = len(ch.markov)
    if ch.relative_degree != n:
        raise RobofdiError(f"chain_smo: the relative degree is {ch.relative_degree} < n = {n}; this factory needs one chain "
                           "through the whole state (build the x_o observer beside it with CascadeSMO, Remark 7)")
    lam = np.array(gains, dtype=float).ravel()
    if lam.shape != (n,):
        raise RobofdiError(f"chain_smo: field 'gains' must hold {n} gains λ_1..λ_{n}, got {gains!r}")
    Ab, Bb = ch.Abar, ch.Bbar

    def affine(y, u):
        return Ab, Bb @ u

    stages = [Stage(lam[0], 0, Wy=[1.0], Cx=np.eye(n)[0], name="r1")]
    stages += [Stage(lam[k], k, after=k - 1, name=f"r{k + 1}") for k in range(1, n)]
    xb0 = None if x0 is None else np.linalg.solve(ch.Gamma1, np.array(x0, dtype=float))
    return CascadeSMO(n, affine, stages, settings, _names(inputs, Bb.shape[1], "u"), _names(measurements, 1, "y"),
                      x0=xb0, output_map=ch.Gamma1, residual_names=names, where="chain_smo")


def output_observer(L: Callable, gains: Sequence[float], settings: SMOSettings, inputs, measurements, z0=None,
                    residual_units=None, signatures: Sequence = (), estimate: Sequence[int] = (),
                    estimate_names: Sequence[str] = (), estimate_units: Sequence[str] = ()) -> CascadeSMO:
    """The SMOO (54): z' = L(y, u) + Λ sign(y − z), residual r_eq = (Λ sign(y − z))_eq (Sec. 5); linear case (60):
    L = K y + C B u. z starts at the first measurement unless ``z0`` is given. ``L(y, u)`` returns the p-vector;
    the residual components are named ``req_<measurement>``."""
    lam = np.array(gains, dtype=float).ravel()
    p = len(measurements)
    if lam.shape != (p,):
        raise RobofdiError(f"output_observer: field 'gains' must hold {p} gains λ_i, got {gains!r}")
    zero = np.zeros((p, p))

    def affine(y, u):
        return zero, np.asarray(L(y, u), dtype=float)

    stages = [Stage(lam[i], i, Wy=np.eye(p)[i], Cx=np.eye(p)[i], name=f"req_{measurements[i]}") for i in range(p)]
    return CascadeSMO(p, affine, stages, settings, inputs, measurements, x0=z0, residual_units=residual_units,
                      signatures=signatures, estimate=estimate, estimate_names=estimate_names,
                      estimate_units=estimate_units, where="output_observer",
                      initial=(lambda y: y) if z0 is None else None)
