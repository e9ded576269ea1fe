"""The sub-stepping kernel of the sliding-mode observers (:mod:`robofdi.observers.sliding_mode`).

One call integrates one diagnosis interval [t_{k−1}, t_k] of length T with ``nsub`` explicit-Euler steps of
h = T / nsub (Saif & Xiong need h far below the switching and filter time scales: 1e-8 s steps against 1e-5 s
filters for their Example 2). The observer it integrates is the general form every observer of the chapter fits::

    x̂' = M(s) x̂ + c(s) + Σ_j V[:, j] ψ(ē_j)                      (eqs. 5/7, 16/18, 38, 51, 54, 66, 70, 80, 82)
    ē_j = Wy_j · y(s) − Cx_j · x̂                                (output stages: ē₁ = y − x̂₁, W C e, y − z)
    ē_j = g_j(s) · z_{src_j}                                       (cascade stages: ē_j = (λ_{j−1} ψ(ē_{j−1}))_eq)
    τ_j z_j' + z_j = λ_j ψ(ē_j)                                    (the equivalent-control estimate, first-order LPF)

s ∈ [0, T] is the time inside the interval; y(s) is a cubic per channel (coefficients ``ycoef``); M, c and g are
interpolated linearly between their values at the interval's ends (they depend on the measured y only); ψ is the
sign, the saturation clip(ē/ε, −1, 1), or the unit vector ē/‖ē‖ over the output stages (eq. 17). A stage that is
not ``active`` (anti-peaking: "we reach the manifold one by one") has ē_j = 0 and injects nothing, while its
filter keeps running on its source.

It returns the interval mean of λ_j ψ(ē_j) (a moving average over T: a second equivalent-control estimate), the
largest |z_j| inside the interval (for max-hold peak detection) and the interval mean of ē_j (for a sliding
detector: chattering averages out; 0 for a stage that is not active). Compiled with numba when it is installed (≈100×
faster than the interpreted loop; benchmarks/smo_update.py), interpreted otherwise.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["integrate_interval", "COMPILED"]

SIGN, SAT, UNIT = 0, 1, 2


def _integrate(xh, z, nsub, h, ycoef, M0, M1, c0, c1, V, Wy, Cx, kind, src, g0, g1, lam, active, sw, eps, alpha,
               mean_out, peak_out, emean_out):
    n = xh.shape[0]
    S = V.shape[1]
    p = ycoef.shape[0]
    T = nsub * h
    e = np.zeros(S)
    psi = np.zeros(S)
    dx = np.zeros(n)
    yv = np.zeros(p)
    for j in range(S):
        mean_out[j] = 0.0
        emean_out[j] = 0.0
        peak_out[j] = abs(z[j])
    for k in range(nsub):
        s = k * h
        w = s / T
        for c in range(p):
            yv[c] = ycoef[c, 0] + s * (ycoef[c, 1] + s * (ycoef[c, 2] + s * ycoef[c, 3]))
        # stage errors: output stages first, cascade stages read the filters of the previous step
        norm2 = 0.0
        for j in range(S):
            if active[j] == 0:
                e[j] = 0.0
                continue
            if kind[j] == 0:
                v = 0.0
                for c in range(p):
                    v += Wy[j, c] * yv[c]
                for i in range(n):
                    v -= Cx[j, i] * xh[i]
                e[j] = v
                norm2 += v * v
            else:
                e[j] = (g0[j] + (g1[j] - g0[j]) * w) * z[src[j]]
        for j in range(S):
            v = e[j]
            emean_out[j] += v
            if sw == 0 or (sw == 2 and kind[j] == 1):
                psi[j] = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
            elif sw == 1:
                q = v / eps
                psi[j] = 1.0 if q > 1.0 else (-1.0 if q < -1.0 else q)
            else:
                psi[j] = v / math.sqrt(norm2) if norm2 > 0.0 else 0.0
        for i in range(n):
            acc = c0[i] + (c1[i] - c0[i]) * w
            for m in range(n):
                acc += (M0[i, m] + (M1[i, m] - M0[i, m]) * w) * xh[m]
            for j in range(S):
                acc += V[i, j] * psi[j]
            dx[i] = acc
        for i in range(n):
            xh[i] += h * dx[i]
        for j in range(S):
            u = lam[j] * psi[j]
            mean_out[j] += u
            z[j] += alpha[j] * (u - z[j])
            a = abs(z[j])
            if a > peak_out[j]:
                peak_out[j] = a
    for j in range(S):
        mean_out[j] /= nsub
        emean_out[j] /= nsub


try:                                           # pragma: no cover - which branch runs depends on the install
    import numba

    _kernel = numba.njit(cache=True, nogil=True)(_integrate)
    COMPILED = True
except ImportError:                            # pragma: no cover
    _kernel = _integrate
    COMPILED = False


def integrate_interval(xh, z, nsub, h, ycoef, M0, M1, c0, c1, V, Wy, Cx, kind, src, g0, g1, lam, active, sw, eps,
                       alpha):
    """Advance (x̂, z) in place over one interval; returns (mean of λψ over the interval, max |z| inside it, mean of
    ē over it)."""
    S = V.shape[1]
    mean_out, peak_out, emean_out = np.zeros(S), np.zeros(S), np.zeros(S)
    _kernel(xh, z, int(nsub), float(h), ycoef, M0, M1, c0, c1, V, Wy, Cx, kind, src, g0, g1, lam, active, int(sw),
            float(eps), alpha, mean_out, peak_out, emean_out)
    return mean_out, peak_out, emean_out
