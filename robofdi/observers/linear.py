"""Observer-based residual generation for discrete linear models, with fault signatures from DC gains.

Luenberger observer residual (fault detection filter with V = I — Ding, *Model-based Fault Diagnosis Techniques*,
2nd ed. 2013, Sec. 5.1; Chen & Patton 1999, Ch. 2), on the nominal (belief) model:

    x̂(k+1) = A x̂(k) + B u(k) + L r(k),        r(k) = y(k) − C x̂(k) − D u(k−1)

With the plant convention of :class:`robofdi.sims.linear.LinearPlant` (y(k) = C x(k) + D u(k−1) + v), a fault f
held from some sample on drives the residual through the error dynamics e(k+1) = (A − LC) e + F f, r = C e + H f:

    actuator j (u_applied = u + f e_j):  F = (B − LD) e_j,  H = D e_j   →  G_a(1) = C (I − A + LC)⁻¹ (B − LD) + D
    sensor j   (y = C x + D u + f e_j):  F = −L e_j,        H = e_j     →  G_s(1) = I − C (I − A + LC)⁻¹ L
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.signal

from robofdi.errors import RobofdiError, all_finite
from robofdi.models.linear import (
    LinearModel, covariance_factor, format_mode, require_discrete, unobservable_modes, vector_field,
)
from robofdi.observers.residual import Residual, check_measurement

__all__ = ["ObserverResidual", "observer_gain_poles", "observer_gain_kalman", "spectral_radius"]

#: Default share of the largest (scaled) DC gain that makes a residual component *required* in a signature.
REQUIRED_FRACTION = 0.3
#: A gain below this share of the hypothesis' largest gain counts as zero (not even *allowed*).
ZERO_GAIN = 1e-6
#: Longest step response simulated for the peak (transient) gains, in samples.
MAX_HORIZON = 20000


def spectral_radius(M: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M)))) if M.size else 0.0


def _check_detectable(model: LinearModel, where: str, need_observable: bool = False) -> None:
    modes = unobservable_modes(model.A, model.C)
    unstable = [lam for lam in modes if abs(lam) >= 1.0 - 1e-12]
    if unstable:
        raise RobofdiError(f"{where}: (A, C) is not detectable: mode λ={format_mode(unstable[0])} unobservable")
    if need_observable and modes:
        raise RobofdiError(
            f"{where}: (A, C) is not observable: mode λ={format_mode(modes[0])} unobservable; pole placement moves every "
            "mode (use observer_gain_kalman for a detectable pair)"
        )


def _check_stable_observer(model: LinearModel, L: np.ndarray, where: str) -> None:
    rho = spectral_radius(model.A - L @ model.C)
    if not rho < 1.0:
        raise RobofdiError(f"{where}: the observer A − L C is not stable: spectral radius {rho:.6g}, expected < 1")


def observer_gain_poles(model: LinearModel, poles: Sequence[complex]) -> np.ndarray:
    """L (n×p) with eig(A − L C) = ``poles``: scipy.signal.place_poles (Tits & Yang, IEEE TAC 41(10), 1996) on the
    dual pair (Aᵀ, Cᵀ), L = Kᵀ. Poles: n values strictly inside the unit circle, complex ones in conjugate pairs."""
    where = "observer_gain_poles"
    model = require_discrete(model, where, "diagnosis")
    try:
        p = np.array(poles, dtype=complex).ravel()
    except (TypeError, ValueError):
        raise RobofdiError(f"{where}: field 'poles' must be {model.n} numbers, got {poles!r}") from None
    if p.shape != (model.n,) or not np.all(np.isfinite(p)):
        raise RobofdiError(f"{where}: field 'poles' must be {model.n} finite values (one per state), got {poles!r}")
    if np.any(np.abs(p) >= 1.0):
        raise RobofdiError(f"{where}: field 'poles' must lie inside the unit circle (|p| < 1), got {p[np.abs(p) >= 1][0]}")
    _check_detectable(model, where, need_observable=True)
    if np.all(np.abs(p.imag) < 1e-14):
        p = p.real
    try:
        result = scipy.signal.place_poles(model.A.T, model.C.T, p)
    except ValueError as exc:
        raise RobofdiError(f"{where}: field 'poles' cannot be placed: {exc}") from None
    L = np.real(result.gain_matrix.T)
    _check_stable_observer(model, L, where)
    return L


def observer_gain_kalman(model: LinearModel, process_noise, measurement_noise) -> np.ndarray:
    """Steady-state Kalman predictor gain L = A P Cᵀ (C P Cᵀ + R)⁻¹, P the stabilising solution of the filter DARE
    P = A P Aᵀ − A P Cᵀ (C P Cᵀ + R)⁻¹ C P Aᵀ + Q — Anderson & Moore, *Optimal Filtering*, 1979, Sec. 4.4.

    process_noise Q: n×n (or n variances) covariance of the per-sample state noise (G Q_w Gᵀ for a noise input G);
    measurement_noise R: p×p (or p variances), positive definite.
    """
    where = "observer_gain_kalman"
    model = require_discrete(model, where, "diagnosis")
    Q, _ = covariance_factor(process_noise, model.n, "process_noise")
    R, _ = covariance_factor(measurement_noise, model.p, "measurement_noise")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise RobofdiError(f"{where}: field 'measurement_noise' must be positive definite, got eigenvalues "
                           f"{np.linalg.eigvalsh(R)}")
    _check_detectable(model, where)
    A, C = model.A, model.C
    try:
        P = scipy.linalg.solve_discrete_are(A.T, C.T, Q, R)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise RobofdiError(
            f"{where}: no stabilising Kalman gain ({exc}); every mode on the unit circle must be excited by "
            "'process_noise'"
        ) from None
    L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
    _check_stable_observer(model, L, where)
    return L


class ObserverResidual:
    """Diagnoser protocol: one residual per output (named like the outputs, in their units).

    model: the discrete nominal model (the belief, at the diagnosis period); L: n×p observer gain with A − LC stable
    (:func:`observer_gain_poles`, :func:`observer_gain_kalman`). x0: initial estimate (None: the least-squares
    x̂ = C⁺ (y − D u) of the first sample). residual_scale: per residual, the unit in which gains are compared and
    estimates weighted (typically the calibrated threshold or the sensor noise std; default 1 = own units).

    Fault hypotheses are the inputs (actuator additive faults, in input units) then the outputs (sensor additive
    faults, in output units). Identification: for each hypothesis h whose DC gain column g_h is non-zero, the
    weighted least-squares fit of the steady-state relation r ≈ g_h f — f̂_h = g_hᵀ W r / (g_hᵀ W g_h), W =
    diag(residual_scale⁻²) — a "level" estimate, exact in steady state for a constant fault on a nominal model,
    lagging by the observer's settling time after a change. Hypotheses with zero DC gain (e.g. a sensor bias on an
    integrating output, which the observer absorbs) have no estimate.
    """

    def __init__(self, model: LinearModel, L, x0=None, residual_scale=None, required_fraction: float = REQUIRED_FRACTION):
        where = "ObserverResidual"
        self.model = model = require_discrete(model, where, "diagnosis")
        n, m, p = model.n, model.m, model.p
        try:
            L = np.array(L, dtype=float)
        except (TypeError, ValueError):
            raise RobofdiError(f"{where}: field 'L' must be a numeric {n}x{p} matrix, got {L!r}") from None
        if L.shape != (n, p) or not np.all(np.isfinite(L)):
            raise RobofdiError(f"{where}: field 'L' must be a finite {n}x{p} matrix (states x outputs), got shape {L.shape}")
        _check_stable_observer(model, L, where)
        self.L = L
        if x0 is not None:
            x0 = np.array(x0, dtype=float)
            if x0.shape != (n,) or not np.all(np.isfinite(x0)):
                raise RobofdiError(f"{where}: field 'x0' must be None or a finite vector of {n} values, got {x0!r}")
        self.x0 = x0
        self.residual_scale = vector_field(residual_scale, p, "residual_scale", where, 1.0, positive=True)
        rf = required_fraction
        if isinstance(rf, bool) or not isinstance(rf, (int, float, np.floating)) or not (0 < rf <= 1):
            raise RobofdiError(f"{where}: field 'required_fraction' must be in (0, 1], got {rf!r}")
        self.required_fraction = float(rf)

        self.inputs = list(model.input_names)
        self.measurements = list(model.output_names)
        self.components = list(model.output_names)
        self.hypotheses = self.inputs + self.measurements
        A, B, C, D = model.A, model.B, model.C, model.D
        Acl = A - L @ C
        self._F = np.hstack([B - L @ D, -L])                 # n × (m+p): fault input of the error dynamics
        self._H = np.hstack([D, np.eye(p)])                  # p × (m+p): fault feedthrough to r
        self._Acl = Acl
        self.dc_gain = C @ np.linalg.solve(np.eye(n) - Acl, self._F) + self._H   # [G_a(1) | G_s(1)], p × (m+p)
        self._peak = None
        top = self.peak_gain().max(axis=0)
        self._estimated = [h for h in range(m + p) if top[h] > 0 and np.abs(self.dc_gain[:, h]).max() > ZERO_GAIN * top[h]]
        self.estimate_components = [self.hypotheses[h] for h in self._estimated]
        self.estimate_modes = ["level"] * len(self._estimated)
        W = 1.0 / self.residual_scale**2
        G = self.dc_gain[:, self._estimated]
        self._projection = (G * W[:, None]).T / np.maximum(np.einsum("ih,i,ih->h", G, W, G), 1e-300)[:, None]
        units_u, units_y = list(model.units["u"]), list(model.units["y"])
        hyp_units = units_u + units_y
        self.units = {"residual": units_y, "estimate": [hyp_units[h] for h in self._estimated]}
        self.reset()

    def reset(self) -> None:
        self._x = None
        self._innovation = None

    @property
    def state_estimate(self) -> np.ndarray | None:
        """x̂(k) of the last update (None before the first)."""
        return None if self._x is None else self._x.copy()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y = y(k) measured now, u = ū(k−1) held over the interval that ended at k; the first call initialises."""
        md = self.model
        y = check_measurement(y, md.p, "y")
        u = check_measurement(u, md.m, "u")
        if self._x is None:
            self._x = self.x0.copy() if self.x0 is not None else np.linalg.lstsq(md.C, y - md.D @ u, rcond=None)[0]
            self._innovation = y - md.C @ self._x - md.D @ u
            return Residual(np.zeros(md.p), np.zeros(len(self._estimated)))
        self._x = md.A @ self._x + md.B @ u + self.L @ self._innovation
        r = y - md.C @ self._x - md.D @ u
        if not all_finite(r):
            raise RobofdiError("ObserverResidual: the residual diverged (non-finite); check the model and gain 'L'")
        self._innovation = r
        return Residual(r.copy(), self._projection @ r)

    def peak_gain(self) -> np.ndarray:
        """max_k |r(k)| of the unit step response of each hypothesis (p × (m+p)): the transient gain, simulated over
        the observer's settling horizon (until ρ(A − LC)^k < 1e-6, at most MAX_HORIZON samples)."""
        if self._peak is None:
            rho = spectral_radius(self._Acl)
            settle = np.ceil(np.log(1e-6) / np.log(max(rho, 1e-12))) if rho < 1 - 1e-12 else MAX_HORIZON
            horizon = int(min(MAX_HORIZON, 2 + settle))
            E = np.zeros_like(self._F)
            peak = np.zeros_like(self.dc_gain)
            C = self.model.C
            for _ in range(horizon):
                np.maximum(peak, np.abs(C @ E + self._H), out=peak)
                E = self._Acl @ E + self._F
            self._peak = np.maximum(peak, np.abs(self.dc_gain))
        return self._peak

    def _scaled(self, scale):
        s = self.residual_scale if scale is None else vector_field(scale, self.model.p, "scale", "signatures", 1.0, positive=True)
        return np.abs(self.dc_gain) / s[:, None], self.peak_gain() / s[:, None]

    def signatures(self, scale=None, required_fraction: float | None = None) -> list:
        """One :class:`robofdi.decision.Signature` per detectable hypothesis (inputs, then outputs).

        Gains are compared in units of ``scale`` (default: ``residual_scale``; pass the calibrated threshold so that
        "substantial" means "crosses its threshold with the others"). required: components whose scaled DC gain
        is at least ``required_fraction`` (default 0.3) of the hypothesis' largest; if every DC gain is zero (the
        observer absorbs the fault in steady state) the peak transient gains are used instead. allowed: the other
        components with a non-zero (> 1e-6 of the largest) DC or transient gain.
        A hypothesis with no gain at all is undetectable and gets no signature (see :meth:`undetectable`).
        Hypotheses with equal required sets are not isolable from each other by a threshold decision: they are all
        returned (:meth:`ambiguity_groups` lists them) and :class:`ThresholdDecision` picks the strongest.
        """
        from robofdi.decision import Signature

        frac = self.required_fraction if required_fraction is None else required_fraction
        if isinstance(frac, bool) or not isinstance(frac, (int, float, np.floating)) or not (0 < frac <= 1):
            raise RobofdiError(f"signatures: field 'required_fraction' must be in (0, 1], got {frac!r}")
        dc, peak = self._scaled(scale)
        out = []
        for h, name in enumerate(self.hypotheses):
            top = peak[:, h].max()
            if top <= 0:
                continue
            basis = dc[:, h] if dc[:, h].max() > ZERO_GAIN * top else peak[:, h]
            required = {c for c, g in zip(self.components, basis) if g >= frac * basis.max()}
            allowed = {c for c, g, gp in zip(self.components, dc[:, h], peak[:, h])
                       if max(g, gp) > ZERO_GAIN * top} - required
            out.append(Signature(name, frozenset(required), frozenset(allowed)))
        return out

    def undetectable(self) -> list[str]:
        """Hypotheses whose fault never reaches the residual (zero transient and DC gain)."""
        peak = self.peak_gain()
        return [name for h, name in enumerate(self.hypotheses) if peak[:, h].max() <= 0]

    def ambiguity_groups(self, scale=None, required_fraction: float | None = None) -> list[tuple[str, ...]]:
        """Groups (≥ 2) of hypotheses whose signatures have the same required set: not isolable from each other."""
        groups: dict[frozenset, list[str]] = {}
        for s in self.signatures(scale, required_fraction):
            groups.setdefault(s.required, []).append(s.fault)
        return [tuple(v) for v in groups.values() if len(v) > 1]
