"""A symbolic control-affine model ẋ = f(x) + Σ gᵢ(x) uᵢ, y = h(x) (sympy), checked at construction.

Leuschen, Walker & Cavallaro, "Nonlinear Fault Detection for Hydraulic Systems", eq. (1). The model is the
belief a diagnoser derives its tests from: parameters are sympy symbols with nominal values (``params``), so the
same derivation serves any parameter set (catalogue values, calibrated values).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp

from robofdi.errors import RobofdiError

__all__ = ["ControlAffineModel"]


def _symbols(value, name: str, where: str) -> tuple[sp.Symbol, ...]:
    items = tuple(value)
    bad = [s for s in items if not isinstance(s, sp.Symbol)]
    if bad:
        raise RobofdiError(f"{where}: field '{name}' must hold sympy Symbols, got {bad[0]!r}")
    dup = sorted({str(s) for s in items if items.count(s) > 1})
    if dup:
        raise RobofdiError(f"{where}: field '{name}' has duplicate symbol(s) {', '.join(dup)}")
    return items


@dataclass(frozen=True)
class ControlAffineModel:
    """ẋ = f(x) + G(x) u, y = h(x) — eq. (1). Build it with :meth:`from_equations` from ẋ written out in full.

    states, inputs: sympy Symbols; f: n expressions; G: n×m matrix (column i = gᵢ); h: p expressions of the states;
    params: parameter Symbol → nominal value (every other free symbol must be a state or an input);
    output_names / input_names: names of y and u entries (default: the symbols' names); units per entry.
    """

    states: tuple
    inputs: tuple
    f: sp.Matrix
    G: sp.Matrix
    h: sp.Matrix
    params: Mapping = field(default_factory=dict)
    output_names: tuple = ()
    input_names: tuple = ()
    output_units: tuple = ()
    input_units: tuple = ()
    name: str = "model"

    def __post_init__(self):
        where = f"ControlAffineModel {self.name!r}"
        states = _symbols(self.states, "states", where)
        inputs = _symbols(self.inputs, "inputs", where)
        if not states:
            raise RobofdiError(f"{where}: field 'states' must name at least one state")
        clash = set(states) & set(inputs)
        if clash:
            raise RobofdiError(f"{where}: symbol(s) {sorted(map(str, clash))} are both states and inputs")
        f, G, h = sp.Matrix(self.f), sp.Matrix(self.G), sp.Matrix(self.h)
        n, m = len(states), len(inputs)
        if f.shape != (n, 1):
            raise RobofdiError(f"{where}: field 'f' must have {n} entries (one per state {list(map(str, states))}), "
                               f"got {f.shape[0]}")
        if m and G.shape != (n, m):
            raise RobofdiError(f"{where}: field 'G' must be {n}x{m} (states x inputs), got {G.shape[0]}x{G.shape[1]}")
        if not m:
            G = sp.zeros(n, 0)
        if h.shape[1] != 1 or h.shape[0] == 0:
            raise RobofdiError(f"{where}: field 'h' must be a column of output expressions, got shape {h.shape}")
        params = dict(self.params)
        bad = [k for k in params if not isinstance(k, sp.Symbol)]
        if bad:
            raise RobofdiError(f"{where}: field 'params' must map sympy Symbols to numbers, got key {bad[0]!r}")
        for k, v in params.items():
            try:
                params[k] = float(v)
            except (TypeError, ValueError):
                raise RobofdiError(f"{where}: field 'params[{k}]' must be a number, got {v!r}") from None
        overlap = set(params) & (set(states) | set(inputs))
        if overlap:
            raise RobofdiError(f"{where}: symbol(s) {sorted(map(str, overlap))} are parameters and states/inputs")
        known = set(states) | set(inputs) | set(params)
        for label, expr in (("f", f), ("G", G), ("h", h)):
            unknown = sorted(map(str, expr.free_symbols - known))
            if unknown:
                raise RobofdiError(f"{where}: field '{label}' uses symbol(s) {', '.join(unknown)} that are neither "
                                   "states, inputs nor params (mismatched symbol lists)")
        if G.free_symbols & set(inputs) or f.free_symbols & set(inputs):
            raise RobofdiError(f"{where}: f and G must not contain inputs; the model is not control-affine")
        if h.free_symbols & set(inputs):
            raise RobofdiError(f"{where}: field 'h' must be a function of the states only (y = h(x)), it uses inputs "
                               f"{sorted(map(str, h.free_symbols & set(inputs)))}")
        p = h.shape[0]
        out_names = tuple(self.output_names) or tuple(f"y{j + 1}" for j in range(p))
        in_names = tuple(self.input_names) or tuple(str(s) for s in inputs)
        if len(out_names) != p:
            raise RobofdiError(f"{where}: field 'output_names' must have {p} names, got {len(out_names)}")
        if len(in_names) != m:
            raise RobofdiError(f"{where}: field 'input_names' must have {m} names, got {len(in_names)}")
        for label, units, size in (("output_units", self.output_units, p), ("input_units", self.input_units, m)):
            if units and len(units) != size:
                raise RobofdiError(f"{where}: field '{label}' must have {size} units, got {len(units)}")
        object.__setattr__(self, "states", states)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "f", f)
        object.__setattr__(self, "G", G)
        object.__setattr__(self, "h", h)
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "output_names", out_names)
        object.__setattr__(self, "input_names", in_names)
        object.__setattr__(self, "output_units", tuple(self.output_units) or ("",) * p)
        object.__setattr__(self, "input_units", tuple(self.input_units) or ("",) * m)

    @classmethod
    def from_equations(cls, states: Sequence, inputs: Sequence, xdot: Sequence, outputs: Sequence,
                       params: Mapping | None = None, **names) -> ControlAffineModel:
        """Split ẋ = F(x, u) into f(x) + G(x) u; raises if F is not affine in u (a model that is not control-affine)."""
        where = f"ControlAffineModel {names.get('name', 'model')!r}"
        states = _symbols(states, "states", where)
        inputs = _symbols(inputs, "inputs", where)
        F = sp.Matrix([sp.sympify(e) for e in xdot])
        if F.shape[0] != len(states):
            raise RobofdiError(f"{where}: field 'xdot' must have {len(states)} equations (one per state "
                               f"{list(map(str, states))}), got {F.shape[0]} (mismatched symbol lists)")
        zero = dict.fromkeys(inputs, 0)
        G = F.jacobian(sp.Matrix(inputs)) if inputs else sp.zeros(len(states), 0)
        for i, s in enumerate(states):
            for j, u in enumerate(inputs):
                for v in inputs:
                    if sp.simplify(sp.diff(G[i, j], v)) != 0:
                        raise RobofdiError(f"{where}: d{s}/dt is not affine in the inputs (∂²/∂{u}∂{v} ≠ 0); the model "
                                           "is not control-affine ẋ = f(x) + Σ gᵢ(x) uᵢ")
        f = F.subs(zero)
        return cls(states, inputs, f, G, sp.Matrix([sp.sympify(e) for e in outputs]), dict(params or {}), **names)

    @property
    def n(self) -> int:
        return len(self.states)

    @property
    def m(self) -> int:
        return len(self.inputs)

    @property
    def p(self) -> int:
        return self.h.shape[0]

    def vector_field(self) -> sp.Matrix:
        """F(x, u) = f(x) + G(x) u."""
        return self.f + (self.G * sp.Matrix(self.inputs) if self.m else sp.zeros(self.n, 1))

    def with_params(self, **values: float) -> ControlAffineModel:
        """The same equations with some nominal parameter values replaced (by symbol name)."""
        by_name = {str(k): k for k in self.params}
        unknown = sorted(set(values) - set(by_name))
        if unknown:
            raise RobofdiError(f"with_params: unknown parameter(s) {unknown}; expected some of {sorted(by_name)}")
        params = dict(self.params)
        for k, v in values.items():
            params[by_name[k]] = float(v)
        return ControlAffineModel(self.states, self.inputs, self.f, self.G, self.h, params, self.output_names,
                                  self.input_names, self.output_units, self.input_units, self.name)
