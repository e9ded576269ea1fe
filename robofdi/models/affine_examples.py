"""Two more control-affine models for NLAR, of shapes other than the wheel actuator's:

* :func:`pendulum_model` — a pendulum driven by a torque motor, with viscous and smoothed Coulomb friction
  (μ tanh(ω/ε)); only the angle is measured (one output, one second-order test).
* :func:`two_tank_model` — two cascaded tanks with Torricelli outflows (square roots), pump into tank 1, only
  the level of tank 2 measured; the state of tank 1 is reconstructed through a square-root relation.
"""
from __future__ import annotations

import sympy as sp

from robofdi.models.control_affine import ControlAffineModel

__all__ = ["pendulum_model", "two_tank_model", "PENDULUM_CATALOGUE", "TWO_TANK_CATALOGUE", "two_tank_domain"]

#: Nominal pendulum data: inertia about the hinge [kg m²], m g l_c [N m], viscous [N m s/rad], Coulomb [N m], ε [rad/s].
PENDULUM_CATALOGUE = {"I": 0.06, "mgl": 1.1, "b": 0.03, "mu": 0.08, "eps": 0.02}
#: Nominal two-tank data: tank areas [m²], orifice areas [m²] (incl. discharge coefficient), gravity [m/s²].
TWO_TANK_CATALOGUE = {"A1": 0.0154, "A2": 0.0154, "a12": 5.0e-5, "a2": 5.0e-5, "g": 9.81}


def pendulum_model(params: dict | None = None) -> ControlAffineModel:
    """I θ̈ = τ − mgl sin θ − b θ̇ − μ tanh(θ̇/ε),  y = θ."""
    p = {**PENDULUM_CATALOGUE, **(params or {})}
    th, om, tau = sp.symbols("theta omega tau")
    I, mgl, b, mu, eps = sp.symbols("I mgl b mu eps", positive=True)
    return ControlAffineModel.from_equations(
        [th, om], [tau], [om, (tau - mgl * sp.sin(th) - b * om - mu * sp.tanh(om / eps)) / I], [th],
        {I: p["I"], mgl: p["mgl"], b: p["b"], mu: p["mu"], eps: p["eps"]}, output_names=("angle",),
        input_names=("torque",), output_units=("rad",), input_units=("N m",), name="pendulum")


def two_tank_model(params: dict | None = None) -> ControlAffineModel:
    """A₁ḣ₁ = q − a₁₂ sqrt(2g(h₁ − h₂)),  A₂ḣ₂ = a₁₂ sqrt(2g(h₁ − h₂)) − a₂ sqrt(2g h₂),  y = h₂ (h₁ > h₂ > 0)."""
    p = {**TWO_TANK_CATALOGUE, **(params or {})}
    h1, h2, q = sp.symbols("h1 h2 q")
    A1, A2, a12, a2, g = sp.symbols("A1 A2 a12 a2 g", positive=True)
    q12 = a12 * sp.sqrt(2 * g * (h1 - h2))
    return ControlAffineModel.from_equations(
        [h1, h2], [q], [(q - q12) / A1, (q12 - a2 * sp.sqrt(2 * g * h2)) / A2], [h2],
        {A1: p["A1"], A2: p["A2"], a12: p["a12"], a2: p["a2"], g: p["g"]}, output_names=("level2",),
        input_names=("pump_flow",), output_units=("m",), input_units=("m^3/s",), name="two_tank")


def two_tank_domain(model: ControlAffineModel) -> dict:
    """h₁ > h₂ > 0 (the square roots real), pump flow around its operating value."""
    by = {str(s): s for s in (*model.states, *model.inputs)}
    return {by["h1"]: (0.5, 0.9), by["h2"]: (0.1, 0.4), by["q"]: (1e-5, 1e-4)}
