"""The wheel actuator's nominal model (belief): Leuschen, Walker & Cavallaro eqs. (8)–(10).

    θ̈ = −(B_m/J_t) θ̇ + (d_m/J_t) p_l [− (d_m/J_t) p_L]                         (9), load term per ``load_model``
    ṗ_l = −(4β_e d_m/v_t) θ̇ − (4β_e C_tm/v_t) p_l + (4β_e K_f/v_t) sqrt(2(p_s − p_l)/ρ) u_v
    y = [θ̇, p_l]                                                                   (10)

Parameters are catalogue values (:data:`CATALOGUE`): the Black Bruin 404-080 ratings and nominal oil data, the
supply taken as a constant 3000 psi — not the simulated rig's (which sags, leaks more, and has other oil).
``load_model``: "none" (eq. (9) as printed: the pump's torque is missing, a bias R1 = T_l/J_t) or
"measured_pump_pressure" (the measured pump ΔP p_L enters as a known input; spec digest §3 [ERRATUM] 1).
The supply pressure p_s is a parameter; better modelling reads it from its sensor
(``NLARDesign.residual_function(measured={"p_s": "supply_pressure"})``). :func:`printed_tests` gives the chapter's
R2 and R5 exactly as printed (``r2_variant`` / ``r5_variant`` = "as_printed"), to show the errata's effect.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import sympy as sp

from robofdi.errors import RobofdiError
from robofdi.models.control_affine import ControlAffineModel

__all__ = ["HydraulicParameters", "CATALOGUE", "PSI", "hydraulic_model", "hydraulic_domain", "linearised_model", "flow_gains",
           "LOAD_MODELS", "VARIANTS", "printed_tests", "with_variants"]

PSI = 6894.757293168
LOAD_MODELS = ("none", "measured_pump_pressure")
VARIANTS = ("corrected", "as_printed")


@dataclass(frozen=True)
class HydraulicParameters:
    """Motor/valve parameters in SI units (m³/rad, kg m², N m s/rad, m³/(s Pa), Pa, m³, m², kg/m³)."""

    d_m: float = 2990.0 / 250e5          # displacement from the 2990 N m @ 250 bar rating
    J_t: float = 1.5
    B_m: float = 5.0
    C_tm: float = 1.0e-12
    beta_e: float = 1.0e9
    v_t: float = 2.0e-3
    K_f: float = 5.0e-6
    rho: float = 860.0
    p_s: float = 3000.0 * PSI

    def __post_init__(self):
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and v > 0):
                raise RobofdiError(f"HydraulicParameters: field {k!r} must be a number > 0, got {v!r}")


#: The catalogue model: ratings of the Black Bruin 404-080 and the book's 3000 psi supply (spec digest §6.1).
CATALOGUE = HydraulicParameters()


def hydraulic_model(params: HydraulicParameters = CATALOGUE, load_model: str = "measured_pump_pressure") -> ControlAffineModel:
    """Eqs. (8)–(10) as a :class:`ControlAffineModel`; inputs u_v (and the measured pump ΔP p_L per ``load_model``)."""
    if load_model not in LOAD_MODELS:
        raise RobofdiError(f"hydraulic_model: field 'load_model' must be one of {LOAD_MODELS}, got {load_model!r}")
    theta, omega, p_l, u_v, p_L = sp.symbols("theta omega p_l u_v p_L")
    d_m, J_t, B_m, C_tm, beta_e, v_t, K_f, rho, p_s = sp.symbols("d_m J_t B_m C_tm beta_e v_t K_f rho p_s", positive=True)
    values = {d_m: params.d_m, J_t: params.J_t, B_m: params.B_m, C_tm: params.C_tm, beta_e: params.beta_e,
              v_t: params.v_t, K_f: params.K_f, rho: params.rho, p_s: params.p_s}
    inputs, names, units = [u_v], ["servovalve"], ["1"]
    omega_dot = -(B_m / J_t) * omega + (d_m / J_t) * p_l
    if load_model == "measured_pump_pressure":
        omega_dot -= (d_m / J_t) * p_L
        inputs.append(p_L)
        names.append("pump_pressure")
        units.append("Pa")
    p_dot = (-(4 * beta_e * d_m / v_t) * omega - (4 * beta_e * C_tm / v_t) * p_l
             + (4 * beta_e * K_f / v_t) * sp.sqrt(2 * (p_s - p_l) / rho) * u_v)
    return ControlAffineModel.from_equations(
        [theta, omega, p_l], inputs, [omega, omega_dot, p_dot], [omega, p_l], values,
        output_names=("shaft_speed", "load_pressure"), input_names=tuple(names),
        output_units=("rad/s", "Pa"), input_units=tuple(units), name=f"hydraulic[{load_model}]")


def hydraulic_domain(model: ControlAffineModel) -> dict:
    """Where eqs. (8)–(10) are valid and generic: u_v > 0, p_l < p_s (spec digest §3 [ERRATUM] 2)."""
    by = {str(s): s for s in (*model.states, *model.inputs)}
    dom = {by["omega"]: (0.1, 2.0), by["p_l"]: (1e5, 5e6), by["u_v"]: (0.01, 0.5), by["theta"]: (0.0, 6.0)}
    if "p_L" in by:
        dom[by["p_L"]] = (0.0, 3e6)
    return dom


def flow_gains(params: HydraulicParameters, u0: float, p0: float) -> tuple[float, float, float]:
    """(Q0, k_q, k_c) of the symmetric valve law Q = K_f u sqrt(2(p_s − sgn(u) p)/ρ) linearised at (u0, p0):
    Q ≈ Q0 + k_q (u − u0) − k_c (p − p0) — digest §5.1 (u0 = 0 takes the book's one-sided form)."""
    s = 1.0 if u0 >= 0 else -1.0
    phi = float(np.sqrt(2 * max(params.p_s - s * p0, 1.0) / params.rho))
    return params.K_f * u0 * phi, params.K_f * phi, params.K_f * abs(u0) / (params.rho * phi)


def linearised_model(params: HydraulicParameters = CATALOGUE, u0: float = 0.0, p0: float = 0.0,
                     load_model: str = "measured_pump_pressure") -> ControlAffineModel:
    """Eqs. (8)–(10) with the valve law linearised at (u0, p0): M = k_c + C_tm replaces C_tm (linear AR's model)."""
    theta, omega, p_l, u_v, p_L = sp.symbols("theta omega p_l u_v p_L")
    Q0, kq, kc = flow_gains(params, u0, p0)
    P = params
    omega_dot = -(P.B_m / P.J_t) * omega + (P.d_m / P.J_t) * p_l
    inputs, names, units = [u_v], ["servovalve"], ["1"]
    if load_model == "measured_pump_pressure":
        omega_dot -= (P.d_m / P.J_t) * p_L
        inputs.append(p_L)
        names.append("pump_pressure")
        units.append("Pa")
    p_dot = 4 * P.beta_e / P.v_t * (-P.d_m * omega - (P.C_tm + kc) * p_l + Q0 - kq * u0 + kc * p0 + kq * u_v)
    return ControlAffineModel.from_equations(
        [theta, omega, p_l], inputs, [omega, omega_dot, p_dot], [omega, p_l], {},
        output_names=("shaft_speed", "load_pressure"), input_names=tuple(names),
        output_units=("rad/s", "Pa"), input_units=tuple(units), name=f"hydraulic-linear@({u0:.3g},{p0:.3g})")


def printed_tests(design) -> dict:
    """The chapter's R2 (16) and R5 (19) exactly as printed, in the design's measured symbols: R2 without the valve
    term, R5 with sqrt(2(p_s − y2)/ρ) where sqrt(2/(ρ(p_s − y2))) belongs (digest §4.3 [ERRATUM]). Load terms of
    ``load_model="measured_pump_pressure"`` are added as in the digest's R2', R5'."""
    S = {str(s): s for s in design.model.params}
    B, J, d, C, b, v, K, rho, ps = (S[k] for k in ("B_m", "J_t", "d_m", "C_tm", "beta_e", "v_t", "K_f", "rho", "p_s"))
    y1, y1dd, y2, y2dd, u, ud = sp.symbols("shaft_speed shaft_speed_d2 load_pressure load_pressure_d2 servovalve "
                                          "servovalve_d1")
    phi = sp.sqrt(2 * (ps - y2) / rho)
    R2 = -y1dd + (B**2 / J**2 - 4 * b * d**2 / (J * v)) * y1 + (-B * d / J**2 - 4 * b * d * C / (J * v)) * y2
    R5 = (-y2dd + (4 * B * b * d / (J * v) + 16 * b**2 * d * C / v**2 + 8 * b**2 * d * K / v**2 * phi * u) * y1
          + (-4 * b * d**2 / (J * v) + 16 * b**2 * C**2 / v**2 + 8 * b**2 * K * C / v**2 * phi * u) * y2
          - 16 * b**2 * K * C / v**2 * phi * u - 16 * b**2 * K**2 * u**2 / (rho * v**2) + 4 * b * K / v * phi * ud)
    if "pump_pressure" in design.model.input_names:
        pL, pLd = sp.symbols("pump_pressure pump_pressure_d1")
        R2 += B * d / J**2 * pL - d / J * pLd
        R5 += 4 * b * d**2 / (v * J) * pL
    return {"R2": R2, "R5": R5}


def with_variants(design, r2_variant: str = "corrected", r5_variant: str = "corrected"):
    """The design with R2 / R5 replaced by the printed forms where asked ("corrected" = the engine's, the default)."""
    import dataclasses

    for name, value in (("r2_variant", r2_variant), ("r5_variant", r5_variant)):
        if value not in VARIANTS:
            raise RobofdiError(f"with_variants: field {name!r} must be one of {VARIANTS}, got {value!r}")
    printed = printed_tests(design)
    tests = dict(design.tests)
    if r2_variant == "as_printed":
        tests["R2"] = printed["R2"]
    if r5_variant == "as_printed":
        tests["R5"] = printed["R5"]
    return dataclasses.replace(design, tests=tests)
