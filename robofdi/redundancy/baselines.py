"""Baselines for NLAR (Leuschen, Walker & Cavallaro, Sec. 9): linear AR on the linearised model, piecewise-linear
AR (PLAR, nine regions of the valve-position / load-pressure workspace, blended near borders), the book's NNAR
(the linear AR null space applied to the nonlinear equations, :mod:`robofdi.redundancy.nnar`), and a data-driven
baseline that is not from the chapter, ``mlp_ar`` (a neural predictor of the model equations, scikit-learn's
MLPRegressor, trained on fault-free data)."""
from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import sympy as sp

from robofdi.errors import RobofdiError
from robofdi.models.hydraulic import HydraulicParameters, linearised_model
from robofdi.redundancy.derivatives import SavitzkyGolay, estimate_derivatives
from robofdi.redundancy.nlar import derive_nlar
from robofdi.redundancy.nnar import derive_nnar
from robofdi.redundancy.residuals import RedundancyResidual, SignalMap, nlar_residual

__all__ = ["linear_ar_design", "linear_ar_residual", "plar_regions", "plar_residual", "plar_classes", "nnar_design",
           "nnar_residual", "train_mlp_ar", "MLPARResidual", "smoothstep_weights",
           "plar_flow_error"]

_LINEAR_DOMAIN = {sp.Symbol("omega"): (0.1, 2.0), sp.Symbol("p_l"): (1e5, 5e6)}


@lru_cache(maxsize=32)
def linear_ar_design(params: HydraulicParameters, u0: float, p0: float):
    """The linear AR design (continuous parity space, Chow & Willsky): the NLAR engine on the model linearised at
    (u0, p0). Cached per (params, u0, p0): the symbolic derivation takes ~2 s, and PLAR needs nine of them per
    diagnoser built (the design is shared between callers: read it, do not modify it)."""
    return derive_nlar(linearised_model(params, u0, p0), _LINEAR_DOMAIN)


def linear_ar_residual(params: HydraulicParameters, u0: float, p0: float, measurements, inputs,
                       flt: SavitzkyGolay) -> RedundancyResidual:
    """Linear AR (continuous parity space, Chow & Willsky) — the NLAR engine on the model linearised at (u0, p0)."""
    return nlar_residual(linear_ar_design(params, u0, p0), measurements, inputs, flt)


def nnar_design(design, params: HydraulicParameters, u0: float, p0: float):
    """The book's NNAR (Sec. 9): the null space Ω of linear AR at (u0, p0) applied to the nonlinear equations of
    ``design`` (an NLAR design of :func:`robofdi.models.hydraulic.hydraulic_model`); on this rig its tests equal
    NLAR's (Sec. 5 footnote; :func:`robofdi.redundancy.nnar.derive_nnar`)."""
    return derive_nnar(design, linear_ar_design(params, u0, p0))


def nnar_residual(design, measurements, inputs, flt: SavitzkyGolay, signatures=()) -> RedundancyResidual:
    """The NNAR tests of :func:`nnar_design` as a Diagnoser."""
    return nlar_residual(design, measurements, inputs, flt, signatures)


def plar_regions(params: HydraulicParameters) -> list[tuple[float, float]]:
    """Centres (u, p) of the nine equal regions of u ∈ [−1, 1] × p ∈ [−p_s, p_s] (Sec. 9, Fig. 10)."""
    c = (-2 / 3, 0.0, 2 / 3)
    return [(u, p * params.p_s) for u in c for p in c]


def plar_classes(params: HydraulicParameters, symmetry: str = "point5") -> int:
    """Symmetry classes of the nine regions, i.e. the linearisations needed: "book4" (gains depend on |u|, |p|
    only — the book's count) or "point5" (the symmetric valve law is only point-symmetric, Q(−u, −p) = −Q(u, p);
    digest §5.1 [RECON]). :func:`plar_residual` linearises all nine centres directly."""
    if symmetry not in ("book4", "point5"):
        raise RobofdiError(f"plar_classes: field 'symmetry' must be 'book4' or 'point5', got {symmetry!r}")
    keys = set()
    for u, p in plar_regions(params):
        su, sp_ = int(np.sign(round(u, 9))), int(np.sign(round(p, 3)))
        if symmetry == "book4":
            keys.add((abs(su), abs(sp_)))
        else:                                        # orbit {(u, p), (−u, −p)}: its lexicographically larger member
            keys.add(max((su, sp_), (-su, -sp_)))
    return len(keys)


def smoothstep_weights(x: float, centres: Sequence[float], width: float, band: float = 0.1) -> np.ndarray:
    """Weights of the cells along one axis: 1 in the cell, smoothstep blend over ±band·width around each border."""
    c = np.asarray(centres, dtype=float)
    w = np.zeros(c.size)
    i = int(np.clip(np.argmin(np.abs(c - x)), 0, c.size - 1))
    w[i] = 1.0
    half = band * width
    for j in (i - 1, i + 1):
        if 0 <= j < c.size:
            border = 0.5 * (c[i] + c[j])
            dist = abs(x - border)                            # distance into cell i from that border
            if dist < half:
                z = (dist + half) / (2 * half)                  # 0.5 at the border, 1 at the band's inner edge
                own = z * z * (3 - 2 * z)
                w[j], w[i] = 1.0 - own, own
    return w


