"""Reduced-order Kalman filter fault estimation for discrete MIMO systems — Jiang & Chowdhury, "Fault estimation
and accommodation for linear MIMO discrete-time systems", IEEE TCST 13(3), 2005 (eqs. (5)–(28), and (31)–(41) for
the unknown-input extension).

Model (1)–(2): x(k+1) = A x + B u + E f + D ζ + ω,  y = C x + v,  cov ω = S > 0 (process), cov v = Q > 0 (sensor).
Coordinates x̄ = T x = col(x₁, x₂, x₃) with x₁ = N x (N an orthonormal basis of C's null space: the unmeasured part)
and col(x₂, x₃) = ȳ = Π C x, the outputs reordered so that y₂ (the ``fault_outputs``, q of them) comes last:
then C̄ = [0 I], and Assumption 1 reads rank(CE) = q with E₃ (q×q) non-singular. The fault is eliminated from the
measured rows, a Kalman filter estimates x₁ from the derived measurement λ, and the fault follows one step late:

    f̂(k−1) = E₃⁻¹ [y₂(k) − A₃ x̂(k−1) − B₃ u(k−1) − D₃ ζ̂(k−1)]                                     (28), (41)

The covariances (16)–(19) of the reduced filter are garbled in the printed paper (an erratum):
``covariance_mode`` "as_printed" uses them literally, "swapped" exchanges the two names (T₁ maps the process noise
of x₁, T₂ the derived measurement noise), "corrected" uses the noise vector [ω(k); v(k); v(k+1)] (cross term
ignored). Noise-free, the estimate is exact once x̂₁ has converged, whatever the mode.
"""
from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import LinearModel, covariance_factor, format_mode, require_discrete, unobservable_modes
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["ReducedOrderDesign", "reduced_order_design", "reduced_order_covariances", "steady_state_gain",
           "KalmanFaultEstimator", "COVARIANCE_MODES", "ParameterFaultEKF", "EffectivenessDiagnoser",
           "parameter_directions_of"]

COVARIANCE_MODES = ("as_printed", "swapped", "corrected")
#: Smallest singular value (relative to ‖CE‖) below which E₃ counts as singular.
SINGULAR_RTOL = 1e-9


def _matrix(value, rows: int, name: str, where: str) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise RobofdiError(f"{where}: field {name!r} must be a numeric matrix with {rows} rows, got {value!r}") from None
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != rows or a.shape[1] == 0 or not np.all(np.isfinite(a)):
        raise RobofdiError(f"{where}: field {name!r} must be a finite {rows}xq matrix (q >= 1), got shape {a.shape}")
    return a


