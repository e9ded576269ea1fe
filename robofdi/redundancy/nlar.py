"""Nonlinear analytical redundancy (NLAR): tests R = Ω·𝒪_ΔDD for any control-affine model.

Leuschen, Walker & Cavallaro, "Nonlinear Fault Detection for Hydraulic Systems", Sec. 2.1, eqs. (3)–(4):

1. 𝒪_Δ, the triangular nonlinear observability: per output hⱼ the rows L_F^k hⱼ (F = f + Σ gᵢuᵢ, u held
   constant), k = 0 … rⱼ, where rⱼ is the (generic) rank of that output's gradient block ∇𝒪_Δ,ⱼ; so rⱼ + 1 rows.
2. 𝒪_ΔDD, the dynamically derived observability: the same rows written with the measured derivatives,
   𝒪_ΔDD,ⱼₖ = yⱼ⁽ᵏ⁾ − cⱼₖ(x, u, u̇, …), where cⱼₖ = Dᵏhⱼ − L_F^k hⱼ collects the input-derivative terms of the
   total time derivative D (eq. (13)'s u̇ correction).
3. Ω, the left null matrix with Ω 𝒪_Δ ≡ 0: anchored on the first pivot row a (the book's θ̇ column),
   row j has −𝒪_Δ,ⱼ in column a and 𝒪_Δ,ₐ in column j (eq. (12)).
4. R = Ω 𝒪_ΔDD evaluated at the state x̂ reconstructed from the pivot rows (eq. (4)); the book prints
   Rⱼ = −(Ω 𝒪_ΔDD)ⱼ / 𝒪_Δ,ₐ(x̂) = 𝒪_Δ,ⱼ(x̂) − 𝒪_ΔDD,ⱼ, the form used here (it does not vanish with 𝒪_Δ,ₐ).
5. The count of independent tests, corrected (spec digest §1 [ERRATUM]): N = Σⱼ (rⱼ + 1) − rank ∇𝒪_Δ. Tests that
   vanish identically (the pivot rows: the book's R3) are trivial; tests dependent on earlier ones are redundant.

Ranks are generic ranks: the rank of the gradient evaluated at random points of the model's domain.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from robofdi.errors import RobofdiError
from robofdi.models.control_affine import ControlAffineModel

__all__ = ["NLARDesign", "derive_nlar", "derivative_symbol", "generic_rank"]

RANK_TOL = 1e-8
RANK_POINTS = 5


def derivative_symbol(name: str, k: int) -> sp.Symbol:
    """The symbol of the k-th time derivative of the signal ``name`` (k = 0: the signal itself)."""
    return sp.Symbol(name if k == 0 else f"{name}_d{k}")


def _sample_points(model: ControlAffineModel, domain: Mapping, count: int, seed: int) -> list[dict]:
    """Random points of (states, inputs) inside ``domain`` (symbol → (low, high)), default (0.1, 1) each."""
    rng = np.random.default_rng(seed)
    pts = []
    for _ in range(count):
        pt = {}
        for s in (*model.states, *model.inputs):
            lo, hi = domain.get(s, (0.1, 1.0))
            pt[s] = float(rng.uniform(lo, hi))
        pts.append(pt)
    return pts


def generic_rank(rows: sp.Matrix, wrt: tuple, model: ControlAffineModel, points: list[dict]) -> int:
    """Generic rank of the Jacobian ∂rows/∂wrt: the largest numeric rank at the sample points (rows normalised)."""
    return _jacobian_rank(rows, wrt, (*model.states, *model.inputs), model.params, points)


def _jacobian_rank(exprs: sp.Matrix, wrt, variables, params, points: list[dict]) -> int:
    """max over ``points`` (variable → value) of the numeric rank of ∂exprs/∂wrt, rows normalised; points where it
    is not finite or not real are skipped."""
    if exprs.shape[0] == 0:
        return 0
    fn = sp.lambdify(list(variables), exprs.jacobian(sp.Matrix(list(wrt))).subs(params), modules="numpy")
    best = 0
    for pt in points:
        M = np.array(fn(*[pt[s] for s in variables]), dtype=complex)
        if not np.all(np.isfinite(M)) or np.abs(M.imag).max(initial=0.0) > 1e-9 * max(1.0, np.abs(M).max()):
            continue
        M = M.real
        norms = np.linalg.norm(M, axis=1)
        M = M[norms > 0] / norms[norms > 0, None]
        if M.size:
            best = max(best, int(np.linalg.matrix_rank(M, tol=RANK_TOL)))
    return best


@dataclass
class NLARDesign:
    """Everything the NLAR derivation produces for one model (symbolic; see :func:`derive_nlar`).

    rows: (output index j, order k) of every row of 𝒪_Δ; observability: 𝒪_Δ(x, u); dd: 𝒪_ΔDD(y, u, x̂);
    orders: rⱼ per output; rank: rank ∇𝒪_Δ; pivots: indices of the rows that reconstruct the state;
    reconstruction: observable state → expression in measured signals; omega: Ω(x, u) ((N_rows − 1) × N_rows);
    products: Ω·𝒪_ΔDD at x̂; tests: name → Rⱼ (normalised, book form) of every Ω row; trivial / redundant: names
    removed; independent: the kept test names; count: N = Σ(rⱼ+1) − rank.
    """

    model: ControlAffineModel
    rows: list
    observability: sp.Matrix
    dd: sp.Matrix
    orders: list
    rank: int
    pivots: list
    reconstruction: dict
    omega: sp.Matrix
    products: sp.Matrix
    tests: dict
    trivial: list
    redundant: list
    independent: list
    count: int
    signals: list = field(default_factory=list)

    @property
    def max_output_order(self) -> int:
        return max(self.orders) if self.orders else 0

    def max_input_order(self) -> int:
        """Highest input derivative any kept test uses."""
        top = 0
        names = {str(s) for e in self.independent for s in self.tests[e].free_symbols}
        for name in self.model.input_names:
            for k in range(1, 8):
                if str(derivative_symbol(name, k)) in names:
                    top = max(top, k)
        return top

    def arguments(self, measured: Mapping | None = None) -> list[sp.Symbol]:
        """Symbols the kept tests take, in a fixed order: each output's derivatives 0…rⱼ, then each input's 0…q,
        then the signals of ``measured`` parameters (see :meth:`residual_function`)."""
        q = self.max_input_order()
        args = [derivative_symbol(n, k) for j, n in enumerate(self.model.output_names) for k in range(self.orders[j] + 1)]
        args += [derivative_symbol(n, k) for n in self.model.input_names for k in range(q + 1)]
        args += [sp.Symbol(v) for v in (measured or {}).values()]
        return args

    def residual_function(self, params: Mapping | None = None, names=None, measured: Mapping | None = None):
        """Fast numeric tests: a function of :meth:`arguments` (positional floats) returning the kept tests, built
        by sympy.lambdify with common subexpressions eliminated; ``params`` (symbol or name → value) override the
        model's nominal values; ``measured`` (parameter name → signal name) turns slowly varying parameters into
        measured signals (e.g. the supply pressure p_s from its sensor; its time derivative is neglected)."""
        values = dict(self.model.params)
        by_name = {str(k): k for k in values}
        for k, v in (params or {}).items():
            key = by_name.get(str(k))
            if key is None:
                raise RobofdiError(f"residual_function: unknown parameter {k!r}; expected some of {sorted(by_name)}")
            values[key] = float(v)
        for k, sig in (measured or {}).items():
            key = by_name.get(str(k))
            if key is None:
                raise RobofdiError(f"residual_function: unknown measured parameter {k!r}; expected one of {sorted(by_name)}")
            values[key] = sp.Symbol(sig)
        names = list(self.independent if names is None else names)
        exprs = [self.tests[n].subs(values) for n in names]
        return sp.lambdify(self.arguments(measured), exprs, modules="math", cse=True)


def _total_derivative(expr, model: ControlAffineModel, depth: int) -> sp.Expr:
    """D expr = ∇ₓexpr·F(x, u) + Σᵢ Σₖ ∂expr/∂uᵢ⁽ᵏ⁾ uᵢ⁽ᵏ⁺¹⁾ (inputs varying in time)."""
    F = model.vector_field()
    out = sum((sp.diff(expr, x) * F[i] for i, x in enumerate(model.states)), sp.Integer(0))
    for name, u in zip(model.input_names, model.inputs):
        for k in range(depth + 1):
            s = u if k == 0 else derivative_symbol(name, k)
            out += sp.diff(expr, s) * derivative_symbol(name, k + 1)
    return out


def derive_nlar(model: ControlAffineModel, domain: Mapping | None = None, seed: int = 0,
                simplify: bool = True) -> NLARDesign:
    """The NLAR tests of ``model`` — Leuschen et al. Sec. 2.1 steps 1–5 (see the module docstring).

    ``domain``: state/input symbol → (low, high) where the equations are real and generic (e.g. p_l < p_s);
    default (0.1, 1) each. Raises :class:`RobofdiError` when the outputs see no state, or when the states that
    enter the observability rows cannot be reconstructed from them (an unobservable model).
    """
    if not isinstance(model, ControlAffineModel):
        raise RobofdiError(f"derive_nlar: field 'model' must be a ControlAffineModel, got {type(model).__name__}")
    domain = dict(domain or {})
    unknown = [s for s in domain if s not in (*model.states, *model.inputs)]
    if unknown:
        raise RobofdiError(f"derive_nlar: field 'domain' names {unknown[0]!r}, not a state or input of the model")
    points = _sample_points(model, domain, RANK_POINTS, seed)
    xs = model.states
    n = model.n
    input_zero = {derivative_symbol(nm, k): 0 for nm in model.input_names for k in range(1, n + 3)}

    # step 1: per output, rows until the block's rank stops growing
    rows, full, obs, orders = [], [], [], []
    for j in range(model.p):
        block: list[sp.Expr] = []
        expr = model.h[j]
        rank = 0
        for k in range(n + 1):
            o_k = sp.expand(expr.subs(input_zero)) if k else expr
            block.append(o_k)
            new_rank = generic_rank(sp.Matrix(block), xs, model, points)
            rows.append((j, k))
            full.append(expr)
            obs.append(o_k)
            if new_rank == rank:
                break
            rank = new_rank
            expr = _total_derivative(expr, model, k)
        orders.append(rank)
    O = sp.Matrix(obs)
    total_rank = generic_rank(O, xs, model, points)
    if total_rank == 0:
        raise RobofdiError(f"derive_nlar: model {model.name!r} is unobservable: the outputs "
                           f"{list(model.output_names)} do not depend on any state")

    # pivots: lowest derivative order first, each raising the rank
    pivots: list[int] = []
    for idx in sorted(range(len(rows)), key=lambda i: (rows[i][1], rows[i][0])):
        if generic_rank(sp.Matrix([obs[i] for i in pivots + [idx]]), xs, model, points) > len(pivots):
            pivots.append(idx)
        if len(pivots) == total_rank:
            break
    grad = O.jacobian(sp.Matrix(xs)).subs(model.params)
    seen = [x for i, x in enumerate(xs) if any(sp.simplify(g) != 0 for g in grad[:, i])]
    if len(seen) != total_rank:
        raise RobofdiError(
            f"derive_nlar: model {model.name!r} is unobservable: states {list(map(str, seen))} enter the observability "
            f"rows but rank ∇𝒪_Δ = {total_rank}; they cannot be reconstructed from y (change coordinates or add sensors)")

    # the measured version of each row: y_j^(k) (with the input-derivative correction c = full − 𝒪_Δ)
    y_of = {i: derivative_symbol(model.output_names[j], k) for i, (j, k) in enumerate(rows)}
    corrections = [sp.expand(full[i] - obs[i]) for i in range(len(rows))]
    equations = [sp.Eq(full[i], y_of[i]) for i in pivots]
    try:
        solutions = sp.solve(equations, seen, dict=True)
    except NotImplementedError:
        solutions = []
    if not solutions:
        raise RobofdiError(f"derive_nlar: cannot solve the pivot rows of model {model.name!r} for the states "
                           f"{list(map(str, seen))} (no closed-form reconstruction)")
    xhat = _pick_real_solution(solutions, model, points, y_of, pivots, full)
    dd = sp.Matrix([y_of[i] - corrections[i].subs(xhat) for i in range(len(rows))])

    # Ω anchored on the first pivot row; products and the book's normalised tests
    a = pivots[0]
    N = len(rows)
    omega = sp.zeros(N - 1, N)
    others = [i for i in range(N) if i != a]
    for r, i in enumerate(others):
        omega[r, a] = -obs[i]
        omega[r, i] = obs[a]
    products = (omega.subs(xhat) * dd)
    tests, trivial = {}, []
    rename = {u: derivative_symbol(nm, 0) for nm, u in zip(model.input_names, model.inputs)}
    for r, i in enumerate(others):
        R = (obs[i].subs(xhat) - dd[i]).subs(rename)
        if simplify:
            R = sp.simplify(R)
        tests[f"R{r + 1}"] = R
    signals = sorted({s for R in tests.values() for s in R.free_symbols} - set(model.params), key=str)
    meas_points = _measurement_points(model, points, rows, full, signals, seed)
    for name, R in tests.items():
        if R == 0 or _vanishes(R, signals, model, meas_points):
            trivial.append(name)
    kept, redundant = [], []
    for name in tests:
        if name in trivial:
            continue
        if _signal_rank([tests[k] for k in kept + [name]], signals, model, meas_points) > len(kept):
            kept.append(name)
        else:
            redundant.append(name)
    count = sum(r + 1 for r in orders) - total_rank
    return NLARDesign(model, rows, O, dd, orders, total_rank, pivots, xhat, omega, products, tests, trivial, redundant,
                      kept, count, signals)


def _pick_real_solution(solutions, model, points, y_of, pivots, full) -> dict:
    """The reconstruction x̂(y) that reproduces the states at the sample points (real branch of sympy.solve)."""
    if len(solutions) == 1:
        return solutions[0]
    for sol in solutions:
        ok = True
        for pt in points[:2]:
            meas = {y_of[i]: full[i].subs(model.params).subs(pt) for i in pivots}
            meas.update({s: 0 for s in set().union(*(e.free_symbols for e in sol.values()))
                         if s not in meas and s not in model.params and s not in model.inputs})
            for x, e in sol.items():
                val = complex(e.subs(model.params).subs(pt).subs(meas))
                if abs(val - pt[x]) > 1e-6 * max(1.0, abs(pt[x])):
                    ok = False
        if ok:
            return sol
    return solutions[0]


def _measurement_points(model, points, rows, full, signals, seed: int) -> list[dict]:
    """Measured values y⁽ᵏ⁾, u⁽ᵏ⁾ generated by the model at the sample points (input derivatives random), each
    perturbed by 5 % so that a genuine test does not vanish there while a trivial one does."""
    rng = np.random.default_rng(seed + 1)
    names = {str(s): s for s in signals}
    out = []
    for pt in points:
        values = {}
        for nm, u in zip(model.input_names, model.inputs):
            values[derivative_symbol(nm, 0)] = pt[u]
            for k in range(1, len(rows) + 2):
                values[derivative_symbol(nm, k)] = 0.1 * abs(pt[u]) * float(rng.uniform(-1, 1))
        subs = {**pt, **{u: values[derivative_symbol(nm, 0)] for nm, u in zip(model.input_names, model.inputs)},
                **{derivative_symbol(nm, k): values[derivative_symbol(nm, k)] for nm in model.input_names
                   for k in range(1, len(rows) + 2)}}
        for (j, k), expr in zip(rows, full):
            values[derivative_symbol(model.output_names[j], k)] = float(sp.N(expr.subs(model.params).subs(subs)))
        out.append({names[str(s)]: v * (1 + 0.05 * float(rng.standard_normal())) for s, v in values.items()
                    if str(s) in names})
    return out


def _vanishes(R, signals, model, points) -> bool:
    """True when R is zero at every (perturbed) measurement point, relative to the size of each signal's
    contribution |∂R/∂s · s| there: a trivial test."""
    expr = R.subs(model.params)
    fn = sp.lambdify(signals, [expr, *[sp.diff(expr, s) for s in signals]], modules="numpy")
    for pt in points:
        vals = [pt[s] for s in signals]
        out = np.array([complex(v) for v in fn(*vals)])
        if not np.all(np.isfinite(out)):
            return False
        scale = float(np.sum(np.abs(out[1:] * np.array(vals))))
        if abs(out[0]) > 1e-9 * scale + 1e-15 * max(1.0, float(np.max(np.abs(vals)))):
            return False
    return True


def _signal_rank(tests, signals, model, points) -> int:
    """Generic rank of the tests' Jacobian with respect to the measured signals."""
    return _jacobian_rank(sp.Matrix(tests), signals, signals, model.params, points)
