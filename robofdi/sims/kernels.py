"""Compiled kernels of the arm simulator's hot path: the honest-harness effects of one physics sub-step and the
sensor model, on preallocated arrays (no allocation, no Python per joint).

Every kernel is plain Python on scalars, compiled by :func:`robofdi.jit.kernel` (numba, ``cache=True``: compiled
once per source change and kept on disk beside this file — numba's ``NUMBA_CACHE_DIR`` moves it —, so later
processes load it in milliseconds; ``fastmath`` off, so every operation is the IEEE operation the NumPy expression
did and the record is bit-identical). The pure-Python path is :mod:`robofdi.jit`'s: ``NUMBA_DISABLE_JIT=1`` in the
environment, or :func:`robofdi.jit.interpreted` for a block, runs every kernel as its Python function (the same
results, slower); without numba installed, kernels are their Python functions. Two NumPy calls stay outside the
kernels because NumPy's implementation differs from the C library's in the last bit: ``np.tanh`` (NumPy's SIMD
tanh) and the ripple's ``A @ s`` (a BLAS product, whose summation order is the library's). ``math.sin`` and
``math.exp`` are the C library's, as NumPy's float64 ``sin``/``exp`` are on x86-64 without AVX-512; on AVX-512
CPUs NumPy's ``exp`` is its own (the last bit differs for some arguments), so there the NumPy formulation agrees
with the kernels to rounding, while the compiled and the pure-Python paths still agree bit for bit.
"""
from __future__ import annotations

import math

import numpy as np

from robofdi.jit import COMPILED as JIT, kernel

__all__ = ["JIT", "apply_torque", "ripple_arguments", "disturbance", "measure"]


@kernel
def apply_torque(u, lo, hi, inv_gain, act, ctrl, tau):  # pragma: no cover - compiled
    """tau = u saturated to [lo, hi] (np.minimum(np.maximum(u, lo), hi)); ctrl[act] = tau · inv_gain (inv_gain of
    length 0: ctrl = tau). False when u is not finite (nothing written then)."""
    n = u.size
    for i in range(n):
        if not math.isfinite(u[i]):
            return False
    for i in range(n):
        x = u[i]
        x = x if x >= lo[i] else lo[i]          # np.maximum, finite operands
        x = x if x <= hi[i] else hi[i]          # np.minimum
        tau[i] = x
        ctrl[act[i]] = x * inv_gain[i] if inv_gain.size else x
    return True


@kernel
def ripple_arguments(qpos, qvel, qadr, dofs, index, freq, phase, inv_eps, s, t):  # pragma: no cover - compiled
    """s[j] = sin(freq[j] q[index[j]] + phase[j]) (every ripple term) and t[i] = q̇_i / ε_i (the Stribeck tanh's
    argument; NumPy takes its tanh), q = qpos[qadr], q̇ = qvel[dofs]."""
    for j in range(index.size):
        s[j] = math.sin(freq[j] * qpos[qadr[index[j]]] + phase[j])
    for i in range(t.size):
        t[i] = qvel[dofs[i]] * inv_eps[i]


@kernel
def disturbance(qvel, dofs, tau, s, split, load, ripple, ripple_on, excess, inv_v, tanh_t, stribeck_on,
                qfrc):  # pragma: no cover - compiled
    """qfrc[dofs] = −δ of :meth:`ArmSimulator.disturbance`: δ_i = (A s)_i + τ_i c_i s[split + i] (``ripple`` = A s)
    + (F_s − F_c)_i exp(−(q̇_i/v_s)²) tanh(q̇_i/ε_i) (``tanh_t``), each term only when switched on."""
    for i in range(dofs.size):
        d = 0.0
        if ripple_on:
            d = ripple[i] + tau[i] * load[i] * s[split + i]
        if stribeck_on:
            x = qvel[dofs[i]] * inv_v
            d = d + excess[i] * math.exp(-(x * x)) * tanh_t[i]
        qfrc[dofs[i]] = -d


@kernel
def measure(qpos, qvel, qadr, dofs, resolution, inv_resolution, pos_noise, zq, vel_noise, zv, out):  # pragma: no cover
    """out = [q; q̇] as the sensors read them: q quantised to ``resolution`` where it is > 0 (round half to even),
    plus pos_noise · zq and vel_noise · zv (each only when its draws ``zq`` / ``zv`` are not empty)."""
    n = qadr.size
    for i in range(n):
        q = qpos[qadr[i]]
        if resolution[i] > 0:
            q = np.rint(q * inv_resolution[i]) * resolution[i]
        if zq.size:
            q = q + pos_noise[i] * zq[i]
        out[i] = q
        v = qvel[dofs[i]]
        if zv.size:
            v = v + vel_noise[i] * zv[i]
        out[n + i] = v
