"""Sliding-mode control with on-line control allocation on the AUV — Edwards, Alwi & Tan §6, eqs. (55)–(70), in the
form the seed digest's §8 transfer gives for a thruster-driven vehicle: x = [η; ν_b], B = [0; M⁻¹B_thr], so B1 = 0,
γ1 = γ2 = 0 and condition (66) holds for every health pattern; the sliding motion does not depend on W.

Two parts, split as the closed loop splits controller and accommodation:

* :class:`SlidingModeAuvControl` (controller) — the virtual control of (67)–(70) on the task-space tracking error
  e = η − η_d, ė (the nominal model's computed torque removes J̇ν, Coriolis, damping and restoring terms, so the
  error is the double integrator ë = v with B1 = 0, B2 = I): σ = N e + ė (61), ν̂ = −Ã21 e − Ã22 σ + Φσ
  − (ρ + η)σ/(‖σ‖ + δ) with the adaptive ρ = r(l1‖x‖ + l2) of (69)–(70) (from
  :class:`robofdi.ftc.smc_ca.SMCCAController`). The body acceleration ν̇ = J⁻¹(η̈_d + ν̂ − J̇ν) goes through the
  nominal model to the wrench τ, and the thrust demand is u = B⁺τ (like the chapter-4 controller).
* :class:`HealthWeightedAllocation` (accommodation) — τ = B u_cmd re-allocated on-line with W = I − K̂ (58): a
  thruster the health isolates has k̂ = 1, floored at w_min (Proposition 5 needs w_i > 0, erratum 11);
  u = W Bᵀ(B W² Bᵀ)⁻¹ τ, i.e. u = B^† ν with ν = (B W Bᵀ)(B W² Bᵀ)⁻¹ τ (57), (60), so that B(I − K)u = τ when
  K̂ = K. Saturation (not in the paper): above ±limit, the W-weighted bounded least squares on the believed
  effective map B W (scipy ``lsq_linear``), the unattained wrench kept in ``last_unattained``.

:func:`auv_smc_ca_check` is the design-time part: (66) and γ0 on the AUV linearised at rest, and the health
patterns (up to two total failures) for which B W Bᵀ is singular.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from robofdi.control.auv import navigation_pose, wrap
from robofdi.errors import RobofdiError, all_finite
from robofdi.ftc.smc_ca import SMCCAController, SMCCADesign, singular_patterns, smc_ca_design, weighted_pinv
from robofdi.models.auv import AuvModel, T_euler_from_body, cross, rotation_from_euler
from robofdi.protocols import Health

__all__ = ["SlidingModeAuvControl", "HealthWeightedAllocation", "auv_smc_ca_check", "SmcAuvSettings"]


@dataclass(frozen=True)
class SmcAuvSettings:
    """The SMC tunables: ``surface`` the six sliding-surface poles −N [1/s] (x, y, z, roll, pitch, yaw); ``phi``
    the six linear σ-rates −Φ [1/s]; eta η [m/s², rad/s²] of (68); l1 [1/s², per unit of ‖x‖], l2, a, b [1/s],
    eps [m/s] of (69)–(70); delta the boundary layer of σ/‖σ‖ [m/s]; w_min the effectiveness floor; dt [s]."""

    surface: tuple = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0)
    phi: tuple = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0)
    eta: float = 0.005
    l1: float = 1.0
    l2: float = 0.1
    a: float = 2.0
    b: float = 0.1
    eps: float = 0.02
    delta: float = 0.05
    w_min: float = 0.05
    dt: float = 0.01

    def __post_init__(self):
        for name in ("surface", "phi"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (6,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
                raise RobofdiError(f"SmcAuvSettings: field {name!r} must be six rates > 0 [1/s], got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        if not (0 < self.w_min <= 1):
            raise RobofdiError(f"SmcAuvSettings: field 'w_min' must be in (0, 1], got {self.w_min!r}")


def _error_design(settings: SmcAuvSettings) -> SMCCADesign:
    """(61) on the task-space error double integrator ẋ1 = x2, ẋ2 = v (B1 = 0, B2 = I): N = diag(surface)."""
    A = np.block([[np.zeros((6, 6)), np.eye(6)], [np.zeros((6, 6)), np.zeros((6, 6))]])
    B = np.vstack([np.zeros((6, 6)), np.eye(6)])
    return smc_ca_design(A, B, 6, [-s for s in settings.surface], samples=0, w_min=settings.w_min)


class SlidingModeAuvControl:
    """Controller protocol: ``update(y, (η_d, η̇_d, η̈_d))`` → u_cmd = B⁺τ with τ from the §6 virtual control
    (module docstring). Only the navigation measurements and the nominal model are used."""

    def __init__(self, model: AuvModel, settings: SmcAuvSettings = SmcAuvSettings()):
        self.model, self.settings = model, settings
        self.design = _error_design(settings)
        self.smc = SMCCAController(self.design, settings.dt, Phi=-np.diag(settings.phi), eta=settings.eta,
                                   l1=settings.l1, l2=settings.l2, a=settings.a, b=settings.b, eps=settings.eps,
                                   delta=settings.delta)
        self.B_pinv = np.linalg.pinv(model.B)
        self._T = self.design.Tr @ self.design.Tn        # the design's coordinates (identity up to sign here)
        self.reset()

    def reset(self) -> None:
        self.smc.reset()
        self.tau = np.zeros(6)

    @property
    def gain(self) -> float:
        """The adaptive switching gain r of (70)."""
        return self.smc.r

    def update(self, y: np.ndarray, reference) -> np.ndarray:
        eta_d, deta_d, ddeta_d = reference
        if not all_finite(np.asarray(y[:13], dtype=float)):
            raise RobofdiError("SlidingModeAuvControl: non-finite navigation measurement (NaN sensor reading)")
        eta, nu = navigation_pose(y)
        R = rotation_from_euler(eta[3:])
        T = T_euler_from_body(eta[3:])
        deta = np.concatenate([R @ nu[:3], T @ nu[3:]])
        e = eta - eta_d
        e[3:] = wrap(e[3:])
        nu_hat = self.smc.virtual(np.concatenate([e, deta - deta_d]))
        # ν̂ is in the design's scaled coordinates: x̂2 = Sc x2, so the acceleration is Sc⁻¹ ν̂
        v = np.linalg.solve(self._T[6:, 6:], nu_hat)
        a = ddeta_d + v
        h = 1e-6
        T_dot_nu = (T_euler_from_body(eta[3:] + h * deta[3:]) - T) @ nu[3:] / h
        nu_dot = np.concatenate([R.T @ a[:3] - cross(nu[3:], nu[:3]), np.linalg.solve(T, a[3:] - T_dot_nu)])
        self.tau = self.model.wrench(R, nu, nu_dot)
        return self.B_pinv @ self.tau


class HealthWeightedAllocation:
    """Accommodation protocol: τ = B u_cmd allocated with W = I − K̂ (57)–(60) (module docstring). ``weights``
    holds the last W, ``last_unattained`` the wrench the bound left out [N, N·m]."""

    def __init__(self, B, thrusters, limit: float, w_min: float = 0.05, regularisation: float = 1e-4):
        self.B = np.asarray(B, dtype=float)
        self.thrusters = list(thrusters)
        if self.B.shape != (6, len(self.thrusters)):
            raise RobofdiError(f"HealthWeightedAllocation: field 'B' must be (6, {len(self.thrusters)}), got "
                               f"{self.B.shape}")
        if not (np.isfinite(limit) and limit > 0):
            raise RobofdiError(f"HealthWeightedAllocation: field 'limit' must be a thrust > 0 N, got {limit!r}")
        if not (0 < w_min <= 1):
            raise RobofdiError(f"HealthWeightedAllocation: field 'w_min' must be in (0, 1], got {w_min!r}")
        self.limit, self.w_min, self.regularisation = float(limit), float(w_min), float(regularisation)
        self._index = {t: i for i, t in enumerate(self.thrusters)}
        self.reset()

    def reset(self) -> None:
        self.weights = np.ones(len(self.thrusters))
        self.last_unattained = np.zeros(6)

    def effectiveness(self, health: Health) -> np.ndarray:
        """W = I − K̂: k̂ = 1 for every thruster the health isolates, floored at w_min."""
        w = np.ones(len(self.thrusters))
        for target in health.isolated:
            i = self._index.get(str(target).split(":", 1)[0])
            if i is not None:
                w[i] = self.w_min
        return w

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        tau = self.B @ np.asarray(u_cmd, dtype=float)
        w = self.effectiveness(health)
        self.weights = w
        Bw = self.B * w
        u = w * (self.B.T @ np.linalg.solve(Bw @ Bw.T, tau))       # W Bᵀ (B W² Bᵀ)⁻¹ τ = B^†ν, (57) with (60)
        if np.any(np.abs(u) > self.limit):
            Aq = np.vstack([Bw, np.diag(np.sqrt(self.regularisation / w))])
            bq = np.concatenate([tau, np.zeros(len(w))])
            u = lsq_linear(Aq, bq, bounds=(-self.limit, self.limit), method="bvls").x
        self.last_unattained = tau - Bw @ u
        return u


def auv_smc_ca_check(model: AuvModel, settings: SmcAuvSettings = SmcAuvSettings(), samples: int = 500) -> dict:
    """The design-time checks of §6 on the AUV linearised at rest (x = [η; ν_b], B = [0; M⁻¹B_thr]): γ0, γ1, γ2,
    condition (66) (0: B1 = 0) and the ≤ 2-failure patterns with B W Bᵀ singular; refuses when the single-failure
    patterns are not all tolerated (eq. 57 would have no solution after one total failure)."""
    A = np.block([[np.zeros((6, 6)), np.eye(6)], [np.zeros((6, 6)), -model.M_inv @ np.diag(model.hydro.linear_damping)]])
    B = np.vstack([np.zeros((6, len(model.thrusters))), model.M_inv @ model.B])
    d = smc_ca_design(A, B, 6, [-s for s in settings.surface], w_min=settings.w_min, samples=samples)
    bad = singular_patterns(model.B, 2)
    single = [p for p in bad if len(p) == 1]
    if single:
        raise RobofdiError(f"auv_smc_ca_check: B W Bᵀ is singular after the total failure of thruster "
                           f"{model.thrusters[single[0][0]]} (eq. 57: the others cannot produce every wrench)")
    weighted_pinv(model.B, np.ones(len(model.thrusters)), "auv_smc_ca_check")
    return {"gamma0": d.gamma0, "gamma1": d.gamma1, "gamma2": d.gamma2, "condition_66": d.condition,
            "sliding_poles": sorted(float(p.real) for p in d.sliding_poles),
            "singular_double_failures": [[model.thrusters[i] for i in p] for p in bad]}