@dataclass(frozen=True)
class ReducedOrderDesign:
    """The partition of Jiang & Chowdhury Sec. II in the coordinates x̄ = T x (see the module docstring).

    ``order``: output indices, ȳ = y[order] = col(y₁, y₂). Blocks: n1 = n − p (unmeasured), n2 = p − q, q.
    ``Abar`` etc. are the eliminated matrices Ā₁ = A₁ − E₁E₃⁻¹A₃, Ā₂ = A₂ − E₂E₃⁻¹A₃ (eqs. (5)–(10)).
    """

    T: np.ndarray
    T_inv: np.ndarray
    order: np.ndarray
    fault_outputs: tuple[str, ...]
    n1: int
    n2: int
    q: int
    A: np.ndarray            # T A T⁻¹
    B: np.ndarray            # T B
    E: np.ndarray            # T E
    E3_inv: np.ndarray
    G1: np.ndarray           # E₁ E₃⁻¹
    G2: np.ndarray           # E₂ E₃⁻¹
    Abar1: np.ndarray        # n1 × n
    Abar2: np.ndarray        # n2 × n
    Bbar1: np.ndarray
    Bbar2: np.ndarray
    rank_CE: int

    def blocks(self, M: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Column blocks (n1, n2, q) of an n-column matrix, e.g. Ā₁ = [Ā₁₁ Ā₁₂ Ā₁₃]."""
        a, b = self.n1, self.n1 + self.n2
        return M[:, :a], M[:, a:b], M[:, b:]

    @property
    def Abar11(self) -> np.ndarray:
        return self.blocks(self.Abar1)[0]

    @property
    def Abar21(self) -> np.ndarray:
        return self.blocks(self.Abar2)[0]


def reduced_order_design(model: LinearModel, E, fault_outputs: Sequence[str] | None = None) -> ReducedOrderDesign:
    """Partition and fault elimination — Jiang & Chowdhury (2005) eqs. (5)–(10), Assumption 1.

    model: discrete, C of full row rank p < n. E: n×q fault distribution (q ≤ p). fault_outputs: the q output
    names that form y₂ (E₃ must be non-singular for them); None: the choice with the best-conditioned E₃.
    """
    where = "reduced_order_design"
    model = require_discrete(model, where, "diagnosis")
    n, p = model.n, model.p
    E = _matrix(E, n, "E", where)
    q = E.shape[1]
    C = model.C
    if np.linalg.matrix_rank(C) < p:
        raise RobofdiError(f"{where}: C must have full row rank p={p} (independent sensors), got rank "
                           f"{np.linalg.matrix_rank(C)}")
    if p >= n:
        raise RobofdiError(f"{where}: the reduced-order filter needs unmeasured states (p < n), got p={p}, n={n}")
    if q >= p:
        raise RobofdiError(f"{where}: field 'E' has q={q} fault channels; the method needs q < p={p} outputs "
                           "(y₁ non-empty drives the filter)")
    CE = C @ E
    rank_CE = int(np.linalg.matrix_rank(CE))
    if rank_CE != q:
        raise RobofdiError(f"{where}: Assumption 1 violated: rank(CE) = {rank_CE}, expected q = {q} "
                           "(every fault must reach the outputs independently)")
    scale = max(float(np.linalg.norm(CE, 2)), 1e-300)
    names = list(model.output_names)
    if fault_outputs is None:
        best = max(itertools.combinations(range(p), q),
                   key=lambda sel: np.linalg.svd(CE[list(sel)], compute_uv=False)[-1])
        sel = list(best)
    else:
        if isinstance(fault_outputs, str):
            raise RobofdiError(f"{where}: field 'fault_outputs' must be a list of {q} output names, got a string")
        fault_outputs = list(fault_outputs)
        unknown = [o for o in fault_outputs if o not in names]
        if unknown or len(fault_outputs) != q or len(set(fault_outputs)) != q:
            raise RobofdiError(f"{where}: field 'fault_outputs' must be {q} distinct names of {names}, got {fault_outputs}")
        sel = [names.index(o) for o in fault_outputs]
    E3_raw = CE[sel]
    smallest = float(np.linalg.svd(E3_raw, compute_uv=False)[-1])
    if smallest <= SINGULAR_RTOL * scale:
        raise RobofdiError(f"{where}: E₃ (the rows of CE for fault_outputs {[names[i] for i in sel]}) is singular "
                           f"(smallest singular value {smallest:.3g}); Assumption 1 needs it non-singular: choose "
                           "other fault_outputs")
    order = np.array([i for i in range(p) if i not in sel] + sel)
    N = scipy.linalg.null_space(C)                                   # n × (n − p), orthonormal
    N = N * np.where(N[np.argmax(np.abs(N), axis=0), range(N.shape[1])] < 0, -1.0, 1.0)   # sign convention
    T = np.vstack([N.T, C[order]])
    T_inv = np.linalg.inv(T)
    Ab, Bb, Eb = T @ model.A @ T_inv, T @ model.B, T @ E
    n1, n2 = n - p, p - q
    E3 = Eb[n1 + n2:]
    E3_inv = np.linalg.inv(E3)
    G1, G2 = Eb[:n1] @ E3_inv, Eb[n1:n1 + n2] @ E3_inv
    A3, B3 = Ab[n1 + n2:], Bb[n1 + n2:]
    return ReducedOrderDesign(
        T=T, T_inv=T_inv, order=order, fault_outputs=tuple(names[i] for i in sel), n1=n1, n2=n2, q=q, A=Ab, B=Bb,
        E=Eb, E3_inv=E3_inv, G1=G1, G2=G2, Abar1=Ab[:n1] - G1 @ A3, Abar2=Ab[n1:n1 + n2] - G2 @ A3,
        Bbar1=Bb[:n1] - G1 @ B3, Bbar2=Bb[n1:n1 + n2] - G2 @ B3, rank_CE=rank_CE)


def _positive_definite(value, size: int, name: str, where: str, equation: str) -> np.ndarray:
    M, _ = covariance_factor(value, size, name)
    smallest = float(np.linalg.eigvalsh(M).min())
    if smallest <= 0:
        raise RobofdiError(f"{where}: field {name!r} must be positive definite ({equation}), got smallest eigenvalue "
                           f"{smallest:.3g}")
    return M


def reduced_order_covariances(design: ReducedOrderDesign, process_noise, measurement_noise,
                              mode: str = "as_printed") -> tuple[np.ndarray, np.ndarray]:
    """(Q̄ process covariance of x₁, S̄ covariance of the derived measurement λ) — Jiang & Chowdhury eqs. (16)–(19).

    process_noise S (n×n, or n variances) on x, measurement_noise Q (p×p, or p variances) on y, both positive
    definite (eq. (4)). ``mode``: "as_printed" (eqs. (16)–(19) literally: S̄ = T₁ΣT₁ᵀ, Q̄ = T₂ΣT₂ᵀ), "swapped"
    (the two names exchanged), "corrected" (η = [ω(k); v(k); v(k+1)], Q_w = G_wΣG_wᵀ, R_v = G_vΣG_vᵀ;
    derived from the paper's noise model, checked numerically).
    """
    where = "reduced_order_covariances"
    if mode not in COVARIANCE_MODES:
        raise RobofdiError(f"{where}: field 'covariance_mode' must be one of {COVARIANCE_MODES}, got {mode!r}")
    d = design
    n, p = d.T.shape[0], d.n2 + d.q
    S = _positive_definite(process_noise, n, "process_noise", where, "S = Sᵀ > 0, eq. (4)")
    Q = _positive_definite(measurement_noise, p, "measurement_noise", where, "Q = Qᵀ > 0, eq. (4)")
    P = np.eye(p)[d.order]
    Sb, Qb = d.T @ S @ d.T.T, P @ Q @ P.T                          # ω and v in the partitioned coordinates
    _, A12, A13 = d.blocks(d.Abar1)
    _, A22, A23 = d.blocks(d.Abar2)
    I1, I2 = np.eye(d.n1), np.eye(d.n2)
    Z12, Z21 = np.zeros((d.n1, d.n2)), np.zeros((d.n2, d.n1))
    if mode == "corrected":
        Sigma = scipy.linalg.block_diag(Sb, Qb, Qb)
        Gw = np.hstack([I1, Z12, -d.G1, -A12, -A13, np.zeros((d.n1, d.n2)), -d.G1])
        Gv = np.hstack([Z21, I2, -d.G2, -A22, -A23, I2, -d.G2])
        return Gw @ Sigma @ Gw.T, Gv @ Sigma @ Gv.T
    Sigma = scipy.linalg.block_diag(Sb, Qb)
    T1 = np.hstack([I1, Z12, -d.G1, -A12, -A13 - d.G1])                            # (18) as printed
    T2 = np.hstack([Z21, I2, -d.G2, I2 + A22, -A23 - d.G2])                          # (19) as printed
    S_bar, Q_bar = T1 @ Sigma @ T1.T, T2 @ Sigma @ T2.T                            # (16), (17)
    return (Q_bar, S_bar) if mode == "as_printed" else (S_bar, Q_bar)


def _augmented(design: ReducedOrderDesign, D: np.ndarray | None):
    """(A_a, C_a, D̄₃): the filter's state ξ = col(x₁, ζ) — eqs. (33)–(37); without D, ξ = x₁."""
    d = design
    A11, C21 = d.Abar11, d.Abar21
    if D is None:
        return A11, C21, np.zeros((d.q, 0))
    Db = d.T @ D
    D1, D2, D3 = Db[:d.n1], Db[d.n1:d.n1 + d.n2], Db[d.n1 + d.n2:]
    s = D.shape[1]
    Aa = np.block([[A11, D1 - d.G1 @ D3], [np.zeros((s, d.n1)), np.eye(s)]])
    Ca = np.hstack([C21, D2 - d.G2 @ D3])
    return Aa, Ca, D3


def steady_state_gain(Aa: np.ndarray, Ca: np.ndarray, Qa: np.ndarray, Sa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, P) of the stationary filter (14)–(15): P the stabilising solution of the filter DARE (scipy), K = A P Cᵀ
    (C P Cᵀ + S̄)⁻¹ — Anderson & Moore, *Optimal Filtering* (1979) Sec. 4.4."""
    try:
        P = scipy.linalg.solve_discrete_are(Aa.T, Ca.T, Qa, Sa)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise RobofdiError(f"steady_state_gain: no stabilising solution of the filter Riccati equation ({exc})") from None
    return Aa @ P @ Ca.T @ np.linalg.inv(Ca @ P @ Ca.T + Sa), P


class KalmanFaultEstimator:
    """Diagnoser protocol: the reduced-order Kalman fault estimator of Jiang & Chowdhury (2005), eqs. (11)–(28),
    with the unknown-input augmentation (31)–(41) when ``unknown_input`` D is given.

    model: discrete nominal model (the belief). E: n×q fault distribution; None = −B, the loss-of-effectiveness
    form f = R u of eq. (29) (q = m, the faults are named like the inputs). process_noise S, measurement_noise Q:
    positive-definite covariances. covariance_mode: see :func:`reduced_order_covariances`. gain: "recursive" (the
    time-varying K(k), P(k) of (14)–(15), from ``P0``) or "steady" (the DARE solution). x1_0: initial x̂₁ (and ζ̂).

    Residual and estimate (one per fault channel, named ``fault_names``): with E given, f̂(k−1) of eq. (28);
    in the loss-of-effectiveness form, r̂ᵢ = Σ f̂ᵢ uᵢ / Σ uᵢ² over the last ``window`` samples (window 1: the
    element-wise r̂ᵢ = f̂ᵢ(k−1) / uᵢ(k−1)), samples with |uᵢ| < ``min_input`` skipped — the paper leaves the step
    from f̂ to R̂ open (spec A.3 [HARNESS]).
    """

    def __init__(self, model: LinearModel, process_noise, measurement_noise, E=None, *,
                 fault_outputs: Sequence[str] | None = None, covariance_mode: str = "as_printed",
                 unknown_input=None, gain: str = "recursive", P0=None, x1_0=None, window: int = 1,
                 min_input: float = 1e-6, fault_names: Sequence[str] | None = None, fault_units: Sequence[str] | None = None):
        where = "KalmanFaultEstimator"
        self.model = model = require_discrete(model, where, "diagnosis")
        self.effectiveness = E is None
        E = -model.B if E is None else _matrix(E, model.n, "E", where)
        self.design = d = reduced_order_design(model, E, fault_outputs)
        self.Q_bar, self.S_bar = reduced_order_covariances(d, process_noise, measurement_noise, covariance_mode)
        self.covariance_mode = covariance_mode
        if np.linalg.eigvalsh(0.5 * (self.S_bar + self.S_bar.T)).min() <= 0:
            raise RobofdiError(f"{where}: the derived measurement covariance S̄ is not positive definite in mode "
                               f"{covariance_mode!r}")
        self.D = None if unknown_input is None else _matrix(unknown_input, model.n, "unknown_input", where)
        s = 0 if self.D is None else self.D.shape[1]
        self._Aa, self._Ca, self._D3 = _augmented(d, self.D)
        na = d.n1 + s
        self._Qa = scipy.linalg.block_diag(self.Q_bar, np.zeros((s, s)))
        modes = unobservable_modes(self._Aa, self._Ca)
        if modes:
            what = "(Ā₁₁, Ā₂₁)" if self.D is None else "the augmented pair ([Ā₁₁ D̄₁; 0 I], [Ā₂₁ D̄₂])"
            raise RobofdiError(f"{where}: Theorem 1 needs {what} observable; mode λ={format_mode(modes[0])} is not "
                               "(choose other fault_outputs, or a D that the derived measurement sees)")
        if gain not in ("recursive", "steady"):
            raise RobofdiError(f"{where}: field 'gain' must be 'recursive' or 'steady', got {gain!r}")
        self.gain = gain
        self._K_ss = steady_state_gain(self._Aa, self._Ca, self._Qa, self.S_bar)[0] if gain == "steady" else None
        self.P0 = np.eye(na) if P0 is None else _positive_definite(P0, na, "P0", where, "initial covariance")
        self.x1_0 = np.zeros(na) if x1_0 is None else check_measurement(x1_0, na, "x1_0")
        if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
            raise RobofdiError(f"{where}: field 'window' must be an integer >= 1 sample, got {window!r}")
        self.window = int(window)
        self.min_input = float(min_input)
        q = d.q
        if fault_names is None:
            fault_names = list(model.input_names) if self.effectiveness else [f"f{i + 1}" for i in range(q)]
        if len(fault_names) != q:
            raise RobofdiError(f"{where}: field 'fault_names' must hold {q} names, got {list(fault_names)}")
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(fault_names)
        self.estimate_components = list(fault_names)
        self.estimate_modes = ["level"] * q
        if self.effectiveness:
            units = ["1"] * q
        else:
            units = list(fault_units) if fault_units is not None else ["1"] * q
        self.units = {"residual": units, "estimate": units}
        self.reset()

    def reset(self) -> None:
        self._xi = None
        self._P = self.P0.copy()
        self._yb = None
        self.fault_estimate = np.zeros(self.design.q)
        self._history: deque = deque(maxlen=self.window)
        self._r = np.zeros(self.design.q)

    @property
    def state_estimate(self) -> np.ndarray | None:
        """x̂(k) = T⁻¹ col(x̂₁(k), ȳ(k)) — eq. (27), in the model's coordinates."""
        if self._xi is None:
            return None
        d = self.design
        return d.T_inv @ np.concatenate([self._xi[:d.n1], self._yb])

    @property
    def unknown_input_estimate(self) -> np.ndarray:
        """ζ̂(k) of the augmented filter (empty without D)."""
        return np.zeros(0) if self._xi is None else self._xi[self.design.n1:].copy()

    @property
    def filter_gain(self) -> np.ndarray:
        return self._K_ss if self._K_ss is not None else self._K

    def signatures(self) -> list:
        from robofdi.decision import Signature

        return [Signature(c, frozenset({c})) for c in self.components]

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y(k) now, u(k−1) held before it → residual (f̂(k−1) or r̂) — eqs. (11)–(15), (28)."""
        md, d = self.model, self.design
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        yb = y[d.order]
        if self._xi is None:
            self._xi, self._yb = self.x1_0.copy(), yb
            self._K = np.zeros((self._Aa.shape[0], d.n2))
            return Residual(np.zeros(d.q), np.zeros(d.q))
        n1, n2 = d.n1, d.n2
        y1, y2, y1p, y2p = yb[:n2], yb[n2:], self._yb[:n2], self._yb[n2:]
        _, A12, A13 = d.blocks(d.Abar1)
        _, A22, A23 = d.blocks(d.Abar2)
        rho = A12 @ y1p + A13 @ y2p + d.G1 @ y2 + d.Bbar1 @ u                           # (12)
        lam = y1 - d.G2 @ y2 - A22 @ y1p - A23 @ y2p - d.Bbar2 @ u                       # (13)
        Aa, Ca, P = self._Aa, self._Ca, self._P
        if self._K_ss is None:
            S_in = Ca @ P @ Ca.T + self.S_bar
            K = Aa @ P @ Ca.T @ np.linalg.inv(S_in)                                        # (14)
            self._P = Aa @ P @ Aa.T + self._Qa - K @ S_in @ K.T                            # (15)
            self._K = K
        else:
            K = self._K_ss
        xi_prev = self._xi
        x_prev = np.concatenate([xi_prev[:n1], self._yb])                               # x̂(k−1), eq. (27)
        xi = Aa @ xi_prev + K @ (lam - Ca @ xi_prev)                                    # (11), (38)
        xi[:n1] += rho
        A3, B3 = d.A[n1 + n2:], d.B[n1 + n2:]
        f = d.E3_inv @ (y2 - A3 @ x_prev - B3 @ u - self._D3 @ xi_prev[n1:])             # (28), (41)
        if not (all_finite(xi) and all_finite(f)):
            raise RobofdiError("KalmanFaultEstimator: the estimate diverged (non-finite); check the model and noise")
        self._xi, self._yb, self.fault_estimate = xi, yb, f
        r = self._effectiveness(f, u) if self.effectiveness else f.copy()
        return Residual(r, r.copy())

    def _effectiveness(self, f: np.ndarray, u: np.ndarray) -> np.ndarray:
        """R̂ from f̂ = R u: windowed least squares r̂ᵢ = Σ f̂ᵢuᵢ / Σ uᵢ² (spec A.3 [HARNESS])."""
        self._history.append((f, u))
        F = np.array([h[0] for h in self._history])
        U = np.array([h[1] for h in self._history])
        used = np.abs(U) >= self.min_input
        den = np.sum(np.where(used, U * U, 0.0), axis=0)
        num = np.sum(np.where(used, F * U, 0.0), axis=0)
        ok = den > 0
        self._r = np.where(ok, num / np.where(ok, den, 1.0), self._r)
        return self._r.copy()


def parameter_directions_of(value, n: int, where: str) -> np.ndarray:
    """The modelling error's directions Aⱼ as a (k, n, n) array (one n×n matrix, a list of them, or none)."""
    dirs = np.array(value, dtype=float)
    if dirs.size == 0:
        return np.zeros((0, n, n))
    if dirs.ndim == 2:
        dirs = dirs[None]
    if dirs.ndim != 3 or dirs.shape[1:] != (n, n) or not np.all(np.isfinite(dirs)):
        raise RobofdiError(f"{where}: field 'parameter_directions' must be a list of finite {n}x{n} matrices")
    return dirs


class EffectivenessDiagnoser:
    """What the estimators of a loss of effectiveness r per actuator declare as diagnosers (Remark 5's two
    readings, :class:`ParameterFaultEKF` and :class:`~robofdi.observers.augmented_error.AugmentedErrorEstimator`):
    the model's inputs and outputs, one residual and one level estimate per actuator (unit 1, named like the
    inputs), each actuator fault isolated by its own row."""

    def _declare_effectiveness(self, model: LinearModel) -> None:
        m = model.m
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(model.input_names)
        self.estimate_components = list(model.input_names)
        self.estimate_modes = ["level"] * m
        self.units = {"residual": ["1"] * m, "estimate": ["1"] * m}

    def signatures(self) -> list:
        from robofdi.decision import Signature

        return [Signature(c, frozenset({c})) for c in self.components]


class ParameterFaultEKF(EffectivenessDiagnoser):
    """Extended Kalman filter for state, uncertain parameters and loss of effectiveness — Jiang & Chowdhury (2005),
    Remark 5 ("if other kinds of uncertainties such as modelling errors are considered (entering the system in
    multiplicative form), the augmented system becomes nonlinear ... an EKF should be used to estimate both the
    state and unknown parameters", after Ljung 1979). The paper gives no equations; the reading here [RECONSTRUCTED]:

        x(k+1) = (A + Σⱼ θⱼ Aⱼ) x(k) + B (I − diag r) u(k) + ω,   y = C x + v,   θ(k+1) = θ(k) + ξ_θ,  r(k+1) = r(k) + ξ_r

    on the augmented state z = col(x, θ, r) (the θ x term is bilinear, hence the EKF), Jacobian
    [[A(θ̂), [Aⱼ x̂]ⱼ, −B diag(u)], [0, I, 0], [0, 0, I]]. ``parameter_directions``: the Aⱼ (n×n each) — the
    modelling error's structure; process_noise (n×n, on x), measurement_noise (p×p), parameter_drift and
    fault_drift (the random-walk variances of θ and r, per sample), P0: initial covariance of z.
    Residual and estimate: r̂ per actuator (the loss of effectiveness, unit 1, named like the inputs); θ̂ is
    ``parameter_estimate``. ``update(y(k), u(k−1))``: predict with u(k−1), correct with y(k).
    """

    def __init__(self, model: LinearModel, parameter_directions, process_noise, measurement_noise,
                 parameter_drift=1e-8, fault_drift=1e-6, P0=None, x0=None):
        where = "ParameterFaultEKF"
        self.model = model = require_discrete(model, where, "diagnosis")
        n, m, p = model.n, model.m, model.p
        dirs = parameter_directions_of(parameter_directions, n, where)
        self.directions, self.n_theta = dirs, dirs.shape[0]
        nz = n + self.n_theta + m
        self.Qx = _positive_definite(process_noise, n, "process_noise", where, "process covariance")
        self.R = _positive_definite(measurement_noise, p, "measurement_noise", where, "measurement covariance")
        drift_t = np.broadcast_to(np.asarray(parameter_drift, dtype=float), (self.n_theta,))
        drift_r = np.broadcast_to(np.asarray(fault_drift, dtype=float), (m,))
        if np.any(drift_t < 0) or np.any(drift_r < 0) or not (np.all(np.isfinite(drift_t)) and np.all(np.isfinite(drift_r))):
            raise RobofdiError(f"{where}: fields 'parameter_drift' and 'fault_drift' must be variances >= 0")
        self.Q = scipy.linalg.block_diag(self.Qx, np.diag(drift_t), np.diag(drift_r))
        self.P0 = np.eye(nz) if P0 is None else _positive_definite(P0, nz, "P0", where, "initial covariance")
        self.x0 = None if x0 is None else check_measurement(x0, n, "x0")
        self._declare_effectiveness(model)
        self.reset()

    def reset(self) -> None:
        self._z = None
        self._P = self.P0.copy()
        self.innovation = np.zeros(self.model.p)

    @property
    def state_estimate(self) -> np.ndarray | None:
        return None if self._z is None else self._z[: self.model.n].copy()

    @property
    def parameter_estimate(self) -> np.ndarray:
        n = self.model.n
        return np.zeros(self.n_theta) if self._z is None else self._z[n:n + self.n_theta].copy()

    @property
    def fault_estimate(self) -> np.ndarray:
        return np.zeros(self.model.m) if self._z is None else self._z[self.model.n + self.n_theta:].copy()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        md = self.model
        n, nt = md.n, self.n_theta
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        H = np.hstack([md.C, np.zeros((md.p, nt + md.m))])
        if self._z is None:
            x = np.linalg.lstsq(md.C, y, rcond=None)[0] if self.x0 is None else self.x0
            self._z = np.concatenate([x, np.zeros(nt + md.m)])
        else:
            x, th, r = self._z[:n], self._z[n:n + nt], self._z[n + nt:]
            A_th = md.A + np.tensordot(th, self.directions, axes=1)
            J = np.eye(n + nt + md.m)
            J[:n, :n] = A_th
            J[:n, n:n + nt] = np.einsum("jab,b->aj", self.directions, x)
            J[:n, n + nt:] = -md.B * u[None, :]
            self._z = np.concatenate([A_th @ x + md.B @ ((1.0 - r) * u), th, r])       # prediction
            self._P = J @ self._P @ J.T + self.Q
        self.innovation = y - H @ self._z
        S = H @ self._P @ H.T + self.R
        K = np.linalg.solve(S, H @ self._P).T
        self._z = self._z + K @ self.innovation
        I_KH = np.eye(self._z.size) - K @ H
        self._P = I_KH @ self._P @ I_KH.T + K @ self.R @ K.T                          # Joseph form
        if not (all_finite(self._z) and all_finite(self._P.ravel())):
            raise RobofdiError("ParameterFaultEKF: the estimate diverged (non-finite); check the model and noises")
        return Residual(self.fault_estimate, self.fault_estimate)
