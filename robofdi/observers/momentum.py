"""Discrete-time generalised-momentum observer — the industrial baseline residual for collision and actuator-fault
detection (De Luca & Mattone, ICRA 2003, eq. (10), discretised with the forward Euler rule):

    r(k) = K_O ( M̂(q_k) q̇_k − p₀ − Σ_{j<k} T (ū_j + Ĉᵀ(q_j, q̇_j) q̇_j − ĝ(q_j) − D̂ q̇_j + r_j) )

r is a first-order low-pass estimate of the unmodelled joint torque δτ (N·m), bandwidth K_O. With an identified
:class:`~robofdi.models.friction.JointFriction` τ̂_f the bias is β = ĝ + D̂ q̇ − Ĉᵀq̇ + τ̂_f(q̇) (friction-compensated
residual), τ̂_f identified from fault-free residuals by :func:`identify_friction`.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.signal import lfilter

from robofdi import RobofdiError
from robofdi.decision.isolation import Signature
from robofdi.models.friction import JointFriction
from robofdi.jit import kernel
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers.evaluations import evaluations
from robofdi.observers.residual import Residual, check_measurement, shared_measurement

__all__ = ["MomentumObserver", "JointMomentumDiagnoser", "identify_friction", "identify_friction_and_load",
           "observer_filter"]


@kernel
def _momentum_step(gravity, damping, v, coriolis, friction, u, r_prev, p, p0, integral_prev, T, gain, integral, r):
    """β = ĝ + D̂ q̇ − Ĉᵀq̇ (+ τ̂_f when ``friction`` is not None), the integral and r(k) of eq. (10), entry by
    entry in the order of operations of their array form, into ``integral`` and ``r``."""
    for i in range(r.shape[0]):
        beta = gravity[i] + damping[i] * v[i] - coriolis[i]
        if friction is not None:
            beta = beta + friction[i]
        integral[i] = integral_prev[i] + T * (u[i] - beta + r_prev[i])
        r[i] = gain * (p[i] - p0[i] - integral[i])


# The batch form of the kernel above (robofdi.lockstep): on every run's rows, one call a sample for all runs.
@kernel
def _momentum_step_each(gravity, damping, Y_prev, coriolis, friction, U, r_prev, p, p0, integral_prev, T, gain, integral,
                        r):
    """Eq. (10) per run, with the friction τ̂_f (a, n) or without (None): _momentum_step."""
    n = U.shape[1]
    if friction is None:        # (numba prunes the branch its argument's type rules out)
        for i in range(r.shape[0]):
            _momentum_step(gravity[i], damping[i], Y_prev[i, n:], coriolis[i], None, U[i], r_prev[i], p[i], p0[i],
                           integral_prev[i], T, gain, integral[i], r[i])
    else:
        for i in range(r.shape[0]):
            _momentum_step(gravity[i], damping[i], Y_prev[i, n:], coriolis[i], friction[i], U[i], r_prev[i], p[i], p0[i],
                           integral_prev[i], T, gain, integral[i], r[i])


class MomentumObserver:
    """Residual components ``joint{i}`` in N·m; the residual is also the actuator-fault estimate."""

    def __init__(self, model: ManipulatorModel, T: float, gain: float = 50.0, friction: JointFriction | None = None):
        if not (np.isfinite(T) and T > 0):
            raise RobofdiError(f"MomentumObserver: field 'T' must be a positive sample time, got {T}")
        if not (np.isfinite(gain) and 0 < gain * T < 1):
            raise RobofdiError(f"MomentumObserver: field 'gain' must be in (0, 1/T) = (0, {1 / T:g}), got {gain}")
        if friction is not None and friction.n != model.n:
            raise RobofdiError(f"MomentumObserver: field 'friction' has {friction.n} joints, the model {model.n}")
        self.model, self.T, self.gain, self.n, self.friction = model, float(T), float(gain), model.n, friction
        self.inputs = list(model.joint_names)
        self.measurements = [f"{j}_pos" for j in model.joint_names] + [f"{j}_vel" for j in model.joint_names]
        self.components = list(model.joint_names)
        self.estimate_components = list(model.joint_names)
        self.estimate_modes = ["level"] * self.n
        self.units = {"residual": ["N·m"] * self.n, "estimate": ["N·m"] * self.n}
        self._evaluations = evaluations(model)
        self.reset()

    def reset(self) -> None:
        self._prev = None
        self.mass = None        # M(q_k) of the last sample (None before the first)

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y = [q; q̇](k), u = ū(k−1)."""
        n, m = self.n, self.model
        y = shared_measurement(y, 2 * n, "y")
        u = shared_measurement(u, n, "u")
        v = y[n:]
        ev = self._evaluations             # M̂, ĝ, Ĉ at this sample's arguments, shared with the other diagnosers
        self.mass = ev.mass_matrix_at(y)    # M(q_k) of this sample (read-only), for users of the momentum (consistency's ν)
        p = self.mass.dot(v)
        if self._prev is None:
            self._p0, self._integral, self._r = p, np.zeros(n), np.zeros(n)
        else:
            yp = self._prev
            vp = yp[n:]
            coriolis = ev.coriolis_at(yp).T.dot(vp)
            friction = self.friction.torque(vp) if self.friction is not None else None
            integral, r = np.empty(n), np.empty(n)
            _momentum_step(ev.gravity_at(yp), m.damping, vp, coriolis, friction, u, self._r, p, self._p0,
                           self._integral, self.T, self.gain, integral, r)
            self._integral, self._r = integral, r
        self._prev = y                      # read-only (shared_measurement): kept without a copy
        return Residual(self._r.copy(), self._r.copy())

    def signatures(self):
        from robofdi.decision import Signature

        return [Signature(j, frozenset([j])) for j in self.model.joint_names]


