"""The Lyapunov weight that makes Guo et al.'s adaptive law output-only for a non-square C — the
Kalman–Yakubovich (SPR) output condition of the digest's correction to eq. (16) (spec B.2 [ERRATUM]):

    F_cᵀ P + P F_c = −Q_lyap < 0,   P > 0,   P T bᵢ = Cᵀ Gᵢ  for every actuator i

(F_c the bank's s-plane observer matrix, T bᵢ the lock direction). With it, γᵢ Gᵢᵀ rᵢ = γᵢ (T bᵢ)ᵀ P eᵢ, and
Theorem 2's V = ½(eᵀPe + φ²/γ) decreases with only the outputs measured. :func:`spr_lyapunov_weight` finds such a P
and returns its Q_lyap for ``LockInPlaceBank(Q_lyap=..., output_form="spr")``.

A necessary condition (derived here, not in the paper): Gᵀ C T B = (T B)ᵀ P T B, which is positive definite when
T B has full column rank, so rank(C T B) must equal rank(T B); the function refuses, naming the ranks, when it does
not. The search itself: P is parametrised on the linear subspace where Nᵀ P T B = 0 (N spans ker C), and the
smallest eigenvalue of P and Q_lyap (P normalised to trace 1) is maximised by a derivative-free search (scipy's
Nelder–Mead, fixed start); the answer is checked, not trusted.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.optimize

from robofdi.errors import RobofdiError
from robofdi.models.linear import LinearModel, require_discrete
from robofdi.observers.uio import uio_design

__all__ = ["spr_lyapunov_weight", "observer_matrix"]


def observer_matrix(F: np.ndarray, dt: float) -> np.ndarray:
    """The s-plane observer matrix F_c = log(F)/dt of a discrete UIO (as ``LockInPlaceBank`` builds its P)."""
    F = np.asarray(F, dtype=float)
    if np.allclose(F, np.diag(np.diag(F))):
        return np.diag(np.log(np.diag(F))) / dt
    return scipy.linalg.logm(F).real / dt


def _symmetric_basis(n: int) -> np.ndarray:
    basis = []
    for i in range(n):
        for j in range(i, n):
            S = np.zeros((n, n))
            S[i, j] = S[j, i] = 1.0
            basis.append(S)
    return np.array(basis)


def spr_lyapunov_weight(model: LinearModel, poles: Sequence[complex], E=None, margin: float = 1e-3,
                        max_iterations: int = 20000) -> np.ndarray:
    """Q_lyap (n×n, positive definite, scaled to a smallest eigenvalue of 1) whose Lyapunov P meets
    P T bᵢ = Cᵀ Gᵢ for every actuator (module docstring), for the bank ``LockInPlaceBank(model, poles, E)``.
    ``margin``: the smallest eigenvalue P / trace(P) and Q_lyap must reach (the search stops there). Raises
    :class:`RobofdiError` when the rank condition fails or no P is found within ``max_iterations``."""
    where = "spr_lyapunov_weight"
    model = require_discrete(model, where, "diagnosis")
    d = uio_design(model, poles, E)
    n, C = model.n, model.C
    Fc = observer_matrix(d.F, model.dt)
    TB = d.T @ model.B
    scale = max(np.linalg.norm(TB), 1e-300)
    r_tb = np.linalg.matrix_rank(TB, tol=1e-9 * scale)
    r_ctb = np.linalg.matrix_rank(C @ TB, tol=1e-9 * scale * max(np.linalg.norm(C), 1e-300))
    if r_ctb < r_tb:
        raise RobofdiError(f"{where}: rank(C T B) = {r_ctb} < rank(T B) = {r_tb}: no P > 0 meets P T B = Cᵀ G "
                           "(Gᵀ C T B = (T B)ᵀ P T B would have full rank); the SPR output form does not exist for "
                           "these actuators and outputs")
    N = scipy.linalg.null_space(C)
    basis = _symmetric_basis(n)
    if N.shape[1] == 0:
        free = np.eye(len(basis))                               # square C: every P qualifies
    else:
        free = scipy.linalg.null_space(np.array([(N.T @ S @ TB).ravel() for S in basis]).T)
    if free.shape[1] == 0:
        raise RobofdiError(f"{where}: P T bᵢ ∈ range(Cᵀ) leaves no symmetric P (the constraints fix P = 0)")

    def P_of(a):
        P = np.tensordot(free @ a, basis, axes=1)
        return P / np.trace(P)

    def worst(a):
        tr = np.trace(np.tensordot(free @ a, basis, axes=1))
        if not abs(tr) > 1e-12:
            return 1e3
        P = P_of(a)
        return -min(np.linalg.eigvalsh(P).min(), np.linalg.eigvalsh(-(Fc.T @ P + P @ Fc)).min())

    # start: the default bank's P (Q_lyap = I) projected onto the constraint subspace
    P0 = scipy.linalg.solve_continuous_lyapunov(Fc.T, -np.eye(n))
    coords = np.array([P0[i, j] for i in range(n) for j in range(i, n)])
    a0 = np.linalg.lstsq(free, coords, rcond=None)[0]
    found = []

    def enough(intermediate_result):
        if -intermediate_result.fun >= margin:
            found.append(intermediate_result.x)
            raise StopIteration

    best = scipy.optimize.minimize(worst, a0, method="Nelder-Mead", callback=enough,
                                   options={"maxiter": max_iterations, "xatol": 1e-12, "fatol": 1e-14})
    P = P_of(found[0] if found else best.x)
    Q = -(Fc.T @ P + P @ Fc)
    Q = 0.5 * (Q + Q.T)
    lo = min(np.linalg.eigvalsh(P).min(), np.linalg.eigvalsh(Q).min())
    miss = np.linalg.norm(N.T @ P @ TB) / max(np.linalg.norm(P @ TB), 1e-300) if N.shape[1] else 0.0
    if not (lo >= margin and miss < 1e-9):
        raise RobofdiError(f"{where}: no P found with P > 0, −(F_cᵀP + PF_c) > 0 and P T bᵢ ∈ range(Cᵀ) (best "
                           f"smallest eigenvalue {lo:.3g}, margin {margin:g}); the SPR output form may not exist here")
    return Q / np.linalg.eigvalsh(Q).min()
