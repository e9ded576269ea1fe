"""Adaptive fault-estimation observer for discrete-time linear systems — the seed-004 paper's class (F-16 vertical
dynamics example), in robofdi's reconstruction (the paper's equation bodies
are lost in the extraction; this is the standard discrete adaptive fault-estimation observer, NOT its exact text):

    x̂(k+1) = A x̂(k) + B u(k) + E f̂(k) + L (y(k) − C x̂(k))
    f̂(k+1) = f̂(k) + Γ F (y(k+1) − C x̂(k+1))

Error system for a constant fault (e_x = x − x̂, e_f = f − f̂) — the reconstructed Theorem 1's augmented system:

    [e_x; e_f](k+1) = [[A − LC, E], [−ΓFC(A − LC), I − ΓFCE]] [e_x; e_f](k)

which equals (similarity) the augmented-state observer A_a − K_a C_a with A_a = [[A, E], [0, I]], C_a = [C 0],
K_a = [L + EΓF; ΓF]: :func:`adaptive_fe_gains` places its poles (scipy.signal.place_poles) and returns (L, ΓF).
The Lyapunov certificate (P > 0 with A_augᵀ P A_aug − P = −I, scipy's discrete Lyapunov solver) exists iff the
spectral radius is < 1 — the reconstructed condition (6) for fixed gains (Remark 3 fixes one unknown).
Remark 2 (the state at the first step from stacked outputs, then an online fault estimate at that step):
:func:`first_step_estimate`, used by ``AdaptiveFaultEstimator(first_step=N)``.
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.signal

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import LinearModel, require_discrete
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["augmented_error_matrix", "lyapunov_certificate", "adaptive_fe_gains", "adaptive_fe_lmi_gains",
           "first_step_estimate",
           "AdaptiveFaultEstimator", "is_spd"]


def is_spd(M, tol: float = 0.0) -> bool:
    """True when the symmetric part of M is positive definite (smallest eigenvalue > tol)."""
    M = np.asarray(M, dtype=float)
    return M.ndim == 2 and M.shape[0] == M.shape[1] and float(np.linalg.eigvalsh(0.5 * (M + M.T)).min()) > tol


def augmented_error_matrix(A, C, E, L, G) -> np.ndarray:
    """[[A − LC, E], [−G C (A − LC), I − G C E]] with G = ΓF (q×p) — the error system of the reconstruction."""
    A0 = A - L @ C
    q = E.shape[1]
    return np.block([[A0, E], [-G @ C @ A0, np.eye(q) - G @ C @ E]])


def lyapunov_certificate(M: np.ndarray) -> np.ndarray:
    """P = Pᵀ > 0 with Mᵀ P M − P = −I (scipy.linalg.solve_discrete_lyapunov); an error when none exists (ρ(M) ≥ 1)."""
    rho = float(np.max(np.abs(np.linalg.eigvals(M))))
    if not rho < 1.0:
        raise RobofdiError(f"adaptive fault estimation: the augmented error system is not stable (spectral radius "
                           f"{rho:.6g} >= 1): no Lyapunov function, condition (6) fails for these gains")
    P = scipy.linalg.solve_discrete_lyapunov(M.T, np.eye(M.shape[0]))
    return 0.5 * (P + P.T)


def adaptive_fe_gains(model: LinearModel, E, poles: Sequence[complex]) -> tuple[np.ndarray, np.ndarray]:
    """(L, G = ΓF) placing the n + q poles of the augmented error system (see the module docstring)."""
    where = "adaptive_fe_gains"
    model = require_discrete(model, where, "diagnosis")
    A, C = model.A, model.C
    E = _fault_matrix(E, model.n, where)
    n, q = model.n, E.shape[1]
    p = np.array(poles, dtype=complex).ravel()
    if p.shape != (n + q,) or np.any(np.abs(p) >= 1):
        raise RobofdiError(f"{where}: field 'poles' must be {n + q} values inside the unit circle, got {poles!r}")
    Aa = np.block([[A, E], [np.zeros((q, n)), np.eye(q)]])
    Ca = np.hstack([C, np.zeros((C.shape[0], q))])
    try:
        Ka = np.real(scipy.signal.place_poles(Aa.T, Ca.T, p.real if np.all(np.abs(p.imag) < 1e-14) else p)
                     .gain_matrix.T)
    except ValueError as exc:
        raise RobofdiError(f"{where}: the augmented pair ([A E; 0 I], [C 0]) cannot be placed ({exc}); the faults "
                           "must be observable from y (no transmission zero at z = 1)") from None
    G = Ka[n:]
    return Ka[:n] - E @ G, G


def adaptive_fe_lmi_gains(model: LinearModel, E, decay: float = 0.95, solver: str | None = None):
    """(L, G = ΓF, P) from an LMI — the seed-004 paper's Remark 3 in the reconstruction: condition (6),
    (A_a − K_a C_a)ᵀ P (A_a − K_a C_a) < decay² P with P > 0, is bilinear in (P, K_a); the change of variables
    W = P K_a makes it the LMI  [[decay² P, (P A_a − W C_a)ᵀ], [P A_a − W C_a, P]] > 0  (Schur complement; the
    paper's remark instead fixes one of the two matrices, which for a fixed K_a leaves the Lyapunov LMI of
    :func:`lyapunov_certificate`). K_a = P⁻¹W; L = K_a[:n] − E G, G = K_a[n:] (module docstring). Every error mode
    then decays at least as fast as ``decay``ᵏ, and P certifies it. Needs cvxpy (``pip install 'robofdi[lmi]'``)."""
    where = "adaptive_fe_lmi_gains"
    model = require_discrete(model, where, "diagnosis")
    E = _fault_matrix(E, model.n, where)
    if not (isinstance(decay, (int, float)) and 0 < decay <= 1):
        raise RobofdiError(f"{where}: field 'decay' must be a number in (0, 1], got {decay!r}")
    try:
        import cvxpy as cp
    except ImportError:
        raise RobofdiError(f"{where}: the LMI needs cvxpy (pip install 'robofdi[lmi]'); adaptive_fe_gains places "
                           "the poles with scipy only") from None
    n, q, p = model.n, E.shape[1], model.p
    Aa = np.block([[model.A, E], [np.zeros((q, n)), np.eye(q)]])
    Ca = np.hstack([model.C, np.zeros((p, q))])
    P = cp.Variable((n + q, n + q), symmetric=True)
    W = cp.Variable((n + q, p))
    X = P @ Aa - W @ Ca
    rate = 0.995 * decay                 # solved with a small margin, so that the checked rate holds after round-off
    lmi = cp.bmat([[rate ** 2 * P, X.T], [X, P]])
    # a feasibility problem: minimising ‖W‖ pushes the solution onto the rate bound, where it fails the check below
    problem = cp.Problem(cp.Minimize(0),
                         [P >> np.eye(n + q), 0.5 * (lmi + lmi.T) >> 1e-6 * np.eye(2 * (n + q))])
    try:
        with warnings.catch_warnings():          # "solution may be inaccurate": the answer is checked below
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=solver)
    except cp.error.SolverError as exc:
        raise RobofdiError(f"{where}: the LMI solver failed ({exc})") from None
    infeasible = RobofdiError(f"{where}: the LMI is infeasible for decay {decay:g} (solver status {problem.status}): "
                              "no gains give that rate, or the faults are not observable from y")
    if problem.status not in ("optimal", "optimal_inaccurate") or P.value is None:
        raise infeasible
    Pv = 0.5 * (P.value + P.value.T)
    Ka = np.linalg.solve(Pv, W.value)
    Acl = Aa - Ka @ Ca                   # the solver's answer is checked, not trusted ("optimal_inaccurate")
    if not (is_spd(Pv) and float(np.linalg.eigvalsh(Acl.T @ Pv @ Acl - decay ** 2 * Pv).max()) < 0):
        raise infeasible
    G = Ka[n:]
    return Ka[:n] - E @ G, G, Pv


def first_step_estimate(A, B, C, E, ys, us) -> tuple[np.ndarray, np.ndarray]:
    """Remark 2 of the seed-004 paper (reconstructed): x(0) and a constant fault f from the stacked outputs
    y(0) … y(N−1) with the inputs u(0) … u(N−2), by least squares on

        y(j) = C Aʲ x(0) + Σ_{i<j} C A^{j−1−i} (B u(i) + E f),   j = 0 … N−1

    (the observability matrix of the augmented pair ([[A, E], [0, I]], [C 0]) over N steps, required of full column
    rank n + q); returns (x̂(N−1), f̂), the state at the window's last sample propagated with the estimates."""
    A, B, C, E = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C, E))
    ys, us = np.atleast_2d(np.asarray(ys, dtype=float)), np.asarray(us, dtype=float).reshape(-1, B.shape[1])
    n, q, N = A.shape[0], E.shape[1], ys.shape[0]
    if ys.shape[1] != C.shape[0] or us.shape[0] != N - 1:
        raise RobofdiError(f"first_step_estimate: need ys of shape (N, {C.shape[0]}) and us of shape (N − 1, "
                           f"{B.shape[1]}), got {ys.shape} and {us.shape}")
    rows, rhs = [], []
    Aj = np.eye(n)
    drive_u = np.zeros(n)                     # Σ_{i<j} A^{j−1−i} B u(i)
    drive_f = np.zeros((n, q))                # Σ_{i<j} A^{j−1−i} E
    for j in range(N):
        rows.append(np.hstack([C @ Aj, C @ drive_f]))
        rhs.append(ys[j] - C @ drive_u)
        if j < N - 1:
            drive_u = A @ drive_u + B @ us[j]
            drive_f = A @ drive_f + E
            Aj = A @ Aj
    O = np.vstack(rows)
    if np.linalg.matrix_rank(O) < n + q:
        raise RobofdiError(f"first_step_estimate: the stacked observability matrix over N = {N} samples has rank "
                           f"{np.linalg.matrix_rank(O)} < n + q = {n + q} (window too short or (A, C, E) not "
                           f"observable): Remark 2 does not apply")
    sol = np.linalg.lstsq(O, np.concatenate(rhs), rcond=None)[0]
    x0, f = sol[:n], sol[n:]
    return Aj @ x0 + drive_u + drive_f @ f, f


