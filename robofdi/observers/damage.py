"""Structural-damage estimation — Bošković & Mehra, "Failure detection, identification and reconfiguration in
flight control", §6: the observer (61)–(64) and the adaptive law (66)–(67) for the damage parameter ρ̂ ∈ [0, 1].

[RECONSTRUCTED] Ω is a p-vector and ê an n-vector: the law uses êᵀP[0; Ω] (digest B4). Two robustness
modifications against sensor noise (the chapter's Theorem 5 is noise-free): Ω is evaluated at the observer's
state x̂ (at the measured x its noise correlates with the noise in ê and drives ρ̂ away from 0), and a dead zone
on the x₂ part of ê (adaptation only while ‖ê₂‖ > ``dead_zone``); ρ̂ stays at 0 in a damage-free run.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import solve_continuous_lyapunov

from robofdi.decision.isolation import Signature
from robofdi.errors import RobofdiError
from robofdi.ftc.idcl import check_hurwitz
from robofdi.models.flight import FlightSurrogate
from robofdi.observers.effector_bank import foh_discretize
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["damage_regressor", "DamageEstimator"]


def damage_regressor(A2_coeffs, B2_coeffs, x, u, rho_hat: float) -> np.ndarray:
    """Ω = Σ_{i≥1} i (Aᵢx + Bᵢu) ρ̂^{i−1} = ∂(A(ρ)x + B(ρ)u)/∂ρ at ρ̂ — eq. (67)."""
    out = 0.0
    for i in range(1, len(A2_coeffs)):
        out = out + i * (A2_coeffs[i] @ x + B2_coeffs[i] @ u) * rho_hat ** (i - 1)
    return np.asarray(out, dtype=float)


class DamageEstimator:
    """Diagnoser: x̂̇₁ = Ā x̂ (61), x̂̇₂ = Λê + Â x + B̂ u (62)–(64), ρ̂̇ = Proj_{[0,1]}{−γ êᵀP[0; Ω(x̂, u)]} (66)–(67),
    ê = x̂ − x, P from Λ_oᵀP + PΛ_o = −Q (Λ_o = [Ā; Λ] Hurwitz).

    The observer is sampled exactly for the ρ̂ of the step (x interpolated linearly, u held), ρ̂ by Euler and
    clipped to [0, 1]. ``observer="simplified"``: the x₂-only observer of §5.4's Step 1 carried over to the
    damage parameter, x̂̇₂ = −λ(x̂₂ − x₂) + Â x + B̂ u, ρ̂̇ = Proj{−γ ê₂ᵀΩ} (Lyapunov function ê₂ᵀê₂ + φ²/γ;
    without the slow x₁ modes of Λ_o in P, which make the full law's gradient lag and reverse on this surrogate).
    Residual = estimate = ρ̂ (component ``left_wing``, unit 1); ``rho`` is the current ρ̂."""

    def __init__(self, belief: FlightSurrogate, Lam, dt: float, gamma: float = 2000.0, Q=None,
                 dead_zone: float = 2e-3, target: str = "left_wing", observer: str = "full", lam: float = 20.0):
        if not isinstance(belief, FlightSurrogate):
            raise RobofdiError(f"DamageEstimator: field 'belief' must be a FlightSurrogate, got {type(belief).__name__}")
        self.s = belief
        n, n1 = belief.n, belief.n1
        self.Lam = np.asarray(Lam, dtype=float)
        Lo = np.vstack([belief.Abar, self.Lam])
        check_hurwitz(Lo, "DamageEstimator: the observer error dynamics Λ_o = [Ā; Λ]")
        Q = np.eye(n) if Q is None else np.asarray(Q, dtype=float)
        if Q.shape != (n, n) or np.any(np.linalg.eigvalsh(0.5 * (Q + Q.T)) <= 0):
            raise RobofdiError(f"DamageEstimator: field 'Q' must be a positive-definite {n}×{n} matrix")
        self.P = solve_continuous_lyapunov(Lo.T, -Q)
        for name, v in (("dt", dt), ("gamma", gamma)):
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"DamageEstimator: field {name!r} must be > 0, got {v!r}")
        if not (np.isfinite(dead_zone) and dead_zone >= 0):
            raise RobofdiError(f"DamageEstimator: field 'dead_zone' must be >= 0, got {dead_zone!r}")
        self.dt, self.gamma, self.dead_zone = float(dt), float(gamma), float(dead_zone)
        self._Pb = self.P[:, n1:]                  # P [0; ·]
        if observer not in ("full", "simplified"):
            raise RobofdiError(f"DamageEstimator: field 'observer' must be 'full' or 'simplified', got {observer!r}")
        if not (np.isfinite(lam) and lam > 0):
            raise RobofdiError(f"DamageEstimator: field 'lam' must be > 0, got {lam!r}")
        self.observer, self.lam = observer, float(lam)
        if observer == "full":
            self._disc = foh_discretize(Lo, np.eye(n), np.eye(n), self.dt)
        else:
            p = n - n1
            self._disc = foh_discretize(-self.lam * np.eye(p), np.eye(p), np.eye(p), self.dt)
        self.measurements, self.inputs = list(belief.state_names), list(belief.effectors)
        self.components = [f"rho:{target}"]
        self.estimate_components = [target]
        self.estimate_modes = ["level"]
        self.units = {"residual": ["1"], "estimate": ["1"]}
        self._A2c, self._B2c = belief.A2_coeffs, belief.B2_coeffs
        self.reset()

    def reset(self) -> None:
        self.rho = 0.0
        self._xh = None
        self._prev = None

    def _w(self, x: np.ndarray) -> np.ndarray:
        s = self.s
        if self.observer == "simplified":
            return self.s.A2(self.rho) @ x + self.lam * x[s.n1:]
        w = np.zeros(s.n)
        w[s.n1:] = (s.A2(self.rho) - self.Lam) @ x
        return w

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        s = self.s
        x = check_measurement(y, s.n, "y")
        u = check_measurement(u, s.m, "u")
        simple = self.observer == "simplified"
        if self._prev is None:
            self._xh = x[s.n1:].copy() if simple else x.copy()
        else:
            Phi, G0, G1, Gg = self._disc
            w0, w1 = self._w(self._prev), self._w(x)
            if simple:
                g = s.B2(self.rho) @ u
            else:
                g = np.zeros(s.n)
                g[s.n1:] = s.B2(self.rho) @ u
            self._xh = Phi @ self._xh + G0 @ w0 + G1 @ (w1 - w0) + Gg @ g
            e = self._xh - (x[s.n1:] if simple else x)
            e2 = e if simple else e[s.n1:]
            if np.linalg.norm(e2) > self.dead_zone:
                # Ω at the observer's state: Ω(x_meas) would correlate with the measurement noise in ê and bias ρ̂
                xo = x.copy()
                if simple:
                    xo[s.n1:] = self._xh
                else:
                    xo = self._xh
                Om = damage_regressor(self._A2c, self._B2c, xo, u, self.rho)
                v = -self.gamma * float((e @ Om) if simple else (e @ self._Pb @ Om))
                if not ((self.rho >= 1.0 and v > 0) or (self.rho <= 0.0 and v < 0)):     # projection (66), B8
                    self.rho = min(max(self.rho + self.dt * v, 0.0), 1.0)
        self._prev = x
        return Residual(np.array([self.rho]), np.array([self.rho]))

    def signatures(self):
        return [Signature(self.estimate_components[0], frozenset(self.components))]
