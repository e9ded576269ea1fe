"""Multiple-model effector FDI with adaptive stuck-position observers and the hybrid settling-time supervisor —
Bošković & Mehra, "Failure detection, identification and reconfiguration in flight control", §5: eqs. (44)–(49)
(the simplified observers of §5.4) and the Decision-Making Subsystem of Fig. 10.

Pure design functions: :func:`settling_time` (closed form of eq. (49)), :func:`design_gains` (its inverse),
:func:`switching_index` (eq. (44)), :func:`foh_discretize` (exact sampling of a linear observer whose measured
input is interpolated linearly between samples). :class:`HybridEffectorFDI` is the diagnoser.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import expm

from robofdi.decision.isolation import Signature
from robofdi.errors import RobofdiError
from robofdi.ftc.idcl import check_isolable
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["settling_time", "design_gains", "switching_index", "foh_discretize", "HybridEffectorFDI"]


def settling_time(lam: float, gamma: float, b) -> float:
    """2 % settling time [s] of φ̈ + λφ̇ + γ bᵀb φ = 0 — eq. (49): 8/λ when underdamped (γbᵀb > λ²/4), else
    4/|−λ/2 + √(λ²/4 − γbᵀb)| (the slow real root)."""
    if not (np.isfinite(lam) and lam > 0 and np.isfinite(gamma) and gamma > 0):
        raise RobofdiError(f"settling_time: fields 'lam' and 'gamma' must be > 0, got {lam!r}, {gamma!r}")
    bb = float(np.dot(b, b))
    if bb <= 0:
        raise RobofdiError("settling_time: field 'b' must be a non-zero effector column")
    k = gamma * bb
    if k > lam**2 / 4:
        return 8.0 / lam
    return 4.0 / abs(-lam / 2 + np.sqrt(lam**2 / 4 - k))


def design_gains(tau_s: float, zeta: float, b) -> tuple[float, float]:
    """(λ, γ) giving settling time ``tau_s`` [s] and damping ``zeta`` ∈ (0, 1) in eq. (49): λ = 8/τ_s,
    γ = (λ/2ζ)²/bᵀb."""
    if not (np.isfinite(tau_s) and tau_s > 0) or not (0 < zeta < 1):
        raise RobofdiError(f"design_gains: need tau_s > 0 s and zeta in (0, 1), got {tau_s!r}, {zeta!r}")
    lam = 8.0 / tau_s
    return lam, (lam / (2 * zeta)) ** 2 / float(np.dot(b, b))


def switching_index(e_sq: np.ndarray, integral: np.ndarray, t: float, c: Sequence[float]) -> np.ndarray:
    """Iⱼ(t) = c₁‖êⱼ(t)‖² + c₂/(t + c₃) ∫_{t₀}^t ‖êⱼ‖² dτ — eq. (44) (the chapter's form, not Guo et al.'s)."""
    c1, c2, c3 = c
    return c1 * np.asarray(e_sq) + c2 / (t + c3) * np.asarray(integral)


def foh_discretize(M, Nx, Ng, dt: float):
    """(Φ, Γ₀, Γ₁, Γ_g) with z(k) = Φ z(k−1) + Γ₀ w(k−1) + Γ₁ (w(k) − w(k−1)) + Γ_g g for ż = M z + N_x w + N_g g,
    w linear between samples (first-order hold of a measurement) and g held (zero-order hold of an input)."""
    M, Nx, Ng = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (M, Nx, Ng))
    nz, nw, ng = M.shape[0], Nx.shape[1], Ng.shape[1]
    N = nz + 2 * nw + ng
    big = np.zeros((N, N))
    big[:nz, :nz], big[:nz, nz:nz + nw], big[:nz, nz + 2 * nw:] = M, Nx, Ng
    big[nz:nz + nw, nz + nw:nz + 2 * nw] = np.eye(nw)
    E = expm(big * dt)
    return E[:nz, :nz], E[:nz, nz:nz + nw], E[:nz, nz + nw:nz + 2 * nw] / dt, E[:nz, nz + 2 * nw:]


class HybridEffectorFDI:
    """Diagnoser: the hybrid FDI-ARC bank of §5.4 for lock-in-place / hard-over effector failures.

    Observers on the x₂ subsystem (measured state x, commanded u_c): the current nominal
    x̂̇₀ = −λ(x̂₀ − x₂) + A x + B_{∖F} u_c + Σ_{k∈F} b_k û_k (eq. (45)) and, for each effector i ∉ F,
    x̂̇ᵢ = −λ(x̂ᵢ − x₂) + A x + B_{∖(F∪i)} u_c + Σ_F b_k û_k + bᵢ ûᵢ (46) with ûᵢ̇ = Proj{−γ (x̂ᵢ − x₂)ᵀ bᵢ} (47),
    (38). Every ``t_s`` the supervisor evaluates Iⱼ (44): in MONITOR, when I₀ − minᵢ Iᵢ > ``delta`` it switches to
    i* = argmin (IDENTIFY: the accommodation then uses the adaptive û_{i*}, eq. (43)); after ``tau_s[i*]`` it
    freezes û_{i*}, adds i* to F, resets every observer state to x and the integrals of (44) (COMMIT), and
    monitors again (Step 4 of §5.4; the digest's state machine). Failures must be at least τ_s apart. The
    supervisor waits ``holdoff`` (default 8/λ, the observers' settling time) after every (re)start, and never
    isolates more than m − p effectors (the allocation needs p of them).

    Residual: [I₀, I_{effector}…] (the switching indices, 0 for committed effectors) then one status per
    effector (0 healthy, 1 identifying, 2 committed). Estimate: û per effector [rad] (frozen for F).
    ``tau_s`` default per effector: 8/λ (eq. (49)) + its full travel at the rate limit (a hard-over still moving
    when the estimate froze would be mis-identified). ``x2_index``: the entries of y that are x₂.
    """

    def __init__(self, A2, B2, effectors: Sequence[str], states: Sequence[str], x2_index: Sequence[int], dt: float,
                 u_min, u_max, rate_limit=None, lam: float = 40.0, gamma: float = 5000.0,
                 c: Sequence[float] = (1.0, 10.0, 100.0), t_s: float = 0.05, delta: float = 1e-5, tau_s=None,
                 holdoff: float | None = None):
        self.A2 = np.asarray(A2, dtype=float)
        self.B2 = np.asarray(B2, dtype=float)
        p, m = self.B2.shape
        self.effectors, self.measurements = list(effectors), list(states)
        n = len(self.measurements)
        if self.A2.shape != (p, n) or len(self.effectors) != m:
            raise RobofdiError(f"HybridEffectorFDI: fields 'A2' / 'B2' / 'effectors' must be ({p}, {n}) / (p, m) / m "
                               f"names, got {self.A2.shape} / {self.B2.shape} / {len(self.effectors)}")
        check_isolable(self.B2, self.effectors)
        self.x2 = np.asarray(x2_index, dtype=int)
        if self.x2.shape != (p,):
            raise RobofdiError(f"HybridEffectorFDI: field 'x2_index' must give the {p} entries of y that are x₂")
        for name, v in (("dt", dt), ("lam", lam), ("t_s", t_s), ("delta", delta)):
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"HybridEffectorFDI: field {name!r} must be > 0, got {v!r}")
        if len(c) != 3 or not all(np.isfinite(v) and v > 0 for v in c):
            raise RobofdiError(f"HybridEffectorFDI: field 'c' must be three constants c₁, c₂, c₃ > 0, got {c}")
        self.gamma = np.broadcast_to(np.asarray(gamma, dtype=float), (m,)).copy()
        if not np.all(np.isfinite(self.gamma) & (self.gamma > 0)):
            raise RobofdiError(f"HybridEffectorFDI: field 'gamma' must be > 0 (per effector or one value), got {gamma!r}")
        self.u_min = np.broadcast_to(np.asarray(u_min, float), (m,)).copy()
        self.u_max = np.broadcast_to(np.asarray(u_max, float), (m,)).copy()
        if np.any(self.u_min >= self.u_max):
            raise RobofdiError("HybridEffectorFDI: fields 'u_min' < 'u_max' per effector")
        self.dt, self.lam, self.c, self.delta = float(dt), float(lam), tuple(map(float, c)), float(delta)
        self.every = max(1, int(round(t_s / dt)))
        self.holdoff = 8.0 / lam if holdoff is None else float(holdoff)
        if not (np.isfinite(self.holdoff) and self.holdoff >= 0):
            raise RobofdiError(f"HybridEffectorFDI: field 'holdoff' must be a time >= 0 s, got {holdoff!r}")
        if tau_s is None:
            travel = 0.0 if rate_limit is None else (self.u_max - self.u_min) / np.asarray(rate_limit, float)
            tau_s = 8.0 / lam + travel
        self.tau_s = np.broadcast_to(np.asarray(tau_s, dtype=float), (m,)).copy()
        self.inputs = list(self.effectors)
        self.components = ["I:nominal"] + [f"I:{e}" for e in self.effectors] + [f"status:{e}" for e in self.effectors]
        self.estimate_components = list(self.effectors)
        self.estimate_modes = ["level"] * m
        self.units = {"residual": ["(rad/s)^2"] * (m + 1) + ["1"] * m, "estimate": ["rad"] * m}
        S2 = np.zeros((p, n))
        S2[np.arange(p), self.x2] = 1.0
        self._S2 = S2
        Nx0 = self.lam * S2 + self.A2
        self._nominal = foh_discretize(-self.lam * np.eye(p), Nx0, np.eye(p), self.dt)
        self._cand = []
        for i in range(m):
            b = self.B2[:, i]
            M = np.zeros((p + 1, p + 1))
            M[:p, :p], M[:p, p], M[p, :p] = -self.lam * np.eye(p), b, -self.gamma[i] * b
            Nx = np.vstack([Nx0, self.gamma[i] * b @ S2])
            Ng = np.vstack([np.eye(p), np.zeros((1, p))])
            self._cand.append(foh_discretize(M, Nx, Ng, self.dt))
        self.reset()

    # ------------------------------------------------------------------ state machine
    def reset(self) -> None:
        m = len(self.effectors)
        self.frozen: dict[int, float] = {}         # F: committed effectors and their frozen û
        self.sequence: list[tuple[float, str]] = [(0.0, "nominal")]   # (time, model) of every switch
        self.mode, self.active, self._t_o = "monitor", None, 0.0
        self._k = 0
        self._prev = None
        self._xh0 = None
        self._z = np.zeros((m, self.B2.shape[0] + 1))
        self._integral = np.zeros(m + 1)
        self._t0 = 0.0
        self.index = np.zeros(m + 1)

    def _restart(self, x: np.ndarray, u: np.ndarray) -> None:
        """Observer states to x₂, candidate û to the command (inside its limits), integrals of (44) to 0."""
        x2 = x[self.x2]
        self._xh0 = x2.copy()
        self._z[:, :-1] = x2
        self._z[:, -1] = np.clip(u, self.u_min, self.u_max)
        self._integral[:] = 0.0
        self._t0 = self._k * self.dt

    def _stuck_term(self) -> np.ndarray:
        v = np.zeros(self.B2.shape[0])
        for k, uk in self.frozen.items():
            v += self.B2[:, k] * uk
        return v

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        m = len(self.effectors)
        x = check_measurement(y, len(self.measurements), "y")
        u = check_measurement(u, m, "u")
        if self._prev is None:
            self._restart(x, u)
        else:
            xp = self._prev
            uh = u.copy()
            uh[list(self.frozen)] = 0.0
            g0 = self.B2 @ uh + self._stuck_term()
            Phi, G0, G1, Gg = self._nominal
            self._xh0 = Phi @ self._xh0 + G0 @ xp + G1 @ (x - xp) + Gg @ g0
            for i in range(m):
                if i in self.frozen:
                    continue
                Phi, G0, G1, Gg = self._cand[i]
                gi = g0 - self.B2[:, i] * uh[i]
                z = Phi @ self._z[i] + G0 @ xp + G1 @ (x - xp) + Gg @ gi
                z[-1] = min(max(z[-1], self.u_min[i]), self.u_max[i])      # projection (38), B8
                self._z[i] = z
        self._prev = x
        x2 = x[self.x2]
        e_sq = np.zeros(m + 1)
        e_sq[0] = float(np.sum((self._xh0 - x2) ** 2))
        e_sq[1:] = np.sum((self._z[:, :-1] - x2) ** 2, axis=1)
        for i in self.frozen:
            e_sq[1 + i] = 0.0
        t = self._k * self.dt
        self._integral += e_sq * self.dt
        self.index = switching_index(e_sq, self._integral, t - self._t0, self.c)
        for i in self.frozen:
            self.index[1 + i] = 0.0
        if self._k % self.every == 0 and self._k > 0:
            self._supervise(t, x, u)
        self._k += 1
        status = np.zeros(m)
        for i in self.frozen:
            status[i] = 2.0
        if self.active is not None:
            status[self.active] = 1.0
        est = self._z[:, -1].copy()
        for i, ui in self.frozen.items():
            est[i] = ui
        return Residual(np.concatenate([self.index, status]), est)

    def _supervise(self, t: float, x: np.ndarray, u: np.ndarray) -> None:
        free = [i for i in range(len(self.effectors)) if i not in self.frozen]
        if self.mode == "monitor":
            if len(free) <= self.B2.shape[0] or t < self._t0 + self.holdoff - 1e-9:
                return              # no redundancy left to reconfigure with / observers still settling
            I = self.index[1:][free]
            j = int(np.argmin(I))
            if self.index[0] - I[j] > self.delta:
                self.mode, self.active, self._t_o = "identify", free[j], t
                self.sequence.append((t, self.effectors[free[j]]))
        elif t >= self._t_o + self.tau_s[self.active] - 1e-9:
            i = self.active
            self.frozen[i] = float(self._z[i, -1])
            self.mode, self.active = "monitor", None
            self._restart(x, u)

    def signatures(self):
        return [Signature(e, frozenset({f"status:{e}"})) for e in self.effectors]
