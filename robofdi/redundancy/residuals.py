"""Residual generators over analytical-redundancy tests (Diagnoser protocol, :mod:`robofdi.protocols`).

A test is a function of the measured signals and their time derivatives (NLAR, linear AR, PLAR, NNAR, mlp_ar all are);
:class:`RedundancyResidual` feeds it from a :class:`~robofdi.redundancy.derivatives.DerivativeEstimator`, sample by
sample, so the same object runs in the closed loop, offline over a record, or on rig data.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from robofdi.decision import Signature
from robofdi.errors import RobofdiError
from robofdi.observers.residual import Residual, check_measurement
from robofdi.redundancy.derivatives import DerivativeEstimator, SavitzkyGolay

__all__ = ["SignalMap", "RedundancyResidual", "nlar_residual"]


class SignalMap:
    """Where each model signal comes from: ``sources[i] = ("y", index)`` (a sensor channel) or ``("u", index)`` (an
    actuator command), for the model's outputs then its inputs; ``orders[i]`` the highest derivative the tests use."""

    def __init__(self, names: Sequence[str], sources: Sequence[tuple[str, int]], orders: Sequence[int]):
        if not (len(names) == len(sources) == len(orders)):
            raise RobofdiError("SignalMap: fields 'names', 'sources' and 'orders' must have the same length")
        for name, (kind, idx) in zip(names, sources):
            if kind not in ("y", "u") or not isinstance(idx, (int, np.integer)) or idx < 0:
                raise RobofdiError(f"SignalMap: source of {name!r} must be ('y' | 'u', index >= 0), got {(kind, idx)!r}")
        self.names, self.sources, self.orders = list(names), list(sources), [int(k) for k in orders]
        self.y_index = np.array([i for k, i in self.sources if k == "y"], dtype=int)
        self.u_index = np.array([i for k, i in self.sources if k == "u"], dtype=int)
        self._from_y = np.array([k == "y" for k, _ in self.sources])
        # argument order of the tests: signal by signal, derivative 0…order
        self.arguments = [(k, c) for c, q in enumerate(self.orders) for k in range(q + 1)]

    def channels(self, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        out = np.empty(len(self.sources))
        out[self._from_y] = y[self.y_index]
        out[~self._from_y] = u[self.u_index]
        return out


class RedundancyResidual:
    """Diagnoser: residuals ``tests(*arguments)`` of a test function, with derivatives from a Savitzky–Golay filter.

    tests: ``f(*args)`` → sequence of residuals, args ordered as :attr:`SignalMap.arguments`; components: residual names;
    residual_units: their units; measurements / inputs: the simulator's sensor channels and actuators;
    filter: the derivative filter (its delay is :attr:`delay`); signatures: isolation signatures.
    Until the window is full the residual is zero (blank those samples in the decision: :attr:`warmup`).
    """

    def __init__(self, tests: Callable, components: Sequence[str], residual_units: Sequence[str],
                 measurements: Sequence[str], inputs: Sequence[str], signal_map: SignalMap, filter: SavitzkyGolay,
                 signatures: Sequence[Signature] = ()):
        if not callable(tests):
            raise RobofdiError("RedundancyResidual: field 'tests' must be a function of the signal derivatives")
        self.tests = tests
        self.components = list(components)
        if len(residual_units) != len(self.components):
            raise RobofdiError(f"RedundancyResidual: field 'residual_units' must have {len(self.components)} entries")
        self.units = {"residual": list(residual_units), "estimate": []}
        self.measurements, self.inputs = list(measurements), list(inputs)
        for kind, idx in signal_map.sources:
            size = len(self.measurements) if kind == "y" else len(self.inputs)
            if idx >= size:
                raise RobofdiError(f"RedundancyResidual: signal source ({kind!r}, {idx}) is out of range ({size} entries)")
        self.signal_map = signal_map
        if max(signal_map.orders) > filter.max_derivative:
            raise RobofdiError(f"RedundancyResidual: the tests need derivative order {max(signal_map.orders)}, the filter "
                               f"gives up to max_derivative={filter.max_derivative}")
        self.filter = filter
        self._sigs = tuple(signatures)
        self.estimate_components: list[str] = []
        self.estimate_modes: list[str] = []
        self._estimator = DerivativeEstimator(filter, len(signal_map.sources))
        self._zero = np.zeros(len(self.components))
        self._empty = np.zeros(0)
        self._arg_k = np.array([k for k, _ in signal_map.arguments])
        self._arg_c = np.array([c for _, c in signal_map.arguments])

    @property
    def delay(self) -> float:
        """[s] the residual lags the measurements by (the derivative filter's delay)."""
        return self.filter.delay

    @property
    def warmup(self) -> int:
        """Samples before the first residual (the filter window)."""
        return self.filter.window

    def reset(self) -> None:
        self._estimator.reset()

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        y = check_measurement(y, len(self.measurements), "y")
        u = check_measurement(u, len(self.inputs), "u")
        d = self._estimator.update(self.signal_map.channels(y, u))
        if d is None:
            return Residual(self._zero.copy(), self._empty)
        try:
            r = np.asarray(self.tests(*d[self._arg_k, self._arg_c].tolist()), dtype=float)
        except (ValueError, ZeroDivisionError, OverflowError):   # outside the model's domain (e.g. p_l ≥ p_s)
            r = np.full(len(self.components), np.inf)
        if not np.all(np.isfinite(r)):   # a finite, alarming value: the decision refuses non-finite residuals
            r = np.nan_to_num(r, nan=1e300, posinf=1e300, neginf=-1e300)
        return Residual(r, self._empty)

    def signatures(self) -> Sequence[Signature]:
        return self._sigs


def nlar_residual(design, measurements: Sequence[str], inputs: Sequence[str], filter: SavitzkyGolay,
                  signatures: Sequence[Signature] = (), params=None, sources: dict | None = None,
                  residual_units: Sequence[str] | None = None, measured: dict | None = None) -> RedundancyResidual:
    """The kept NLAR tests of ``design`` (:class:`~robofdi.redundancy.nlar.NLARDesign`) as a Diagnoser.

    Each model output / input is read from the simulator's channel of the same name — a sensor channel, else an
    actuator — unless ``sources`` maps its name to ("y" | "u", index). ``params`` override nominal values;
    ``measured`` (parameter name → signal name) reads parameters from signals (e.g. p_s from the supply sensor).
    """
    model = design.model
    measured = dict(measured or {})
    names = [*model.output_names, *model.input_names, *measured.values()]
    sources = dict(sources or {})
    resolved = []
    for name in names:
        if name in sources:
            resolved.append(sources[name])
        elif name in measurements:
            resolved.append(("y", list(measurements).index(name)))
        elif name in inputs:
            resolved.append(("u", list(inputs).index(name)))
        else:
            raise RobofdiError(f"nlar_residual: model signal {name!r} is neither a sensor channel {list(measurements)} "
                               f"nor an actuator {list(inputs)}; map it with 'sources'")
    q = design.max_input_order()
    orders = list(design.orders) + [q] * model.m + [0] * len(measured)
    units = residual_units or [_test_unit(design, n) for n in design.independent]
    return RedundancyResidual(design.residual_function(params, measured=measured), design.independent, units,
                              measurements, inputs, SignalMap(names, resolved, orders), filter, signatures)


def _test_unit(design, name: str) -> str:
    """Unit of test ``name``: the unit of its measured row, y_j^(k) → unit/s^k."""
    r = list(design.tests).index(name)
    others = [i for i in range(len(design.rows)) if i != design.pivots[0]]
    j, k = design.rows[others[r]]
    unit = design.model.output_units[j] or "1"
    return unit if k == 0 else f"{unit}/s" if k == 1 else f"{unit}/s^{k}"
