"""Nearly nonlinear analytical redundancy (NNAR): the linear AR null space Ω applied to the nonlinear equations.

Leuschen, Walker & Cavallaro, "Nonlinear Fault Detection for Hydraulic Systems", Sec. 9 (Appendix, NNAR) and the
footnote of Sec. 5. Linear AR on a linearisation of the model gives a constant left null matrix Ω_lin of the linear
observability, Ω_lin ∇𝒪_Δ,lin = 0; each linear test is Ω_lin applied to the stack of equation residuals

    E_(j,k) = D^k h_j(x̂, u, u̇, …) − y_j^(k)        (the model's k-th derivative of output j minus the measured one:
                                                   sensor comparisons k = 0, model equations k = 1, their
                                                   first derivatives k = 2, …)

NNAR keeps that relation (the same Ω_lin, the same rows) and evaluates E with the *nonlinear* model, x̂ the state
reconstructed from the pivot rows. Because Ω_lin approximates the nonlinear null space, the NLAR guarantee (every
observable discrepancy shows) does not carry over in general: the linear and nonlinear observabilities can have a
different rank. Where they have the same rows and pivots — the book's wheel actuator — every Ω_lin row is
e_i − Σ_p α_ip e_p with E_p ≡ 0 on the pivot rows, so NNAR's tests are NLAR's tests exactly ("for this specific
case the approximation used in the NNAR technique is exact", Sec. 5).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import sympy as sp

from robofdi.errors import RobofdiError
from robofdi.redundancy.nlar import NLARDesign, _total_derivative, derivative_symbol

__all__ = ["linear_null_space", "derive_nnar"]

NULL_TOL = 1e-9


def linear_null_space(linear: NLARDesign) -> np.ndarray:
    """Ω_lin ((N−1)×N, constant) of a linear AR design: the left null space of its observability gradient
    ∇𝒪_Δ, one row per non-anchor row of 𝒪_Δ in the engine's order (:func:`~robofdi.redundancy.nlar.derive_nlar`,
    eq. (12) layout), row i = e_i − Σ_p α_ip e_p with ∇𝒪_Δ,i = Σ_p α_ip ∇𝒪_Δ,p over the pivot rows p. Raises
    :class:`RobofdiError` when the design's model is not linear (its gradient depends on the state or input)."""
    model = linear.model
    grad = linear.observability.jacobian(sp.Matrix(model.states)).subs(model.params)
    if grad.free_symbols:
        raise RobofdiError(f"linear_null_space: model {model.name!r} is not linear: its observability gradient "
                           f"depends on {sorted(map(str, grad.free_symbols))}")
    G = np.array(grad, dtype=float)
    pivots = list(linear.pivots)
    P = G[pivots]
    others = [i for i in range(G.shape[0]) if i != pivots[0]]
    omega = np.zeros((len(others), G.shape[0]))
    for r, i in enumerate(others):
        alpha, *_ = np.linalg.lstsq(P.T, G[i], rcond=None)
        omega[r, i] += 1.0
        omega[r, pivots] -= alpha
    scale = max(1.0, float(np.abs(G).max()))
    if np.abs(omega @ G).max() > NULL_TOL * scale:
        raise RobofdiError(f"linear_null_space: the pivot rows of {model.name!r} do not span its observability")
    return omega


def derive_nnar(design: NLARDesign, linear: NLARDesign, simplify: bool = True) -> NLARDesign:
    """The NNAR tests (Sec. 9): ``linear``'s Ω_lin (:func:`linear_null_space`, from linear AR on a linearisation
    of ``design.model``) applied to the nonlinear equation residuals of ``design.model``, E_(j,k) = D^k h_j(x̂) − y_j^(k)
    over ``linear``'s rows (the module docstring). Returns an :class:`NLARDesign` of ``design.model`` whose tests are
    the NNAR tests, named and kept as ``linear``'s (use it with :func:`~robofdi.redundancy.residuals.nlar_residual`),
    with ``omega`` = Ω_lin. The sign is NLAR's (prediction − measurement)."""
    model = design.model
    lin = linear.model
    if (tuple(map(str, lin.output_names)) != tuple(map(str, model.output_names))
            or tuple(map(str, lin.input_names)) != tuple(map(str, model.input_names))):
        raise RobofdiError(f"derive_nnar: the linear model {lin.name!r} must have the outputs and inputs of "
                           f"{model.name!r} ({list(model.output_names)}, {list(model.input_names)})")
    omega = linear_null_space(linear)
    rename = {u: derivative_symbol(nm, 0) for nm, u in zip(model.input_names, model.inputs)}
    stack = []
    for j, k in linear.rows:
        expr = model.h[j]
        for step in range(k):
            expr = _total_derivative(expr, model, step)
        predicted = expr.subs(design.reconstruction).subs(rename)
        stack.append(predicted - derivative_symbol(model.output_names[j], k))
    E = sp.Matrix(stack)
    others = [i for i in range(len(linear.rows)) if i != linear.pivots[0]]
    tests = {}
    for r, _ in enumerate(others):
        row = [sp.Float(c) if c != 0 else 0 for c in omega[r]]
        R = sum((c * E[i] for i, c in enumerate(row) if c != 0), sp.Integer(0))
        tests[f"R{r + 1}"] = sp.simplify(R) if simplify else R
    missing = [n for n in linear.independent if n not in tests]
    if missing:
        raise RobofdiError(f"derive_nnar: linear design tests {missing} have no NNAR counterpart")
    return dataclasses.replace(design, rows=list(linear.rows), orders=list(linear.orders), pivots=list(linear.pivots),
                               omega=sp.Matrix(omega), products=sp.Matrix(omega) * E, tests=tests,
                               trivial=list(linear.trivial), redundant=list(linear.redundant),
                               independent=list(linear.independent), count=linear.count)
