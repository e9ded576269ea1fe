"""Initial values of the ripple model of eq. (50) by spectral analysis of fault-free residuals
(Caccavale & Villani Sec. 7: "suitable initial values ... found via spectral analysis of the residuals")."""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from robofdi import RobofdiError
from robofdi.observers.diagnostic import RippleModel

__all__ = ["ripple_initial_parameters"]


def _sine_cost(c: float, x: np.ndarray, r: np.ndarray):
    """Least squares r ≈ a + s sin(c x) + k cos(c x) at a fixed spatial frequency c; returns (cost, a, b, d)."""
    basis = np.stack([np.ones_like(x), np.sin(c * x), np.cos(c * x)], axis=1)
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    a, sn, co = coef
    return float(np.sum((basis @ coef - r) ** 2)), a, float(np.hypot(sn, co)), float(np.arctan2(co, sn))


def _fit_sine(x: np.ndarray, r: np.ndarray, lo: float, hi: float):
    """r ≈ a + b sin(c x + d) with c refined continuously in [lo, hi] (bounded scalar minimisation of the
    least-squares cost): a grid error δc would shift d by δc·x̄ on a sweep far from x = 0."""
    c = float(minimize_scalar(lambda c: _sine_cost(c, x, r)[0], bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-9 * max(hi, 1.0)}).x)
    _, a, b, d = _sine_cost(c, x, r)
    return a, b, c, d


def ripple_initial_parameters(positions: np.ndarray, velocity_residual: np.ndarray, grid: int = 4096,
                              min_travel: float = 0.05) -> np.ndarray:
    """θ₀ (8n values) from one fault-free run: for each joint that travels at least ``min_travel`` rad,
    resample its velocity-row residual on a uniform grid of its position, take the FFT peak as the spatial
    frequency θ_c, refine it continuously and the amplitude θ_b and phase θ_d by least squares. Offsets θ_a, the torque
    term (θ_e, θ_f, θ_g) and the position rows start at 0 (θ_f = θ_c).

    positions: (N, n) joint positions x̄₁; velocity_residual: (N, n) the rows n+1..2n of a residual in state
    units (rad/s per sample), e.g. the simple residual of eq. (20).
    """
    x = np.asarray(positions, dtype=float)
    r = np.asarray(velocity_residual, dtype=float)
    if x.ndim != 2 or x.shape != r.shape or len(x) < 16:
        raise RobofdiError(
            "ripple_initial_parameters: 'positions' and 'velocity_residual' must be equal (N, n) arrays with N >= 16, "
            f"got {x.shape} and {r.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(r))):
        raise RobofdiError("ripple_initial_parameters: inputs must be finite")
    n = x.shape[1]
    model = RippleModel(n)
    theta = np.zeros(model.p)
    block = theta[n:].reshape(n, 7)
    for i in range(n):
        xi, ri = x[:, i], r[:, i]
        if np.ptp(xi) < min_travel:
            continue
        order = np.argsort(xi, kind="stable")
        xs, rs = xi[order], ri[order]
        keep = np.concatenate([[True], np.diff(xs) > 1e-12])
        xs, rs = xs[keep], rs[keep]
        xg = np.linspace(xs[0], xs[-1], grid)
        rg = np.interp(xg, xs, rs)
        rg = rg - rg.mean()
        spectrum = np.abs(np.fft.rfft(rg * np.hanning(grid)))
        w = 2 * np.pi * np.fft.rfftfreq(grid, d=xg[1] - xg[0])
        k = 2 + int(np.argmax(spectrum[2:]))
        a, b, c, d = _fit_sine(xs, rs, w[k - 1], w[min(k + 1, len(w) - 1)])
        block[i] = (0.0, b, c, d, 0.0, c, 0.0)
    return theta