def plar_flow_error(params: HydraulicParameters, u: float, p: float, band: float = 0.1) -> float:
    """PLAR's own model error at (u, p) [m³/s]: the blended linearised valve flow (Sec. 9; weights of
    :func:`smoothstep_weights`, the linearisations of :func:`~robofdi.models.hydraulic.flow_gains`) less the valve
    law Q = K_f u sqrt(2(p_s − sgn(u) p)/ρ) of eq. (10). At steady state on the exact model, PLAR's pressure test
    R4 equals (4β_e/v_t) times this. (The centre column, u₀ = 0, is linearised in the one-sided form of
    :func:`~robofdi.models.hydraulic.flow_gains`, so for u < 0 there the error includes the sgn(u) term.)"""
    from robofdi.models.hydraulic import flow_gains

    uc = (-2 / 3, 0.0, 2 / 3)
    pc = tuple(x * params.p_s for x in uc)
    wu, wp = smoothstep_weights(u, uc, 2 / 3, band), smoothstep_weights(p, pc, 2 * params.p_s / 3, band)
    q = 0.0
    for i in np.flatnonzero(wu):
        for j in np.flatnonzero(wp):
            q0, kq, kc = flow_gains(params, uc[i], pc[j])
            q += wu[i] * wp[j] * (q0 + kq * (u - uc[i]) - kc * (p - pc[j]))
    s = 1.0 if u >= 0 else -1.0
    return float(q - params.K_f * u * np.sqrt(2 * max(params.p_s - s * p, 0.0) / params.rho))


def plar_residual(params: HydraulicParameters, measurements, inputs, flt: SavitzkyGolay,
                  band: float = 0.1) -> RedundancyResidual:
    """PLAR: one linear AR per region, the test of the region holding (u, p_l), blended near borders (Sec. 9)."""
    regions = plar_regions(params)
    parts = [linear_ar_residual(params, u, p, measurements, inputs, flt) for u, p in regions]
    first = parts[0]
    names = [n for n, _ in zip(first.signal_map.names, first.signal_map.sources)]
    args = first.signal_map.arguments
    iu = args.index((0, names.index("servovalve")))
    ip = args.index((0, names.index("load_pressure")))
    uc, pc = (-2 / 3, 0.0, 2 / 3), tuple(x * params.p_s for x in (-2 / 3, 0.0, 2 / 3))
    fns = [p.tests for p in parts]

    def tests(*a):
        wu = smoothstep_weights(a[iu], uc, 2 / 3, band)
        wp = smoothstep_weights(a[ip], pc, 2 * params.p_s / 3, band)
        out = 0.0
        for i in np.flatnonzero(wu):
            for j in np.flatnonzero(wp):
                out = out + wu[i] * wp[j] * np.asarray(fns[3 * i + j](*a))
        return out

    return RedundancyResidual(tests, first.components, first.units["residual"], measurements, inputs,
                              first.signal_map, flt, first.signatures())


# ---- mlp_ar: a data-driven baseline (not the book's NNAR) ---------------------------------------------------
_FEATURES = ("shaft_speed", "load_pressure", "servovalve", "pump_pressure")


def _features(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(N, 4) samples of the signals the model equations use: speed, load ΔP, valve command (held), pump ΔP."""
    return np.column_stack([y[:, 0], y[:, 1], np.r_[0.0, u[:-1, 0]], y[:, 2]])


def train_mlp_ar(records, flt: SavitzkyGolay, seed: int = 0, hidden=(32, 32)):
    """A data-driven predictor of (θ̈, ṗ_l) from (θ̇, p_l, u, p_L): scikit-learn MLPRegressor on fault-free records
    (inputs and targets standardised), a neural analogue of R1 and R4. Not from the chapter (its NNAR is
    :func:`nnar_design`): a model-free baseline."""
    from sklearn.compose import TransformedTargetRegressor
    from sklearn.neural_network import MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    X, T = [], []
    for rec in records:
        d = estimate_derivatives(_features(rec.signals["y_meas"], rec.signals["u_diag"]), flt)
        X.append(d[:, 0, :])
        T.append(d[:, 1, :2])
    X, T = np.vstack(X), np.vstack(T)
    net = MLPRegressor(hidden_layer_sizes=hidden, max_iter=300, early_stopping=True, random_state=seed, tol=1e-5)
    model = TransformedTargetRegressor(make_pipeline(StandardScaler(), net), transformer=StandardScaler())
    model.fit(X, T)
    return model


class MLPARResidual(RedundancyResidual):
    """Diagnoser: N1 = measured θ̈ − predicted, N4 = measured ṗ_l − predicted, the trained network evaluated by its
    own weights (scikit-learn's coefs_ / intercepts_, ReLU) for speed."""

    def __init__(self, model, measurements, inputs, flt: SavitzkyGolay):
        pipe = model.regressor_
        scaler, net = pipe[0], pipe[-1]
        tscale = model.transformer_
        mean, scale = scaler.mean_, scaler.scale_
        tmean, tsc = tscale.mean_, tscale.scale_
        weights = list(zip(net.coefs_, net.intercepts_))

        def tests(w, wd, p, pd, u, pL):
            h = (np.array([w, p, u, pL]) - mean) / scale
            for k, (W, b) in enumerate(weights):
                h = h @ W + b
                if k < len(weights) - 1:
                    h = np.maximum(h, 0.0)
            pred = h * tsc + tmean
            return (wd - pred[0], pd - pred[1])

        smap = SignalMap(["shaft_speed", "load_pressure", "servovalve", "pump_pressure"],
                         [("y", 0), ("y", 1), ("u", 0), ("y", 2)], [1, 1, 0, 0])
        super().__init__(tests, ["N1", "N4"], ["rad/s^2", "Pa/s"], measurements, inputs, smap, flt)