def _fault_matrix(E, n: int, where: str) -> np.ndarray:
    E = np.array(E, dtype=float)
    if E.ndim == 1:
        E = E[:, None]
    if E.ndim != 2 or E.shape[0] != n or E.shape[1] == 0 or not np.all(np.isfinite(E)):
        raise RobofdiError(f"{where}: field 'E' must be a finite {n}xq matrix, got shape {E.shape}")
    if np.linalg.matrix_rank(E) < E.shape[1]:
        raise RobofdiError(f"{where}: E must have full column rank (the paper's assumption), got rank "
                           f"{np.linalg.matrix_rank(E)} for q = {E.shape[1]}")
    return E


class AdaptiveFaultEstimator:
    """Diagnoser protocol: the reconstructed adaptive fault-estimation observer (module docstring).

    model: discrete belief; E (n×q, full column rank; default B: actuator faults named like the inputs); L (n×p);
    F (q×p) and Γ (q×q, symmetric positive definite) — or ``G`` = ΓF directly. The design is rejected when the
    augmented error system's spectral radius is ≥ 1. Residual and estimate: f̂ per fault (the innovation
    y − C x̂ is ``innovation``); a threshold decision on f̂ isolates the fault channel.
    ``spectral_radius`` and ``lyapunov`` (the certificate P) are reported. ``operating_point`` (x₀, u₀): the model is
    a linearisation about the equilibrium (x₀, u₀) — the observer then works on x − x₀, u − u₀, y − C x₀.
    ``first_step`` = N (Remark 2): the first N samples are stacked and x̂, f̂ at the N-th come from
    :func:`first_step_estimate`; before it the estimator reports f̂ = 0 and a zero residual (no estimate yet). None
    (default): x̂ starts from the least-squares C x̂ = y(0) and f̂ = 0.
    """

    def __init__(self, model: LinearModel, L, F=None, Gamma=None, E=None, G=None, fault_names=None,
                 operating_point=None, first_step: int | None = None):
        where = "AdaptiveFaultEstimator"
        if first_step is not None and (isinstance(first_step, bool) or not isinstance(first_step, int)
                                       or first_step < 2):
            raise RobofdiError(f"{where}: field 'first_step' must be None or an integer >= 2, got {first_step!r}")
        self.first_step = first_step
        self.model = model = require_discrete(model, where, "diagnosis")
        n, p = model.n, model.p
        self.E = E = _fault_matrix(model.B if E is None else E, n, where)
        q = E.shape[1]
        L = np.array(L, dtype=float)
        if L.shape != (n, p) or not np.all(np.isfinite(L)):
            raise RobofdiError(f"{where}: field 'L' must be a finite {n}x{p} matrix, got shape {L.shape}")
        if G is None:
            if F is None or Gamma is None:
                raise RobofdiError(f"{where}: give either G = ΓF ({q}x{p}) or both F ({q}x{p}) and Gamma ({q}x{q})")
            F, Gamma = np.array(F, dtype=float), np.array(Gamma, dtype=float)
            if Gamma.ndim == 0:
                Gamma = Gamma * np.eye(q)
            if F.shape != (q, p) or Gamma.shape != (q, q):
                raise RobofdiError(f"{where}: F must be {q}x{p} and Gamma {q}x{q}, got {F.shape} and {Gamma.shape}")
            if not is_spd(Gamma) or not np.allclose(Gamma, Gamma.T):
                raise RobofdiError(f"{where}: field 'Gamma' (learning rate) must be symmetric positive definite")
            G = Gamma @ F
        G = np.array(G, dtype=float)
        if G.shape != (q, p) or not np.all(np.isfinite(G)):
            raise RobofdiError(f"{where}: G = ΓF must be a finite {q}x{p} matrix, got shape {G.shape}")
        self.L, self.G = L, G
        if operating_point is None:
            self.x0, self.u0 = np.zeros(n), np.zeros(model.m)
        else:
            x0, u0 = operating_point
            self.x0 = check_measurement(x0, n, "operating_point x0")
            self.u0 = check_measurement(u0, model.m, "operating_point u0")
        self.y0 = model.C @ self.x0
        self.error_matrix = augmented_error_matrix(model.A, model.C, E, L, G)
        self.spectral_radius = float(np.max(np.abs(np.linalg.eigvals(self.error_matrix))))
        self.lyapunov = lyapunov_certificate(self.error_matrix)
        names = list(model.input_names) if fault_names is None and q == model.m and np.allclose(E, model.B) else \
            (list(fault_names) if fault_names is not None else [f"f{i + 1}" for i in range(q)])
        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(names)
        self.estimate_components = names
        self.estimate_modes = ["level"] * q
        units = list(model.units["u"]) if names == list(model.input_names) else ["1"] * q
        self.units = {"residual": units, "estimate": units}
        self.reset()

    def reset(self) -> None:
        self._x = None
        self._y = None
        self._window: list = []
        self.fault_estimate = np.zeros(self.E.shape[1])
        self.innovation = np.zeros(self.model.p)

    def signatures(self) -> list:
        from robofdi.decision import Signature

        return [Signature(c, frozenset({c})) for c in self.components]

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y(k), u(k−1): x̂(k) from the previous sample, then f̂(k) = f̂(k−1) + ΓF (y(k) − C x̂(k))."""
        md = self.model
        y = check_measurement(y, md.p, "y") - self.y0
        u = check_measurement(u, md.m, "u") - self.u0
        if self._x is None and self.first_step is not None:
            self._window.append((y, u))
            if len(self._window) < self.first_step:
                return Residual(np.zeros(self.E.shape[1]), np.zeros(self.E.shape[1]))
            ys = np.array([w[0] for w in self._window])
            us = np.array([w[1] for w in self._window[1:]])        # u(k−1) arrives with y(k)
            self._x, self.fault_estimate = first_step_estimate(md.A, md.B, md.C, self.E, ys, us)
            self._window = []
            r = y - md.C @ self._x
            self._y, self.innovation = y, r
            return Residual(self.fault_estimate.copy(), self.fault_estimate.copy())
        if self._x is None:
            self._x = np.linalg.lstsq(md.C, y, rcond=None)[0]
        else:
            self._x = md.A @ self._x + md.B @ u + self.E @ self.fault_estimate + self.L @ (self._y - md.C @ self._x)
        r = y - md.C @ self._x
        self.fault_estimate = self.fault_estimate + self.G @ r
        if not (all_finite(r) and all_finite(self.fault_estimate)):
            raise RobofdiError("AdaptiveFaultEstimator: the estimate diverged (non-finite)")
        self._y, self.innovation = y, r
        return Residual(self.fault_estimate.copy(), self.fault_estimate.copy())
