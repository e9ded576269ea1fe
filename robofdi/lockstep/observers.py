"""Batch forms of the arm diagnosers: N runs of one arm system diagnosed together, sample by sample.

A batch form steps the same diagnoser over N runs at once: one call a sample for all active runs, so the Python
work of a sample (input checks, estimator bookkeeping, kernel dispatch, the BLAS products) is paid once per sample
and not once per run. Row i of everything it returns equals, bit for bit, what run i's own diagnoser returns when
stepped alone: the per-run arithmetic is the single form's own kernels, which a batch kernel calls on each run's
rows (through their module, so that :func:`robofdi.jit.interpreted` reaches them); the nominal-model evaluations
are run i's Pinocchio calls (:mod:`robofdi.lockstep.evaluations`; the payload regressor's on its own unit model,
in the single form's order); NumPy's elementwise operations on (a, …) arrays give each row's bits (its SIMD tanh and exp too,
checked in the tests), and so do its stacked products where they are used (see :func:`_stacked`).

The batch kernels (``…_each``) live beside the single kernels they loop over, in those modules: numba's disk cache
checks a compiled kernel against its own file only, so a batch kernel elsewhere would keep a changed single
kernel's old code.

Batch forms exist for :class:`~robofdi.observers.diagnostic.DiagnosticObserver` (Caccavale & Villani eqs.
(20)–(39), (43)) with each of its estimators and both velocity sources, for
:class:`~robofdi.observers.momentum.MomentumObserver` (De Luca & Mattone eq. (10)) without friction, and for the
consistency scheme :class:`~robofdi.observers.consistency.ConsistencyResidual` (its friction-compensated momentum
residual, payload regressor, kinematic consistency and step rows) with each run's own calibrated design;
:func:`batch_form` says which.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from robofdi import RobofdiError
from robofdi.decision.envelope import LOW_SPEED_VELOCITY, REST_VELOCITY
from robofdi.jit import einsum as _einsum
from robofdi.lockstep.evaluations import batch_evaluations
from robofdi.models import friction as friction_model
from robofdi.observers import consistency, diagnostic, kinematic, momentum
from robofdi.observers.consistency import ConsistencyResidual
from robofdi.observers.diagnostic import Adaptive, DiagnosticObserver, NoEstimate, Recursive, TimeDelayed
from robofdi.observers.momentum import MomentumObserver
from robofdi.observers.payload import PayloadRegressor

__all__ = ["BatchConsistencyResidual", "BatchDiagnoser", "BatchDiagnosticObserver", "BatchMomentumObserver",
           "batch_form"]


class BatchDiagnoser:
    """N diagnosers of one kind stepped together (the lockstep engine's side of a diagnoser).

    The engine resets, then hands every sample k the measurements Y (a, ny) and inputs U (a, nu) of the a runs
    still active — a prefix of the runs, longest first, so a never grows between resets; U holds each run's
    ū(k−1) (zeros at sample 0). Y and U are fresh read-only C-contiguous float arrays, the same objects for every
    batch diagnoser of the sample (kept as the previous sample without a copy)."""

    def reset(self) -> None:
        """Every run back to before its first sample."""
        raise NotImplementedError

    def update(self, Y: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One sample of the first a = Y.shape[0] runs: R (a, m) and E (a, e), fresh arrays whose row i are run
        i's diagnoser's ``update(y_i, u_i).r`` and ``.estimate``. Non-finite or misshapen inputs raise
        :class:`~robofdi.RobofdiError`."""
        raise NotImplementedError


def _checked(Y, U, active: int, n: int) -> int:
    """The number a of runs of this sample, after checking Y (a, 2n) and U (a, n) as every arm diagnoser checks
    its y and u (:func:`~robofdi.observers.residual.check_measurement`), with 0 < a ≤ ``active``."""
    a = Y.shape[0] if isinstance(Y, np.ndarray) and Y.ndim == 2 else -1
    if not (0 < a <= active and Y.shape == (a, 2 * n) and isinstance(U, np.ndarray) and U.shape == (a, n)
            and Y.dtype == U.dtype == np.float64):
        raise RobofdiError(f"lockstep: expected float Y (a, {2 * n}) and U (a, {n}) for 0 < a <= {active} runs, got "
                           f"{getattr(Y, 'shape', Y)} and {getattr(U, 'shape', U)}")
    if not (np.isfinite(Y).all() and np.isfinite(U).all()):
        raise RobofdiError("lockstep: diagnoser inputs 'y' or 'u' have non-finite values (NaN/inf measurement)")
    return a


def _first(A: np.ndarray, a: int) -> np.ndarray:
    """The rows of the first a runs: ``A`` itself while no run has ended (the same object, for the memo)."""
    return A if A.shape[0] == a else A[:a]


def _stacked(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """[M[i] · v[i]] for a stack M (a, n, n) and v (a, n): np.matmul on a stack calls BLAS gemv per item, the
    same call as ``M[i].dot(v[i])`` of the single form (bit for bit, checked in the tests; einsum is not)."""
    return np.matmul(M, v[:, :, None])[:, :, 0]


def _same(values) -> bool:
    """All equal: numbers, strings, None or arrays."""
    first = values[0]
    if isinstance(first, np.ndarray):
        return all(isinstance(v, np.ndarray) and np.array_equal(v, first) for v in values[1:])
    return all(v == first for v in values[1:])


# ----------------------------------------------------------------------------------------------------------
class BatchDiagnosticObserver(BatchDiagnoser):
    """:class:`~robofdi.observers.diagnostic.DiagnosticObserver` over N runs: x̂(k+1) = A x̂ + h(x̄) + B(x̄) ū +
    K_o e + η̂ (eqs. (23)–(27)) with the estimator η̂ of eq. (20) (none), (28) (time-delayed), (33) (recursive) or
    (37)–(39) with Q diagonal (adaptive); velocities measured or backward differences of the positions (eq. (43)).

    Shared by the runs: T, the gains, the estimator's settings, ``velocity``, ``eval_at`` and ``residual_space``;
    per run: the nominal model, the adaptive estimator's θ̂₀ and torque scale (calibrated per robot instance)."""

    def __init__(self, observers: Sequence[DiagnosticObserver]):
        first = observers[0]
        self.n, self.T, self.N = first.n, first.T, len(observers)
        self.kind, self.gains = type(first.estimator), first._gains
        self.measured_velocity = first.velocity == "measured"
        self.eval_at_measured = first.eval_at == "measured"
        self.torque = first.residual_space == "torque"
        self.models = [d.model for d in observers]
        self.evaluations = batch_evaluations(self.models)
        est = first.estimator
        if self.kind is Recursive:
            self.gamma = est.gamma
        if self.kind is Adaptive:
            self.q, self.step = est._q, est.step
            self.theta0 = np.array([d.estimator.theta0 for d in observers])
            self.inv_scale = np.array([d.estimator.ripple._inv_scale for d in observers])
        self.reset()

    @classmethod
    def of(cls, observers: Sequence[DiagnosticObserver]) -> BatchDiagnosticObserver | None:
        """The batch form, or None when the observers' settings differ or are not supported (a freeze threshold;
        the adaptive estimator with a full Q or frozen)."""
        ests = [d.estimator for d in observers]
        kind = type(ests[0])
        if (kind not in (NoEstimate, TimeDelayed, Recursive, Adaptive) or any(type(e) is not kind for e in ests)
                or any(d.freeze_threshold is not None for d in observers)):
            return None
        shared = [[getattr(d, name) for d in observers] for name in ("n", "T", "_gains", "velocity", "eval_at",
                                                                      "residual_space")]
        if kind is Recursive:
            shared.append([e.gamma for e in ests])
        if kind is Adaptive:
            if any(e._q is None or e.frozen for e in ests):
                return None
            shared += [[e._q for e in ests], [e.step for e in ests]]
        return cls(observers) if all(_same(values) for values in shared) else None

    def reset(self) -> None:
        self._active = self.N
        self._q_prev = None      # the previous Y, for backward differences
        self._x_prev = None      # x̄(k−1) (a, 2n)
        self._x_hat = self._e_prev = None
        self._eta = np.zeros((self.N, 2 * self.n))     # η̂ of each run (the adaptive one's: from θ̂, each sample)
        if self.kind is Adaptive:
            self._theta = self.theta0.copy()

    def _state(self, Y: np.ndarray, a: int) -> np.ndarray | None:
        """x̄(k): Y itself (read-only, kept without a copy), or [q; (q − q_prev)/T] of eq. (43) (None at the first
        sample; writeable, like the single form's, so the kernels see the same array types)."""
        if self.measured_velocity:
            return Y
        q_prev, self._q_prev = self._q_prev, Y
        if q_prev is None:
            return None
        n = self.n
        Z = np.empty((a, 2 * n))
        diagnostic._backward_state_each(Y, q_prev, self.T, Z)
        return Z

    def update(self, Y: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n, m = self.n, 2 * self.n
        a = self._active = _checked(Y, U, self._active, n)
        X = self._state(Y, a)
        if X is None or self._x_prev is None:
            if X is not None:
                self._x_prev, self._x_hat, self._e_prev = X, X.copy(), np.zeros((a, m))
            return np.zeros((a, m)), np.zeros((a, m))
        x_prev, x_hat, e_prev = _first(self._x_prev, a), self._x_hat[:a], self._e_prev[:a]
        ev = self.evaluations
        if self.kind is Adaptive:             # prepare: η̂(k−1) and the non-zero part G of Z at x̄(k−1), ū(k−1), eq. (50)
            theta, eta, G = self._theta[:a], np.empty((a, m)), np.empty((a, n, 7))
            diagnostic._ripple_terms_each(theta, x_prev, U, self.inv_scale, G, eta)
        else:
            eta = self._eta[:a]
        acc = ev.acceleration_at(x_prev, U)           # the model term of eq. (20), at x̄(k−1), ū(k−1)
        if self.eval_at_measured:
            acc_hat = acc
        else:                    # predict(x̂), eq. (23): the forward dynamics at x̂(k−1), as the single form calls it
            acc_hat = np.array([model.acceleration(xh[:n], xh[n:], u) for model, xh, u in zip(self.models, x_hat, U)])
        rows = np.empty((a, 4, m))                    # r₂₀, x̂, e, r of each run (each run's block the single form's)
        diagnostic._observer_step_each(X, x_prev, x_hat, e_prev, acc, acc_hat, self.eval_at_measured, eta, self.T, self.gains,
                                       rows)
        r_model, self._x_hat, self._e_prev, r = rows.transpose(1, 0, 2)
        self._x_prev = X
        if self.kind is NoEstimate:                   # f̂ = r₂₀ (Sec. 6)
            f_hat = r_model
        elif self.kind is TimeDelayed:                # η̂(k) = r₂₀(k), eq. (28)
            f_hat = self._eta = r_model
        elif self.kind is Recursive:             # η̂(k+1) = η̂(k) + Γ_η r(k), eq. (33) (elementwise: each row's bits)
            f_hat = self._eta = eta + self.gamma * r
        else:                                         # θ̂(k+1), eqs. (37)–(39) with Q diagonal; f̂ = η̂(k−1)
            f_hat, new = eta, np.empty_like(theta)
            # row sums of G² as the single form's einsum "ij,ij->i" (the same inner loop over each row's 7 entries)
            gg = _einsum("kij,kij->ki", G, G)
            diagnostic._adaptive_step_each(theta, G, gg, r, self.q, self.step, new)
            self._theta = new
        return self._output(Y, r, f_hat, r_model)

    def _output(self, Y: np.ndarray, r: np.ndarray, f_hat: np.ndarray, r_model: np.ndarray):
        """R: r, or [r₁; (M̂ r₂)/T] in "torque"; E: [r₂₀ position rows; (M̂ f̂₂)/T] (Sec. 6)."""
        n, a = self.n, Y.shape[0]
        # M̂ at x̄(k)'s positions, which are Y's with either velocity source: the memo is shared with the others
        M = self.evaluations.mass_matrix_at(Y)
        m_f = _stacked(M, f_hat[:, n:])
        m_r = _stacked(M, r[:, n:]) if self.torque else r
        estimate = np.empty((a, 2 * n))
        out = np.empty((a, 2 * n)) if self.torque else r
        diagnostic._output_rows_each(r_model, m_f, r, m_r, self.T, self.torque, estimate, out)
        return out, estimate


# ----------------------------------------------------------------------------------------------------------
class BatchMomentumObserver(BatchDiagnoser):
    """:class:`~robofdi.observers.momentum.MomentumObserver` over N runs: r(k) = K_O (M̂(q_k) q̇_k − p₀
    − Σ_{j<k} T (ū_j + Ĉᵀq̇_j − ĝ − D̂ q̇_j − τ̂_f(q̇_j) + r_j)), De Luca & Mattone eq. (10). Shared: T, K_O and whether
    friction is compensated; per run: the nominal model (its M̂, Ĉ, ĝ and D̂) and the friction τ̂_f's coefficients
    (:class:`~robofdi.models.friction.JointFriction`)."""

    def __init__(self, observers: Sequence[MomentumObserver]):
        first = observers[0]
        self.n, self.T, self.gain, self.N = first.n, first.T, first.gain, len(observers)
        self.damping = np.array([d.model.damping for d in observers])
        self.evaluations = batch_evaluations([d.model for d in observers])
        self.friction = None if first.friction is None else [
            np.array([getattr(d.friction, name) for d in observers], dtype=float)
            for name in ("coulomb", "stribeck", "viscous", "offset", "smoothing", "stribeck_velocity")]
        self.reset()

    @classmethod
    def of(cls, observers: Sequence[MomentumObserver]) -> BatchMomentumObserver | None:
        """The batch form, or None when the settings differ or an observer compensates friction (no scheme steps
        one alone: the consistency scheme's batch form steps its own, :class:`BatchConsistencyResidual`)."""
        if any(d.friction is not None for d in observers):
            return None
        if not all(_same([getattr(d, name) for d in observers]) for name in ("n", "T", "gain")):
            return None
        return cls(observers)

    def reset(self) -> None:
        self._active = self.N
        self._prev = None        # y(k−1), the previous Y
        self._p0 = self._integral = self._r = None

    def update(self, Y: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self._active = _checked(Y, U, self._active, self.n)
        r = self.step(Y, U)
        return r.copy(), r.copy()

    def step(self, Y: np.ndarray, U: np.ndarray) -> np.ndarray:
        """r (a, n) of checked Y and U (read-only: kept until the next sample)."""
        n, a = self.n, Y.shape[0]
        ev = self.evaluations
        p = _stacked(ev.mass_matrix_at(Y), Y[:, n:])        # M̂(q_k) q̇_k
        if self._prev is None:
            self._p0, self._integral, self._r = p, np.zeros((a, n)), np.zeros((a, n))
        else:
            yp = _first(self._prev, a)
            coriolis = _stacked(ev.coriolis_at(yp).transpose(0, 2, 1), yp[:, n:])    # Ĉᵀ(q_{k−1}, q̇_{k−1}) q̇_{k−1}
            gravity, r_prev, p0, integral_prev = ev.gravity_at(yp), self._r[:a], self._p0[:a], self._integral[:a]
            tau_f = None if self.friction is None else self._friction(yp[:, n:])
            integral, r = np.empty((a, n)), np.empty((a, n))
            momentum._momentum_step_each(gravity, self.damping, yp, coriolis, tau_f, U, r_prev, p, p0, integral_prev,
                                         self.T, self.gain, integral, r)
            self._integral, self._r = integral, r
        self._prev = Y           # read-only: kept without a copy
        return self._r

    def _friction(self, V: np.ndarray) -> np.ndarray:
        """τ̂_f(q̇) of each run (a, n) as :meth:`~robofdi.models.friction.JointFriction.torque` takes it: its kernels
        around NumPy's tanh and exp, here on one contiguous (a, n) block each — elementwise, each row's bits
        (checked in the tests, thousands of random rows)."""
        a, n = V.shape[0], self.n
        coulomb, stribeck, viscous, offset, smoothing, stribeck_velocity = self.friction
        arguments, out = np.empty((2, a, n)), np.empty((a, n))
        friction_model._friction_arguments_each(V, smoothing, stribeck_velocity, arguments)
        friction_model._friction_sum_each(np.tanh(arguments[0]), np.exp(arguments[1]), V, coulomb, stribeck, viscous,
                                          offset, out)
        return out


# ----------------------------------------------------------------------------------------------------------
class _BatchPayloadRegressor:
    """:class:`~robofdi.observers.payload.PayloadRegressor` over N runs: LP(Y) (a, n) [N·m/kg], the momentum
    residual (eq. (10)) of each run's unit point mass at its payload point with no applied torque. The Pinocchio
    calls are each run's own, on its regressor's model and data, in the single form's order; the rest one call for
    all runs."""

    def __init__(self, regressors: Sequence[PayloadRegressor]):
        first = regressors[0]
        self.n, self.T, self.gain = first.n, first.T, first.gain
        self.units = [(p.model, p.data) for p in regressors]
        self.nominals = [p._nominal for p in regressors]
        self.plain = not any(p._nominal._has_ref for p in regressors)     # Pinocchio's configurations are the q rows
        self.zeros = np.zeros((len(regressors), self.n))       # no applied torque, no damping
        self.lower = np.tril_indices(self.n, -1)
        self.reset()

    def reset(self) -> None:
        self._prev = None        # (Y, each run's Pinocchio configuration) of the last sample
        self._p0 = self._integral = self._r = None

    def step(self, Y: np.ndarray) -> np.ndarray:
        n, a, prev = self.n, Y.shape[0], self._prev
        Q = Y[:, :n] if self.plain else [nominal._q(q) for nominal, q in zip(self.nominals, Y[:, :n])]
        M = np.empty((a, n, n))
        if prev is None:
            for (model, data), q, m in zip(self.units, Q, M):
                m[:] = pin.crba(model, data, q)
        else:                    # each run's calls in the single form's order: crba(q_k), then at q_{k−1}, q̇_{k−1}
            Y_prev, gravity, C = _first(prev[0], a), np.empty((a, n)), np.empty((a, n, n))
            for (model, data), q, q1, v1, m, g, c in zip(self.units, Q, prev[1], Y_prev[:, n:], M, gravity, C):
                m[:] = pin.crba(model, data, q)
                g[:] = pin.computeGeneralizedGravity(model, data, q1)
                c[:] = pin.computeCoriolisMatrix(model, data, q1, v1)
        M[:, self.lower[0], self.lower[1]] = M[:, self.lower[1], self.lower[0]]      # mirror_upper: copies, the same bits
        p = _stacked(M, Y[:, n:])
        if prev is None:
            self._p0, self._integral, self._r = p, np.zeros((a, n)), np.zeros((a, n))
        else:
            coriolis = _stacked(C.transpose(0, 2, 1), Y_prev[:, n:])
            integral, r = np.empty((a, n)), np.empty((a, n))
            momentum._momentum_step_each(gravity, self.zeros, Y_prev, coriolis, None, self.zeros, self._r[:a], p,
                                         self._p0[:a], self._integral[:a], self.T, self.gain, integral, r)
            self._integral, self._r = integral, r
        self._prev = (Y, Q)
        return self._r


class BatchConsistencyResidual(BatchDiagnoser):
    """:class:`~robofdi.observers.consistency.ConsistencyResidual` over N runs: the friction-compensated momentum
    residual (De Luca & Mattone eq. (10)) with the carried payload, the operating point (ν, the features' low pass,
    the dynamic and step bounds), the kinematic consistency (:mod:`robofdi.observers.kinematic`), then the dynamic,
    kinematic, step and payload rows — each run's by the single form's kernels.

    Shared by the runs: T, K_O, the kinematic windows and the number of ripple orders; per run: the nominal model
    (and its payload point's unit model) and the design calibrated for its robot instance — friction, envelope,
    skew, window scales and reach, ripple, impulse weight, step, gain, trend, move and repeat scales, the carried
    payload."""

    def __init__(self, residuals: Sequence[ConsistencyResidual]):
        first = residuals[0]
        self.n, self.T, self.N, self.gain = first.n, first.T, len(residuals), first.design.gain
        self.hold, self.single, self.alpha, self.lam = first._hold, first._single, first._a, first._gain_lambda
        self.trend_samples = first._trend_samples
        self.sizes = first._kinematic._sizes
        self.evaluations = batch_evaluations([d.model for d in residuals])
        self._momentum = BatchMomentumObserver([d._momentum for d in residuals])
        self._payload = _BatchPayloadRegressor([d._payload for d in residuals])
        kinematics = [d._kinematic for d in residuals]

        def stacked(values):
            return np.ascontiguousarray(np.array(values, dtype=float))

        self.envelope, self.step_scale = (stacked([d.design.envelope for d in residuals]),
                                          stacked([d.design.step_scale for d in residuals]))
        self.skew, self.scales, self.reach = (stacked([k.skew for k in kinematics]), stacked([k.scales for k in kinematics]),
                                              stacked([k._reach for k in kinematics]))
        self.bounded = np.array([k.reach is not None for k in kinematics])
        self.orders, self.ripple, self.ripple_load = (stacked([k.orders for k in kinematics]),
                                                      stacked([k.ripple for k in kinematics]),
                                                      stacked([k.ripple_load for k in kinematics]))
        self.weight, self.move = stacked([d._impulse_weight for d in residuals]), stacked([d._move for d in residuals])
        self.gain_scale, self.trend_scale = (stacked([d._gain_scale for d in residuals]),
                                             stacked([d._trend_scale for d in residuals]))
        self.held_kinematic = stacked([d._held_kinematic for d in residuals])
        self.carried = np.array([d._carried for d in residuals])[:, None]
        self.reset()

    @classmethod
    def of(cls, residuals: Sequence[ConsistencyResidual]) -> BatchConsistencyResidual | None:
        """The batch form, or None when the shared settings differ (or a momentum observer without friction)."""
        if any(d._momentum.friction is None for d in residuals):
            return None
        shared = [[d.n for d in residuals], [d.T for d in residuals], [d.design.gain for d in residuals],
                  [tuple(d.design.windows) for d in residuals], [d._kinematic.orders.shape[1] for d in residuals]]
        return cls(residuals) if all(_same(values) for values in shared) else None

    def reset(self) -> None:
        N, n = self.N, self.n
        self._active, self._k, self._prev = N, 0, None
        self._momentum.reset()
        self._payload.reset()
        # the single form's state of every run, as its reset() leaves it (ConsistencyResidual.reset)
        self._features = np.zeros((N, n, 4))
        self._state = np.zeros((N, 4, n))
        self._state[:, 3] = -1e9
        self._previous = np.zeros((N, 3, n))
        self._steps, self._jumps = np.zeros((N, self.hold, n)), np.zeros((N, self.hold, n))
        self._gain_sums = np.zeros((N, consistency.gain_rows(self.T), n))
        self._gain_sums[:, consistency.Q_LAST] = self._gain_sums[:, consistency.Q_BEFORE] = np.nan
        self._gain, self._trend = np.zeros((N, n)), np.zeros((N, n))
        self._trend_ring, self._trend_sums = np.zeros((N, 4 * self.trend_samples, n)), np.zeros((N, 4, n))
        self._history = np.zeros((N, int(self.sizes.max()) + 1, 3 + 4 * self.orders.shape[2], n))
        self._outside, self._outside_samples = np.zeros((N, n), dtype=bool), np.zeros((N, n), dtype=int)

    def update(self, Y: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n, k, T = self.n, self._k, self.T
        a = self._active = _checked(Y, U, self._active, n)
        first = k == 0
        r = self._momentum.step(Y, U)
        load = self._payload.step(Y)                # LP(Y) [N·m/kg]
        carried = self.carried[:a]
        if carried.any():       # r + m LP(Y) where the run carries a payload: elementwise, each row's bits; r elsewhere
            r = np.where(carried != 0, r + carried * load, r)
        point = np.empty((a, 5, n))
        consistency._operating_point_each(Y, U, r, self.evaluations.mass_matrix_at(Y), self.weight, self._state,
                                          self._features, self.envelope, self.step_scale, self.skew, first, k, self.hold,
                                          self.alpha, self.gain, T, REST_VELOCITY, LOW_SPEED_VELOCITY, point)
        # the onset's share point[:, 3] is 0 on every joint of a run with no |ν| beyond its bound: what the single
        # form's None (no share) sums
        kin, e, scale = np.empty((a, n)), np.empty((a, n)), np.empty((a, n, self.sizes.shape[0]))
        kinematic._kinematic_step_each(Y, Y if first else _first(self._prev, a), first, T, self.skew, point[:, 3],
                                       self._history, k, self.sizes, self.scales, self.orders, self.ripple, self.reach,
                                       self.bounded, kin, e, self._outside, scale, self._outside_samples, U,
                                       self.ripple_load)
        z, estimate = np.empty((a, 3 * n + 1)), np.empty((a, 3 * n + 1))
        consistency._step_rows_each(r, point, kin, e, scale, self.single, self.skew, self.move, self._state, self._steps,
                                    self._jumps, self._previous, k % self.hold, (k - 1) % self.hold, T, z, estimate, Y,
                                    self._gain_sums, self.lam, self.gain_scale, self._gain, self._trend_ring,
                                    self._trend_sums, k, self.trend_scale, self._trend, load, self.held_kinematic)
        self._prev = Y          # read-only: kept without a copy
        self._k += 1
        return z, estimate


def batch_form(diagnosers: Sequence) -> BatchDiagnoser | None:
    """The batch form of ``diagnosers`` (one per run, freshly reset, not yet stepped), or None when they are not
    all of one supported type (exactly: a subclass may step differently) — :class:`DiagnosticObserver`,
    :class:`MomentumObserver` or :class:`ConsistencyResidual` — with the settings the batch shares (the classes'
    ``of``) — then each run is diagnosed alone."""
    kinds = {type(d) for d in diagnosers}
    if len(kinds) != 1:
        return None
    kind = kinds.pop()
    if kind is DiagnosticObserver:
        return BatchDiagnosticObserver.of(diagnosers)
    if kind is MomentumObserver:
        return BatchMomentumObserver.of(diagnosers)
    if kind is ConsistencyResidual:
        return BatchConsistencyResidual.of(diagnosers)
    return None