def observer_filter(x: np.ndarray, gain: float, T: float) -> np.ndarray:
    """The residual's own dynamics applied to a signal sampled with the diagnoser (axis 0): f_k = (1 − K_O T)
    f_{k−1} + K_O T x_{k−1}, f_0 = 0 — how a torque acting at sample k−1 shows in r_k."""
    a = float(gain) * float(T)
    return lfilter([0.0, a], [1.0, a - 1.0], np.asarray(x, dtype=float), axis=0)


def identify_friction(residuals: Sequence[np.ndarray], velocities: Sequence[np.ndarray], gain: float, T: float,
                      skip: int = 0, stribeck_velocity: float = 0.05, smoothing: float = 0.01) -> JointFriction:
    """Least-squares friction identification from fault-free momentum residuals (no friction in the observer):
    r ≈ −LP(Φ(q̇) c) with Φ the :meth:`JointFriction.regressors` and LP :func:`observer_filter`, per joint
    (the residual-based identification of e.g. Lee & Song, IEEE ICRA 2016). ``residuals``/``velocities``: one
    (N_i, n) array per run at the diagnosis rate; samples k < ``skip`` are left out of the fit."""
    return identify_friction_and_load(residuals, velocities, None, gain, T, skip, stribeck_velocity, smoothing)[0]


