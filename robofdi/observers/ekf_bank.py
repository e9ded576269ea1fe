"""Bank of extended Kalman filters on the horizontal motion — the Roby 2 scheme of Antonelli's survey (Sec. 4,
refs. [2, 3]): one EKF per hypothesis (H_0 nominal, H_j thruster j's thrust replaced
by 0), each fed the thrust demands through the nominal thruster model (as in [19]); the hypothesis whose
innovations stay white wins.

Planar model (Fossen's 3-DOF horizontal model about the body origin, relative-velocity damping)::

    m_11 u̇ = X_T + m_22 v r − (X_u + X_uu |u_r|) u_r
    m_22 v̇ = Y_T − m_11 u r − (Y_v + Y_vv |v_r|) v_r
    m_66 ṙ = N_T − (N_r + N_rr |r|) r,        ψ̇ = r,        ċ = 0 (random walk)

with [u_r, v_r] = [u, v] − R(ψ)ᵀ c, c the world-frame ocean current (two states: without them, the current's drag
is a persistent bias that the innovations cannot whiten). [X_T, Y_T, N_T] = B_h T̂, B_h the X, Y, N rows of the
thruster matrix over the horizontal thrusters and ``T̂ = c |Ω̂|Ω̂`` from the nominal motor driven by the commanded
voltage. Measurements: DVL u, v, gyro r and compass ψ (the digest's [u, r, ψ] plus the sway the vehicle has).

Residual of the bank: the windowed normalised innovation squared of every filter, NIS_j = mean over W of
νᵀ S⁻¹ ν (dimensionless, χ²(m W/T)/(W/T) when the filter is consistent). :class:`robofdi.decision.NisBankDecision`
declares H_j when NIS_0 exceeds its χ² 99 % bound and NIS_j is the smallest.

Process noise Q = q · Q_unit, Q_unit = diag of (T/m_11)², (T/m_22)², (T/m_66)² (one newton / newton-metre of
unmodelled force per sample), a small kinematic ψ term and a current random walk; the force-mismatch level q [N²] is
calibrated on fault-free missions (:func:`calibrate_process_noise`), never on the test run.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.stats

from robofdi.decision import Signature
from robofdi.errors import RobofdiError
from robofdi.models.auv import AuvModel, clip
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["EkfBank", "horizontal_thrusters", "nis_bound", "calibrate_process_noise", "nominal_nis",
           "PLANAR_MEASUREMENTS", "HorizontalSensors"]

#: Measurement channels the bank reads (AuvSimulator names), in the order of its measurement vector.
PLANAR_MEASUREMENTS = ("u", "v", "r", "yaw")


class HorizontalSensors:
    """Data-sheet standard deviations of the bank's measurements (DVL [m/s], gyro [rad/s], compass [rad]) — the
    vendor's numbers, not the plant's noise settings."""

    def __init__(self, velocity: float = 0.005, rate: float = 0.002, yaw: float = np.deg2rad(0.5)):
        for name, v in (("velocity", velocity), ("rate", rate), ("yaw", yaw)):
            if not (np.isfinite(v) and v > 0):
                raise RobofdiError(f"HorizontalSensors: field {name!r} must be a standard deviation > 0, got {v!r}")
        self.sigma = np.array([velocity, velocity, rate, yaw])


def horizontal_thrusters(model: AuvModel, tol: float = 1e-6) -> list[str]:
    """The thrusters with a non-zero X, Y or N column of B (the ones the planar bank can see)."""
    cols = model.B[[0, 1, 5]]
    return [t for t, c in zip(model.thrusters, cols.T) if np.linalg.norm(c) > tol]


def nis_bound(measurements: int, window_samples: int, level: float = 0.99) -> float:
    """χ² bound of the window-mean NIS: chi2.ppf(level, m N)/N (Bar-Shalom's NIS test over N samples)."""
    if window_samples < 1 or measurements < 1 or not 0 < level < 1:
        raise RobofdiError(f"nis_bound: need m >= 1, N >= 1 and 0 < level < 1, got {measurements}, {window_samples}, {level}")
    return float(scipy.stats.chi2.ppf(level, measurements * window_samples) / window_samples)


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


class EkfBank:
    """Bank of planar EKFs (module docstring; each filter the standard EKF predict/update, Bar-Shalom, Li &
    Kirubarajan 2001, ch. 10, and its NIS test, §5.4): components ``nis_nominal`` and ``nis_<thruster>`` per
    horizontal thruster; estimate per thruster: the thrust [N] hypothesis H_j says is missing, −T̂_j (level).

    model: the nominal :class:`AuvModel`; measurements: the simulator's channel names; sample_time [s];
    process_noise q [N²] (force mismatch per sample, see :func:`calibrate_process_noise`); window W [s];
    current_walk [m/s/√s]: random walk of the current states; sensors: data-sheet noise.
    """

    def __init__(self, model: AuvModel, measurements: Sequence[str], sample_time: float, process_noise: float = 1.0,
                 window: float = 2.0, thrust_limit: float = 40.0, current_walk: float = 0.002,
                 sensors: HorizontalSensors | None = None, substeps: int = 4):
        if not (np.isfinite(sample_time) and sample_time > 0):
            raise RobofdiError(f"EkfBank: field 'sample_time' must be > 0 s, got {sample_time!r}")
        if not (np.isfinite(process_noise) and process_noise > 0):
            raise RobofdiError(f"EkfBank: field 'process_noise' must be > 0 N², got {process_noise!r}")
        if not (np.isfinite(window) and window >= sample_time):
            raise RobofdiError(f"EkfBank: field 'window' must be >= the sample time {sample_time} s, got {window!r}")
        self.model, self.T, self.thrust_limit = model, float(sample_time), float(thrust_limit)
        self.measurements, self.inputs = list(measurements), list(model.thrusters)
        try:
            self._y_index = np.array([self.measurements.index(c) for c in PLANAR_MEASUREMENTS])
        except ValueError:
            raise RobofdiError(f"EkfBank: measurements must include {list(PLANAR_MEASUREMENTS)}") from None
        self.hypotheses = horizontal_thrusters(model)
        if not self.hypotheses:
            raise RobofdiError("EkfBank: the vehicle has no horizontal thruster")
        self._h = np.array([model.thrusters.index(t) for t in self.hypotheses])
        self.B_h = model.B[[0, 1, 5]][:, self._h]
        M = model.M
        self._m = np.array([M[0, 0], M[1, 1], M[5, 5]])
        p = model.hydro
        self._lin = np.asarray(p.linear_damping, dtype=float)[[0, 1, 5]]
        self._quad = np.asarray(p.quadratic_damping, dtype=float)[[0, 1, 5]]
        self.process_noise, self.window, self.substeps = float(process_noise), float(window), int(substeps)
        self.samples = max(1, int(round(window / sample_time)))
        T = self.T
        q_unit = np.array([(T / self._m[0]) ** 2, (T / self._m[1]) ** 2, (T / self._m[2]) ** 2,
                           (T * T / self._m[2]) ** 2, 0.0, 0.0])
        walk = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 1.0]) * current_walk**2 * T
        self.Q = np.diag(self.process_noise * q_unit + walk)
        self.R = np.diag((sensors or HorizontalSensors()).sigma ** 2)
        self.H = np.hstack([np.eye(4), np.zeros((4, 2))])
        self.bound = nis_bound(4, self.samples)
        self.components = ["nis_nominal"] + [f"nis_{t}" for t in self.hypotheses]
        self.estimate_components = list(self.hypotheses)
        self.estimate_modes = ["level"] * len(self.hypotheses)
        self.units = {"residual": ["1"] * len(self.components), "estimate": ["N"] * len(self.hypotheses)}
        # hypothesis masks on the horizontal thrust: row 0 nominal, row j thruster j off
        self._mask = np.vstack([np.ones(len(self._h)), 1.0 - np.eye(len(self._h))])
        self._eye = 1e-6 * np.eye(6)[:, None, :]          # the Jacobian's steps h e_k, laid out for (6, n, 6)
        self.reset()

    # ------------------------------------------------------------------------------------------------ model
    def _f(self, X: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """One Euler step of the planar model for state columns X (6, k) and wrench tau (3,) or (3, k)."""
        u, v, r, psi, cx, cy = X
        c, s = np.cos(psi), np.sin(psi)
        ur, vr = u - (c * cx + s * cy), v - (-s * cx + c * cy)
        m11, m22, m66 = self._m
        d = lambda k, x: (self._lin[k] + self._quad[k] * np.abs(x)) * x  # noqa: E731
        tau = tau.reshape(3, -1) if np.ndim(tau) == 1 else tau
        du = (tau[0] + m22 * v * r - d(0, ur)) / m11
        dv = (tau[1] - m11 * u * r - d(1, vr)) / m22
        dr = (tau[2] - d(2, r)) / m66
        return np.stack([u + self.T * du, v + self.T * dv, r + self.T * dr, psi + self.T * r, cx, cy])

    def _jacobian(self, x: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Prediction and forward-difference Jacobian of every filter at once: states x (n, 6), wrenches tau
        (3, n) → (n, 6), (n, 6, 6). One elementwise pass over the n × 7 points (the same operations per point as
        one filter at a time, so the same numbers)."""
        h, n = 1e-6, len(x)
        X = np.empty((6, n, 7))
        X[:, :, 0] = x.T
        X[:, :, 1:] = x.T[:, :, None] + self._eye
        F = self._f(X.reshape(6, 7 * n), np.repeat(tau, 7, axis=1)).reshape(6, n, 7)
        # C-contiguous results: numpy's matmul then calls BLAS per filter as for one filter (on strided operands it
        # sums in its own loop, a rounding-level difference)
        return (np.ascontiguousarray(F[:, :, 0].T),
                np.ascontiguousarray(((F[:, :, 1:] - F[:, :, :1]) / h).transpose(1, 0, 2)))

    # ------------------------------------------------------------------------------------------------ protocol
    def reset(self) -> None:
        n = len(self._mask)
        self._x = None
        self._P = np.repeat(np.diag([1e-4, 1e-4, 1e-4, 1e-4, 0.04, 0.04])[None], n, axis=0)
        self._speed = np.zeros(len(self.model.thrusters))
        self._nis = np.zeros((self.samples, n))
        self._k = 0
        self.thrust = np.zeros(len(self._h))

    def update(self, y, u) -> Residual:
        """One sample: predict every filter with the thrust of u = ū(k−1), update with y(k); residual = windowed NIS."""
        z, u = self._measured(y, u)
        return self._filter(z, self._drive(u))

    def _measured(self, y, u) -> tuple[np.ndarray, np.ndarray]:
        """The planar measurements z of y and the thrust demand u clipped to the drivers' limit."""
        y = check_measurement(y, len(self.measurements), "y")
        return y[self._y_index], clip(check_measurement(u, len(self.inputs), "u"), -self.thrust_limit, self.thrust_limit)

    def _drive(self, u: np.ndarray) -> np.ndarray:
        """The nominal thrusters driven by the commanded voltage over one sample → the horizontal thrusters' mean
        thrust [N] (it depends on u only: calibration computes it once for every process-noise level)."""
        th = self.model.thruster
        v_cmd = th.voltage_for_thrust(u)
        h = self.T / self.substeps
        T_before = th.thrust(self._speed)[self._h]
        for _ in range(self.substeps):
            self._speed = self._speed + h * th.speed_rate(self._speed, v_cmd)
        return 0.5 * (T_before + th.thrust(self._speed)[self._h])

    def _filter(self, z: np.ndarray, thrust: np.ndarray) -> Residual:
        """Every filter's predict (with ``thrust``) and update (with z) → the windowed NIS."""
        n = len(self._mask)
        if self._x is None:
            self._x = np.tile(np.concatenate([z, [0.0, 0.0]]), (n, 1))
        self.thrust = thrust
        tau = np.empty((3, n))
        for j in range(n):
            tau[:, j] = self.B_h @ (self._mask[j] * thrust)
        # the n filters' predict/update steps, stacked (numpy's stacked matmul and solve call the same BLAS/LAPACK
        # routine per filter as one filter at a time: the same numbers, a fifth of the Python overhead)
        x_pred, F = self._jacobian(self._x, tau)
        P = F @ self._P @ F.transpose(0, 2, 1) + self.Q
        nu = z - x_pred[:, :4]
        nu[:, 3] = _wrap(nu[:, 3])
        S = P[:, :4, :4] + self.R
        K = np.linalg.solve(S, P[:, :4]).transpose(0, 2, 1)
        Sinv_nu = np.linalg.solve(S, nu[:, :, None])[:, :, 0]
        nis = np.empty(n)
        for j in range(n):
            self._x[j] = x_pred[j] + K[j] @ nu[j]
            nis[j] = nu[j] @ Sinv_nu[j]
        self._x[:, 3] = _wrap(self._x[:, 3])
        self._P = P - K @ S @ K.transpose(0, 2, 1)
        self._nis[self._k % self.samples] = nis
        self._k += 1
        windowed = self._nis[: min(self._k, self.samples)].mean(axis=0)
        return Residual(windowed, -thrust)

    def current_estimate(self, hypothesis: int = 0) -> np.ndarray:
        """The world-frame current [m/s] estimated by filter ``hypothesis`` (0: nominal)."""
        return np.zeros(2) if self._x is None else self._x[hypothesis, 4:].copy()

    def signatures(self):
        return [Signature(t, frozenset([f"nis_{t}"])) for t in self.hypotheses]


def nominal_nis(bank: EkfBank, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The nominal filter's windowed NIS over one run's (y, u) pairs (rows as :func:`robofdi.loop.diagnoser_inputs`).
    ``bank`` is used up: only its nominal filter is kept (the fault filters play no part in calibration)."""
    return _nominal_nis_of(bank, _drives(bank, y, u))


def _drives(bank: EkfBank, y: np.ndarray, u: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(z, thrust) per sample of one run: what :meth:`EkfBank.update` feeds its filters (independent of q)."""
    bank.reset()
    out = []
    for yk, uk in zip(y, u):
        z, uc = bank._measured(yk, uk)
        out.append((z, bank._drive(uc)))
    return out


def _nominal_nis_of(bank: EkfBank, drives, Q: np.ndarray | None = None) -> np.ndarray:
    """The nominal filter's windowed NIS from one run's (z, thrust) pairs (:func:`_drives`, computed once for every
    process-noise level); ``bank`` keeps only its nominal filter. With ``Q`` (k, 6, 6): k nominal filters, one per
    process-noise matrix, stepped together → (samples, k); each column equals that filter alone to rounding (a
    (W, k) window's mean sums row by row, a (W, 1) one pairwise)."""
    bank._mask = bank._mask[:1] if Q is None else np.ones((len(Q), bank._mask.shape[1]))
    if Q is not None:
        bank.Q = Q
    bank.reset()
    nis = np.array([bank._filter(z, thrust).r for z, thrust in drives])
    return nis[:, 0] if Q is None else nis


def _bisection_midpoints(lo: float, hi: float, depth: int) -> dict[tuple[float, float], float]:
    """Every midpoint bisection on [lo, hi] can visit in its next ``depth`` steps, keyed by its interval, computed
    as bisection computes it (0.5 (a + b)), so a search that evaluates them together ends where bisection ends."""
    mids, level = {}, [(lo, hi)]
    for _ in range(depth):
        nxt = []
        for a, b in level:
            mids[(a, b)] = m = 0.5 * (a + b)
            nxt += [(a, m), (m, b)]
        level = nxt
    return mids


def calibrate_process_noise(runs, make_bank, skip: int, margin: float = 1.25, bounds=(1e-3, 1e4),
                            iterations: int = 8, depth: int = 3) -> float:
    """The force-mismatch level q [N²] of :class:`EkfBank` from fault-free runs ``runs`` = [(y, u), ...] (as
    :func:`robofdi.loop.diagnoser_inputs`): the smallest q (bisection in log q) for which the nominal filter's
    windowed NIS stays below bound/margin on every run after ``skip`` samples. ``make_bank(q)`` builds the bank.
    The bisection's next ``depth`` steps are evaluated in one pass over the runs (the 2^depth − 1 midpoints they can
    visit, as stacked nominal filters), so ``iterations`` steps take ⌈iterations/depth⌉ passes, not ``iterations``;
    the midpoints and the decisions are the bisection's (the stacked NIS equal each filter's alone to rounding)."""
    if not (isinstance(depth, int) and depth >= 1):
        raise RobofdiError(f"calibrate_process_noise: field 'depth' must be an integer >= 1, got {depth!r}")
    drives = [_drives(make_bank(bounds[1]), y, u) for y, u in runs]

    def peaks(log_qs) -> dict[float, float]:
        banks = [make_bank(np.exp(x)) for x in log_qs]
        Q = np.stack([b.Q for b in banks])
        worst = np.max([_nominal_nis_of(banks[0], d, Q)[skip:].max(axis=0) for d in drives], axis=0)
        return dict(zip(log_qs, worst / banks[0].bound))

    lo, hi = np.log(bounds[0]), np.log(bounds[1])
    for start in range(0, max(iterations, 1), depth):         # iterations = 0: the check of the upper bound only
        steps = min(depth, iterations - start)
        mids = _bisection_midpoints(lo, hi, steps)
        peak = peaks(([hi] if start == 0 else []) + list(mids.values()))
        if start == 0 and peak[hi] * margin > 1:
            raise RobofdiError(f"calibrate_process_noise: even q = {bounds[1]:g} N² leaves the fault-free NIS above "
                               "the χ² bound; the nominal model misses something")
        for _ in range(steps):
            mid = mids[(lo, hi)]
            if peak[mid] * margin > 1:
                lo = mid
            else:
                hi = mid
    return float(np.exp(hi))
