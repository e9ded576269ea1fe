"""Compiled kernels of the arm simulator's hot path: one control period (torque saturation, the honest-harness
effects of every physics sub-step, MuJoCo's ``mj_step`` through its C API) and the sensor model, on preallocated
arrays (no allocation, no Python per joint or per sub-step).

Every kernel is plain Python on scalars, compiled by :func:`robofdi.jit.kernel` (numba, ``cache=True``: compiled
once per source change and kept on disk beside this file — numba's ``NUMBA_CACHE_DIR`` moves it —, so later
processes load it in milliseconds; ``fastmath`` off). The pure-Python path is :mod:`robofdi.jit`'s:
``NUMBA_DISABLE_JIT=1`` in the environment, or :func:`robofdi.jit.interpreted` for a block, runs every kernel as
its Python function; without numba installed, kernels are their Python functions. Both paths give the same bits:
the arithmetic is IEEE operations in a fixed order, and ``math.sin``, ``exp`` and ``tanh`` are the C library's in
both. The plant is defined by these kernels, not by a library's vector code: NumPy's own SIMD ``tanh`` and a BLAS
product (whose summation order is the BLAS build's and the CPU's) would make the record depend on the machine.
:meth:`ArmSimulator.disturbance` is the NumPy formulation of the same effects; it agrees to rounding.
``mj_step`` runs inside :func:`control_tick` through :mod:`robofdi.sims.capi` (the C function the bindings call,
so the same bits as ``mujoco.mj_step``).
"""
from __future__ import annotations

import math

import numpy as np

from robofdi.jit import COMPILED as JIT, kernel
from robofdi.sims.capi import mj_step_at

__all__ = ["JIT", "TICK_FLOATS", "TICK_INTS", "apply_torque", "physics_forces", "pack", "control_tick", "measure"]


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
def physics_forces(qpos, qvel, qadr, dofs, tau, index, freq, phase, amp, load, s, ripple_on, excess, inv_v, inv_eps,
                   stribeck_on, qfrc):  # pragma: no cover - compiled
    """qfrc[dofs] = −δ of :meth:`ArmSimulator.disturbance` at the data's current state, for one physics step:
    δ_i = Σ_k amp[k n + i] s[k n + i] + τ_i c_i s[K n + i] (the ripple, s[j] = sin(freq[j] q[index[j]] + phase[j]),
    K = amp.size / n) + (F_s − F_c)_i exp(−(q̇_i/v_s)²) tanh(q̇_i/ε_i) (Stribeck), each term only when switched on;
    q = qpos[qadr], q̇ = qvel[dofs]. The sums run in k's order, ``math`` gives sin, exp and tanh (the C library's)."""
    n = dofs.size
    if ripple_on:
        for j in range(index.size):
            s[j] = math.sin(freq[j] * qpos[qadr[index[j]]] + phase[j])
    split = amp.size
    for i in range(n):
        d = 0.0
        if ripple_on:
            r = 0.0
            for k in range(0, split, n):
                r = r + amp[k + i] * s[k + i]
            d = r + tau[i] * load[i] * s[split + i]
        if stribeck_on:
            v = qvel[dofs[i]]
            x = v * inv_v
            d = d + excess[i] * math.exp(-(x * x)) * math.tanh(v * inv_eps[i])
        qfrc[dofs[i]] = -d


#: the parameters of one control period, packed into one float and one integer buffer (:func:`pack`), so that a
#: tick hands the kernel a few arrays instead of twenty (numba's dispatch costs ≈ 0.06 µs an array argument)
TICK_FLOATS = ("lo", "hi", "inv_gain", "amp", "freq", "phase", "load", "excess", "inv_eps", "inv_v", "other_ctrl",
               "resolution", "inv_resolution", "pos_noise", "vel_noise", "sines")
TICK_INTS = ("qadr", "dofs", "act", "index", "other_act")


def pack(names: tuple[str, ...], values: dict, dtype) -> tuple[np.ndarray, np.ndarray, dict]:
    """(buffer, offsets, views): ``values[name]`` (flattened) one after the other in the order of ``names``; the
    offsets (len(names) + 1: name i is ``buffer[offsets[i]:offsets[i + 1]]``); a view of the buffer per name, in
    the value's shape — write into a view (``view[...] = x``) to change what the kernel reads."""
    flat = [np.asarray(values[name], dtype=dtype).ravel() for name in names]
    offsets = np.concatenate([[0], np.cumsum([a.size for a in flat])]).astype(np.int64)
    buffer = np.concatenate(flat) if flat else np.zeros(0, dtype)
    views = {name: buffer[offsets[i]:offsets[i + 1]].reshape(np.shape(values[name]))
             for i, name in enumerate(names)}
    return buffer, offsets, views


@kernel
def control_tick(step, model, data, substeps, ripple_on, stribeck_on, u, F, fo, I, io, qpos, qvel, qfrc, ctrl, tau, zq,
                 zv, y):  # pragma: no cover - compiled
    """One control period: u saturated into tau and ctrl (:func:`apply_torque`), the other actuators' ctrl held,
    ``substeps`` × (:func:`physics_forces`, ``mj_step`` at address ``step`` on the model and data at addresses
    ``model``, ``data``), then the sensors read into y (:func:`measure`). The parameters are :data:`TICK_FLOATS`
    in F and :data:`TICK_INTS` in I (offsets fo, io; :func:`pack`). 0: u not finite (nothing written); 1: stepped
    and measured; 2: stepped, the state (qpos, qvel) is no longer finite (nothing measured)."""
    lo, hi, inv_gain, amp = F[fo[0]:fo[1]], F[fo[1]:fo[2]], F[fo[2]:fo[3]], F[fo[3]:fo[4]]
    freq, phase, load, excess = F[fo[4]:fo[5]], F[fo[5]:fo[6]], F[fo[6]:fo[7]], F[fo[7]:fo[8]]
    inv_eps, inv_v, other_ctrl, resolution = F[fo[8]:fo[9]], F[fo[9]], F[fo[10]:fo[11]], F[fo[11]:fo[12]]
    inv_resolution, pos_noise, vel_noise, s = F[fo[12]:fo[13]], F[fo[13]:fo[14]], F[fo[14]:fo[15]], F[fo[15]:fo[16]]
    qadr, dofs, act, index, other_act = I[io[0]:io[1]], I[io[1]:io[2]], I[io[2]:io[3]], I[io[3]:io[4]], I[io[4]:io[5]]
    if not apply_torque(u, lo, hi, inv_gain, act, ctrl, tau):
        return 0
    for i in range(other_act.size):
        ctrl[other_act[i]] = other_ctrl[i]
    for _ in range(substeps):
        if ripple_on or stribeck_on:
            physics_forces(qpos, qvel, qadr, dofs, tau, index, freq, phase, amp, load, s, ripple_on, excess, inv_v,
                           inv_eps, stribeck_on, qfrc)
        mj_step_at(step, model, data)
    for i in range(qpos.size):
        if not math.isfinite(qpos[i]):
            return 2
    for i in range(qvel.size):
        if not math.isfinite(qvel[i]):
            return 2
    measure(qpos, qvel, qadr, dofs, resolution, inv_resolution, pos_noise, zq, vel_noise, zv, y)
    return 1


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
