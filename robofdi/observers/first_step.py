"""Remark 2 of the seed-004 paper, its Lipschitz-output variant (reconstructed: the remark's symbols are lost; the
text reads "when the output satisfies the Lipschitz condition, define …; then one can get …; then the fault
estimation is …"). The linear case is :func:`robofdi.observers.adaptive.first_step_estimate`.

Plant: x(k+1) = A x(k) + B u(k) + E f, y(k) = C x(k) + g(x(k)), g globally Lipschitz, ‖g(a) − g(b)‖ ≤ γ ‖a − b‖.
With θ = col(x(0), f) the states of the window are affine in θ, x(j) = M_j θ + c_j (c_j the input's drive), so the
stacked outputs read Y = O θ + C c + G(θ), O = [C M_j]_j the observability matrix of the augmented pair (full column
rank n + q). The estimate is the fixed point

    θ = O⁺ (Y − C c − G(θ)),   G(θ) = col(g(M_j θ + c_j))_j,

a contraction with factor κ = γ ‖O⁺‖₂ ‖M‖₂ (M = [M_j]_j) when κ < 1 — the condition this reading of "the output
satisfies the Lipschitz condition" needs; iterated from the linear estimate (g ignored) until the step is below
``tol``. Noise-free, the fixed point is the true θ.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["first_step_estimate_lipschitz", "window_maps"]


def window_maps(A, B, C, E, us, N: int) -> tuple[np.ndarray, np.ndarray]:
    """(M, c): x(j) = M[j] θ + c[j] for j = 0 … N−1, θ = col(x(0), f), with the inputs u(0) … u(N−2)."""
    A, B, C, E = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C, E))
    n, q = A.shape[0], E.shape[1]
    us = np.asarray(us, dtype=float).reshape(-1, B.shape[1])
    M, c = np.zeros((N, n, n + q)), np.zeros((N, n))
    M[0, :, :n] = np.eye(n)
    for j in range(1, N):
        M[j] = A @ M[j - 1]
        M[j, :, n:] += E
        c[j] = A @ c[j - 1] + B @ us[j - 1]
    return M, c


def first_step_estimate_lipschitz(A, B, C, E, ys, us, g: Callable[[np.ndarray], np.ndarray], lipschitz: float,
                                  tol: float = 1e-12, max_iterations: int = 200) -> tuple[np.ndarray, np.ndarray, int]:
    """(x̂(N−1), f̂, iterations) from the stacked outputs y(0) … y(N−1) = C x + g(x) and inputs u(0) … u(N−2)
    (module docstring). ``g``: the output nonlinearity, x (n,) → (p,); ``lipschitz``: its constant γ. Refuses,
    naming the factor, when κ = γ ‖O⁺‖ ‖M‖ ≥ 1 (no contraction: the remark's condition fails for this window)."""
    where = "first_step_estimate_lipschitz"
    A, B, C, E = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, B, C, E))
    ys = np.atleast_2d(np.asarray(ys, dtype=float))
    n, q, p, N = A.shape[0], E.shape[1], C.shape[0], ys.shape[0]
    us = np.asarray(us, dtype=float).reshape(-1, B.shape[1])
    if ys.shape[1] != p or us.shape[0] != N - 1:
        raise RobofdiError(f"{where}: need ys of shape (N, {p}) and us of shape (N − 1, {B.shape[1]}), got "
                           f"{ys.shape} and {us.shape}")
    if isinstance(lipschitz, bool) or not isinstance(lipschitz, (int, float)) or not (
            np.isfinite(lipschitz) and lipschitz >= 0):
        raise RobofdiError(f"{where}: field 'lipschitz' must be a constant >= 0, got {lipschitz!r}")
    M, c = window_maps(A, B, C, E, us, N)
    O = np.vstack([C @ Mj for Mj in M])
    if np.linalg.matrix_rank(O) < n + q:
        raise RobofdiError(f"{where}: the stacked observability matrix over N = {N} samples has rank "
                           f"{np.linalg.matrix_rank(O)} < n + q = {n + q}: Remark 2 does not apply")
    O_pinv = np.linalg.pinv(O)
    kappa = lipschitz * np.linalg.norm(O_pinv, 2) * np.linalg.norm(M.reshape(N * n, n + q), 2)
    if kappa >= 1.0:
        raise RobofdiError(f"{where}: contraction factor γ ‖O⁺‖ ‖M‖ = {kappa:.3g} >= 1 for γ = {lipschitz:g}: the "
                           "fixed point is not guaranteed (a longer window or a smaller γ)")
    rhs = (ys - c @ C.T).ravel()
    theta = O_pinv @ rhs                                        # the linear estimate: g ignored
    iterations = 0
    while iterations < max_iterations:
        iterations += 1
        G = np.concatenate([np.asarray(g(M[j] @ theta + c[j]), dtype=float).reshape(p) for j in range(N)])
        step = O_pinv @ (rhs - G) - theta
        theta = theta + step
        if np.linalg.norm(step) <= tol * max(1.0, np.linalg.norm(theta)):
            return M[-1] @ theta + c[-1], theta[n:], iterations
    raise RobofdiError(f"{where}: no convergence in {max_iterations} iterations (κ = {kappa:.3g})")