def identify_friction_and_load(residuals: Sequence[np.ndarray], velocities: Sequence[np.ndarray],
                               loads: Sequence[np.ndarray] | None, gain: float, T: float, skip: int = 0,
                               stribeck_velocity: float = 0.05, smoothing: float = 0.01,
                               min_share: float = 0.0) -> tuple[JointFriction, float]:
    """:func:`identify_friction` with one more unknown shared by every joint: r ≈ −LP(Φ(q̇) c) − m L, where
    ``loads`` L (one (N_i, n) array per run) is what a unit of m does to the residual — the payload regressor
    LP(Y) per kg (:class:`~robofdi.observers.payload.PayloadRegressor`) for a payload of m kg the nominal model
    lacks. The joint least-squares fit: with each joint's friction fitted out (the projection P⊥ onto the
    complement of its regressors), m = −Σ_j (P⊥L_j)·(P⊥r_j) / Σ_j |P⊥L_j|², then c_j for r_j + m L_j.
    ``min_share``: m is kept only when it explains at least this share of the residual's energy beyond friction,
    (Σ_j (P⊥L_j)·(P⊥r_j))² / (Σ_j |P⊥L_j|² Σ_j |P⊥r_j|²) (model selection: a smaller m is the model's other
    errors, which it would only redistribute). Returns (friction, m); m = 0 without ``loads`` or below
    ``min_share`` (then exactly :func:`identify_friction`'s fit)."""
    if not 0.0 <= min_share <= 1.0:
        raise RobofdiError(f"identify_friction_and_load: field 'min_share' must be a share in [0, 1], got {min_share!r}")
    if len(residuals) == 0 or len(residuals) != len(velocities) or (loads is not None and len(loads) != len(residuals)):
        raise RobofdiError(f"identify_friction: expected as many residual as velocity (and load) runs (>= 1), got "
                           f"{len(residuals)}, {len(velocities)}" + ("" if loads is None else f" and {len(loads)}"))
    rows, targets, shared = [], [], []
    for i, (r, v) in enumerate(zip(residuals, velocities)):
        r, v = np.asarray(r, dtype=float), np.asarray(v, dtype=float)
        if r.ndim != 2 or r.shape != v.shape:
            raise RobofdiError(f"identify_friction: run {i}: residual {r.shape} and velocity {v.shape} must be "
                               "(N, n) arrays of the same shape")
        if loads is not None:
            load = np.asarray(loads[i], dtype=float)
            if load.shape != r.shape:
                raise RobofdiError(f"identify_friction: run {i}: load {load.shape} must have the residual's shape {r.shape}")
            shared.append(load[skip:])
        phi = observer_filter(JointFriction.regressors(v, stribeck_velocity, smoothing), gain, T)
        rows.append(phi[skip:])
        targets.append(r[skip:])
    phi, r = np.concatenate(rows), np.concatenate(targets)
    if phi.shape[0] < 4 * 10:
        raise RobofdiError(f"identify_friction: {phi.shape[0]} samples after skip; expected at least 40")
    m = 0.0
    if loads is not None:
        load, num, den, energy = np.concatenate(shared), 0.0, 0.0, 0.0
        for j in range(r.shape[1]):
            a = phi[:, j]
            load_out = load[:, j] - a @ np.linalg.lstsq(a, load[:, j], rcond=None)[0]
            r_out = r[:, j] - a @ np.linalg.lstsq(a, r[:, j], rcond=None)[0]
            num, den, energy = num + load_out @ r_out, den + load_out @ load_out, energy + r_out @ r_out
        # no sample moved the load, or it explains too little: m stays 0
        if den > 1e-12 * max(1.0, float(np.sum(load * load))) and num * num >= min_share * den * energy:
            m = -num / den
            r = r + m * load
    coef = np.array([np.linalg.lstsq(-phi[:, j], r[:, j], rcond=None)[0] for j in range(r.shape[1])])
    return JointFriction.from_coefficients(coef, stribeck_velocity, smoothing), float(m)


class JointMomentumDiagnoser:
    """Momentum residual on every joint of a MuJoCo-built ``model`` (a :class:`~robofdi.models.multibody.MultibodyModel`;
    a :class:`~robofdi.protocols.Diagnoser`): ``update(y, u)`` with y = [q; q̇] at sample k and u = the action held
    over the step that ended there (ū(k−1), as commanded), τ = B u.

    Residual components: the joint names [N·m for hinges, N for slides]; signatures: one per actuator (the joints its
    column of B reaches). ``measurements``: the names of y's channels (default ``<joint>_pos`` then ``<joint>_vel``);
    ``estimate``: the residual is also the estimate of the unmodelled joint force (identification candidates), or
    there are none. The environment adapters (Gymnasium, dm_control) share it."""

    def __init__(self, model, sample_time: float, gain: float = 10.0, measurements: Sequence[str] | None = None,
                 estimate: bool = True):
        self.model = model
        self.observer = MomentumObserver(model, sample_time, gain)
        self.inputs = list(model.actuator_names)
        joints = list(model.joint_names)
        self.measurements = (list(measurements) if measurements is not None
                             else [f"{j}_pos" for j in joints] + [f"{j}_vel" for j in joints])
        if len(self.measurements) != 2 * model.n:
            raise RobofdiError(f"JointMomentumDiagnoser: field 'measurements' must name {2 * model.n} channels "
                               f"(q then q̇), got {len(self.measurements)}")
        self.components = joints
        self._estimate = bool(estimate)
        unit = ["N" if k == "slide" else "N·m" for k in model.joint_kinds]
        self.estimate_components = list(joints) if estimate else []
        self.estimate_modes = ["level"] * model.n if estimate else []
        self.units = {"residual": unit, "estimate": list(unit) if estimate else []}
        self._signatures = [Signature(a, frozenset(j for j, b in zip(joints, model.B[:, k]) if b != 0))
                            for k, a in enumerate(model.actuator_names)]
        self.reset()

    def signatures(self) -> list[Signature]:
        return list(self._signatures)

    def reset(self) -> None:
        self.observer.reset()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """Residual at sample k (De Luca & Mattone 2003 eq. (10)) from y(k) and τ = B ū(k−1)."""
        u = check_measurement(u, len(self.inputs), "u")
        r = self.observer.update(y, self.model.joint_torque(u)).r
        return Residual(r, r.copy() if self._estimate else np.zeros(0))
