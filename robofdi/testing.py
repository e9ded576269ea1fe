"""The conformance kit: checks that a simulator, a diagnoser, a decision or a system obeys robofdi's protocols
(:mod:`robofdi.protocols`), in the spirit of scikit-learn's ``check_estimator`` and dm_env's test mixin.

Each check raises :class:`ConformanceError` (an ``AssertionError``) naming the part and what failed; it returns
nothing when the part conforms. What is checked:

* **the protocol** — every member of :class:`~robofdi.protocols.Simulator` / :class:`~robofdi.protocols.Diagnoser`
  / :class:`~robofdi.protocols.Decision` / :class:`~robofdi.protocols.System` is there;
* **units and columns on every output** — each names list matches the output's width and every entry has a unit
  string (a simulator's state, u and y; a diagnoser's residual and estimate; every dataset of a system's record);
* **no look-ahead** — a diagnoser's (decision's) output at sample k does not change when samples after k change
  (nor afterwards: an output that aliases the diagnoser's internal buffers is caught too);
* **reset reproduces** — ``reset()`` then the same inputs give identical outputs (also after a partial run);
* **the same seed gives the same output** — a simulator reset with the same seed measures the same; a system's run
  with the same seed records identical arrays;
* **NaN/inf input gives a clear error** — a :class:`~robofdi.errors.RobofdiError` naming the field, never a NaN
  that propagates silently (diagnosers: :func:`robofdi.observers.check_measurement` on ``y`` and ``u``);
* **a diagnoser receives no simulator** — its attributes, walked recursively to a bounded depth, hold no
  :class:`~robofdi.protocols.Simulator`, no MuJoCo ``MjData``, no robofdi simulator instance and no simulator
  environment (truth and belief never mix).

Your own diagnoser, in a test of your package::

    import numpy as np
    from robofdi.testing import check_diagnoser

    def make():                                   # a fresh, uncalibrated or calibrated diagnoser
        return MyDiagnoser(my_nominal_model(), sample_time=0.01)

    y = np.random.default_rng(0).normal(size=(200, 4))     # fault-free (y, ū(k−1)) samples, e.g. from
    u = np.random.default_rng(1).normal(size=(200, 2))     # robofdi.loop.diagnoser_inputs(record)
    check_diagnoser(make, (y, u))

and likewise ``check_simulator(lambda: MyPlant())``, ``check_decision(make_decision, residuals)`` and
``check_system(MySystem(), MyOptions(...))`` (one short fault-free run, twice, on the system's cheapest options).
"""
from __future__ import annotations

import functools
import math
import types
from collections.abc import Callable, Mapping, Sequence
from importlib import import_module
from typing import Any

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.loop import protocol_members
from robofdi.protocols import Decision, Diagnoser, Parts, Simulator, System, TargetLimit

__all__ = ["ConformanceError", "check_simulator", "check_diagnoser", "check_decision", "check_system",
           "find_simulators"]


class ConformanceError(AssertionError):
    """A part does not obey its protocol; the message names the part and the check that failed."""


def _fail(part: str, check: str, detail: str):
    raise ConformanceError(f"{part}: {check}: {detail}")


def _protocol(part: str, obj, protocol: type) -> None:
    missing = [m for m in protocol_members(protocol) if not hasattr(obj, m)]
    if missing:
        _fail(part, "protocol", f"{type(obj).__name__} does not implement {protocol.__name__} (missing: "
                                f"{', '.join(missing)})")


def _names_units(part: str, what: str, names, units, width: int) -> None:
    """``names`` (may be None: not checked) and ``units`` must each have ``width`` entries; units strings."""
    if names is not None and len(list(names)) != width:
        _fail(part, "units and columns", f"{what}: {len(list(names))} names for {width} values")
    if units is None:
        _fail(part, "units and columns", f"{what}: no units")
    units = list(units)
    if len(units) != width:
        _fail(part, "units and columns", f"{what}: {len(units)} units for {width} values")
    bad = [u for u in units if not isinstance(u, str) or not u]
    if bad:
        _fail(part, "units and columns", f"{what}: every entry needs a unit string (e.g. '1' when dimensionless), "
                                         f"got {bad[:3]}")


def _same(a, b) -> bool:
    """Exact equality of outputs (arrays equal with NaN == NaN, tuples / dicts / dataclasses entry by entry)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        if a.dtype.kind in "fc" and b.dtype.kind in "fc":
            return bool(np.array_equal(a, b, equal_nan=True))
        return bool(np.array_equal(a, b))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if hasattr(a, "__dataclass_fields__") and type(a) is type(b):
        return all(_same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def _first_difference(a: Sequence, b: Sequence) -> int | None:
    for k, (x, y) in enumerate(zip(a, b)):
        if not _same(x, y):
            return k
    return None if len(a) == len(b) else min(len(a), len(b))


# ---------------------------------------------------------------------------------------------------- no simulator
@functools.lru_cache(maxsize=1)
def _simulator_types() -> tuple[type, ...]:
    types_ = []
    try:
        import mujoco

        types_.append(mujoco.MjData)
    except ImportError:                                          # pragma: no cover - mujoco is a dependency
        pass
    for name in ("arm", "auv", "hydraulic", "linear"):
        module = import_module(f"robofdi.sims.{name}")
        for value in vars(module).values():
            if isinstance(value, type) and value.__module__ == module.__name__ and hasattr(value, "step") \
                    and hasattr(value, "reset"):
                types_.append(value)
    return tuple(types_)


def _is_simulator(obj) -> str | None:
    kind = type(obj)
    if isinstance(obj, type) or isinstance(obj, types.ModuleType):
        return None
    if isinstance(obj, _simulator_types()):
        return kind.__name__
    mod = getattr(kind, "__module__", "") or ""
    if mod.startswith(("robosuite.environments", "dm_control.rl", "dm_control.suite", "dm_control.mujoco.engine")):
        return f"{mod}.{kind.__name__}"
    if mod.startswith("robofdi.adapters") and kind.__name__.startswith("Faulty"):
        return kind.__name__
    try:
        if isinstance(obj, Simulator):
            return kind.__name__
    except Exception:                                            # a property that fails is not a simulator
        return None
    return None


_LEAVES = (str, bytes, int, float, complex, bool, type(None), np.ndarray, np.generic, range, slice)


def find_simulators(obj, max_depth: int = 5, max_objects: int = 20000) -> list[str]:
    """Attribute paths of every simulator object reachable from ``obj`` (attributes, containers, closures and
    bound methods, to ``max_depth`` levels): empty when truth does not leak in."""
    found, seen = [], set()
    stack = [(obj, type(obj).__name__, 0)]
    while stack and len(seen) < max_objects:
        o, path, depth = stack.pop()
        if isinstance(o, _LEAVES) or id(o) in seen:
            continue
        seen.add(id(o))
        what = _is_simulator(o)
        if what is not None:
            found.append(f"{path} ({what})")
            continue
        if depth >= max_depth or isinstance(o, (type, types.ModuleType)):
            continue
        children: list[tuple[Any, str]] = []
        if isinstance(o, Mapping):
            children = [(v, f"{path}[{k!r}]") for k, v in list(o.items())[:1000]]
        elif isinstance(o, (list, tuple, set, frozenset)):
            children = [(v, f"{path}[{i}]") for i, v in enumerate(list(o)[:1000])]
        elif isinstance(o, types.MethodType):
            children = [(o.__self__, f"{path}.__self__")]
        elif isinstance(o, types.FunctionType):
            cells = o.__closure__ or ()
            children = [(c.cell_contents, f"{path}.<closure {i}>") for i, c in enumerate(cells)
                        if _cell_filled(c)]
            children += [(d, f"{path}.<default {i}>") for i, d in enumerate(o.__defaults__ or ())]
        elif isinstance(o, functools.partial):
            children = [(o.func, f"{path}.func")] + [(a, f"{path}.args[{i}]") for i, a in enumerate(o.args)]
            children += [(v, f"{path}.keywords[{k!r}]") for k, v in o.keywords.items()]
        else:
            attrs = {}
            try:
                attrs = dict(vars(o))
            except TypeError:
                pass
            for slot in getattr(type(o), "__slots__", ()) or ():
                if isinstance(slot, str) and hasattr(o, slot):
                    attrs[slot] = getattr(o, slot)
            children = [(v, f"{path}.{k}") for k, v in attrs.items()]
        stack.extend((c, p, depth + 1) for c, p in children)
    return found


def _cell_filled(cell) -> bool:
    try:
        _ = cell.cell_contents
    except ValueError:
        return False
    return True


# ---------------------------------------------------------------------------------------------------- diagnoser
def _samples(part: str, samples) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(samples, tuple) and len(samples) == 2 and not isinstance(samples[0], tuple):
        y, u = samples
    else:
        pairs = list(samples)
        y, u = [p[0] for p in pairs], [p[1] for p in pairs]
    y, u = np.asarray(y, dtype=float), np.asarray(u, dtype=float)
    if y.ndim != 2 or u.ndim != 2 or len(y) != len(u) or len(y) < 4:
        raise RobofdiError(f"{part}: field 'samples' must be (y (N, ny), u (N, nu)) or N (y, u) pairs with N >= 4, "
                           f"got shapes {y.shape} and {u.shape}")
    if not (np.isfinite(y).all() and np.isfinite(u).all()):
        raise RobofdiError(f"{part}: field 'samples' must be finite (fault-free samples)")
    return y, u


def _run(d, y, u) -> list:
    return [d.update(y[k], u[k]) for k in range(len(y))]


def _residual_parts(res) -> tuple:
    return (res.r, res.estimate)


def check_diagnoser(make_diagnoser: Callable[[], Any], samples, name: str | None = None,
                    max_depth: int = 5) -> None:
    """Check a diagnoser built by ``make_diagnoser()`` (called twice: it must return a fresh one) on fault-free
    ``samples``: (y (N, ny), ū(k−1) (N, nu)) arrays — e.g. :func:`robofdi.loop.diagnoser_inputs` of a record — or
    N (y, u) pairs. Raises :class:`ConformanceError` naming the check that failed (module docstring)."""
    d = make_diagnoser()
    part = f"diagnoser {name or type(d).__name__}"
    y, u = _samples(part, samples)
    _protocol(part, d, Diagnoser)

    # --- the names and units
    for what, names, width in (("measurements", d.measurements, y.shape[1]), ("inputs", d.inputs, u.shape[1])):
        if len(list(names)) != width:
            _fail(part, "units and columns", f"{what}: {len(list(names))} names, the samples have {width} columns")
    if len(list(d.estimate_modes)) != len(list(d.estimate_components)):
        _fail(part, "units and columns", f"estimate_modes: {len(list(d.estimate_modes))} modes for "
                                         f"{len(list(d.estimate_components))} estimate components")
    bad = [m for m in d.estimate_modes if m not in ("level", "increment")]
    if bad:
        _fail(part, "units and columns", f"estimate_modes must be 'level' or 'increment', got {bad[:3]}")
    units = d.units
    if not isinstance(units, Mapping) or "residual" not in units or "estimate" not in units:
        _fail(part, "units and columns", f"units must map 'residual' and 'estimate' to unit lists, got {units!r}")
    m, e = len(list(d.components)), len(list(d.estimate_components))
    _names_units(part, "residual", d.components, units["residual"], m)
    _names_units(part, "estimate", d.estimate_components, units["estimate"], e)
    signatures = list(d.signatures())
    comps = set(d.components)
    for s in signatures:
        extra = (set(getattr(s, "required", ())) | set(getattr(s, "allowed", ()))) - comps
        if extra:
            _fail(part, "units and columns", f"signature {getattr(s, 'fault', s)!r} names {sorted(extra)}, which "
                                             f"are not residual components {sorted(comps)}")

    # --- no simulator inside
    leaks = find_simulators(d, max_depth)
    if leaks:
        _fail(part, "no simulator", f"the diagnoser holds truth: {', '.join(leaks[:3])}")

    # --- every output: widths and finiteness on fault-free samples
    out = _run(d, y, u)
    for k, res in enumerate(out):
        r, est = np.asarray(res.r), np.asarray(res.estimate)
        if r.shape != (m,) or est.shape != (e,):
            _fail(part, "units and columns", f"sample {k}: residual shape {r.shape} / estimate shape {est.shape}, "
                                             f"expected ({m},) / ({e},) from components / estimate_components")
        if not (np.isfinite(r).all() and np.isfinite(est).all()):
            _fail(part, "units and columns", f"sample {k}: non-finite output on fault-free samples")
    first = [tuple(np.array(p, copy=True) for p in _residual_parts(res)) for res in out]
    # --- no look-ahead: outputs kept from the run must still be what they were (no aliasing of internal
    # buffers), and a second instance whose samples after k differ must give the same outputs up to k
    late = [tuple(np.asarray(p) for p in _residual_parts(res)) for res in out]
    k = _first_difference(first, late)
    if k is not None:
        _fail(part, "no look-ahead", f"the output of sample {k} changed after later samples were processed "
                                     "(it aliases the diagnoser's state: return copies)")
    n = len(y)
    cut = n // 2
    y2, u2 = y.copy(), u.copy()
    y2[cut + 1:], u2[cut + 1:] = y[cut + 1:][::-1], u[cut + 1:][::-1]
    if cut + 1 < n and np.array_equal(y2, y) and np.array_equal(u2, u):
        y2[cut + 1:], u2[cut + 1:] = y[:n - cut - 1], u[:n - cut - 1]
    d2 = make_diagnoser()
    if d2 is d:
        _fail(part, "reset reproduces", "make_diagnoser() returned the same object twice; it must build a fresh one")
    other = [tuple(np.array(p, copy=True) for p in _residual_parts(res)) for res in _run(d2, y2, u2)]
    k = _first_difference(first[:cut + 1], other[:cut + 1])
    if k is not None:
        _fail(part, "no look-ahead", f"the output of sample {k} depends on samples after {cut}")
    # --- reset reproduces (after a full run, after a partial run); a fresh instance agreed above up to the cut
    for before in (n, cut):
        d.reset()
        _run(d, y[:before], u[:before])
        d.reset()
        again = [tuple(np.array(p, copy=True) for p in _residual_parts(res)) for res in _run(d, y, u)]
        k = _first_difference(first, again)
        if k is not None:
            _fail(part, "reset reproduces", f"after reset() (following {before} samples) the output differs at "
                                            f"sample {k}: reset() must restore the initial state")
    # --- NaN / inf input gives a clear error
    for field, bad_value in (("y", np.nan), ("u", np.inf), ("y", -np.inf), ("u", np.nan)):
        d.reset()
        _run(d, y[:2], u[:2])
        yb, ub = y[2].copy(), u[2].copy()
        target = yb if field == "y" else ub
        if target.size == 0:
            continue
        target[0] = bad_value
        try:
            res = d.update(yb, ub)
        except RobofdiError as exc:
            msg = str(exc)
            names = list(d.measurements if field == "y" else d.inputs)
            if f"'{field}'" not in msg and not any(str(nm) in msg for nm in names[:1]):
                _fail(part, "NaN/inf input", f"the error for {bad_value} in {field!r} does not name the field: {msg!r}")
            continue
        except Exception as exc:                                     # noqa: BLE001 - reported, not hidden
            _fail(part, "NaN/inf input", f"{bad_value} in {field!r} raised {type(exc).__name__}: {exc} (expected a "
                                         "RobofdiError naming the field; see robofdi.observers.check_measurement)")
        _fail(part, "NaN/inf input", f"{bad_value} in {field!r} was accepted (output r = {np.asarray(res.r)[:3]}...); "
                                     "expected a RobofdiError naming the field (robofdi.observers.check_measurement)")
    d.reset()


# ---------------------------------------------------------------------------------------------------- decision
def check_decision(make_decision: Callable[[], Any], residuals, name: str | None = None) -> None:
    """Check a decision built by ``make_decision()`` on residual rows ``residuals`` (M, m): threshold width,
    alarm shape and type, isolated hypotheses as a tuple of names, no look-ahead, reset reproduces, NaN/inf
    residuals refused with a :class:`~robofdi.errors.RobofdiError`."""
    dec = make_decision()
    part = f"decision {name or type(dec).__name__}"
    _protocol(part, dec, Decision)
    r = np.asarray(residuals, dtype=float)
    if r.ndim != 2 or len(r) < 4:
        raise RobofdiError(f"{part}: field 'residuals' must be (M >= 4, m) rows, got shape {r.shape}")
    m = r.shape[1]
    if np.asarray(dec.threshold).shape != (m,):
        _fail(part, "units and columns", f"threshold shape {np.asarray(dec.threshold).shape}, residual width {m}")

    def run(d, rows):
        out = []
        for row in rows:
            a = d.update(row)
            out.append((np.array(a.alarm, copy=True), tuple(a.isolated)))
        return out

    first = run(dec, r)
    for k, (alarm, isolated) in enumerate(first):
        if alarm.shape != (m,) or alarm.dtype != bool:
            _fail(part, "units and columns", f"sample {k}: alarm {alarm.dtype} shape {alarm.shape}, expected bool ({m},)")
        if not all(isinstance(h, str) for h in isolated):
            _fail(part, "units and columns", f"sample {k}: isolated must be names, got {isolated!r}")
    cut = len(r) // 2
    r2 = r.copy()
    r2[cut + 1:] = r[cut + 1:][::-1] * 3.0
    k = _first_difference(first[:cut + 1], run(make_decision(), r2)[:cut + 1])
    if k is not None:
        _fail(part, "no look-ahead", f"the decision at sample {k} depends on residuals after {cut}")
    dec.reset()
    k = _first_difference(first, run(dec, r))
    if k is not None:
        _fail(part, "reset reproduces", f"after reset() the decision differs at sample {k}")
    dec.reset()
    bad = r[0].copy()
    bad[0] = np.nan
    try:
        dec.update(bad)
    except RobofdiError:
        pass
    else:
        _fail(part, "NaN/inf input", "a NaN residual was accepted; expected a RobofdiError naming the residual")
    dec.reset()


# ---------------------------------------------------------------------------------------------------- simulator
def check_simulator(make_sim: Callable[[], Any], steps: int = 20, seed: int = 0, inputs=None,
                    initial_state=None, name: str | None = None) -> None:
    """Check a simulator built by ``make_sim()``: the protocol, names and units of state, u and y, widths of
    every output, the same seed → identical measurements (a fresh instance and the same one after reset),
    a NaN/inf command refused with a :class:`~robofdi.errors.RobofdiError`, and a nominal model that holds no
    simulator. ``inputs``: (steps, nu) commands (default zeros)."""
    sim = make_sim()
    part = f"simulator {name or type(sim).__name__}"
    _protocol(part, sim, Simulator)
    nu, ny, nx = len(sim.actuators), len(sim.sensor_channels), len(sim.state_names)
    units = sim.units
    for key, width, names in (("state", nx, sim.state_names), ("u", nu, sim.actuators), ("y", ny, sim.sensor_channels)):
        if key not in units:
            _fail(part, "units and columns", f"units has no {key!r} entry")
        _names_units(part, key, names, units[key], width)
    for kind, targets in sim.component_kinds.items():
        extra = set(targets) - set(sim.components)
        if extra:
            _fail(part, "units and columns", f"component_kinds[{kind!r}] names {sorted(extra)}, not in components")
    if not (sim.control_dt > 0 and sim.physics_dt > 0):
        _fail(part, "protocol", f"control_dt {sim.control_dt} and physics_dt {sim.physics_dt} must be > 0 s")
    u = np.zeros((steps, nu)) if inputs is None else np.asarray(inputs, dtype=float)

    def run(s):
        out = [np.array(s.reset(initial_state, seed=seed), copy=True)]
        for k in range(len(u)):
            y = s.step(u[k])
            out.append(np.array(y, copy=True))
            for what, v, width in (("y", y, ny), ("state", s.state, nx), ("u_applied", s.u_applied, nu),
                                   ("true_output", s.true_output, ny)):
                if np.shape(v) != (width,):
                    _fail(part, "units and columns", f"step {k}: {what} shape {np.shape(v)}, expected ({width},)")
        return out

    first = run(sim)
    if np.shape(first[0]) != (ny,):
        _fail(part, "units and columns", f"reset() returned shape {np.shape(first[0])}, expected ({ny},)")
    k = _first_difference(first, run(sim))
    if k is not None:
        _fail(part, "same seed", f"reset(seed={seed}) twice: the measurements differ at step {k}")
    k = _first_difference(first, run(make_sim()))
    if k is not None:
        _fail(part, "same seed", f"two fresh simulators with seed {seed}: the measurements differ at step {k}")
    if nu:
        sim.reset(initial_state, seed=seed)
        bad = np.zeros(nu)
        bad[0] = np.nan
        try:
            y = sim.step(bad)
        except RobofdiError:
            pass
        except Exception as exc:                                     # noqa: BLE001
            _fail(part, "NaN/inf input", f"a NaN command raised {type(exc).__name__}: {exc}; expected a RobofdiError")
        else:
            if not np.isfinite(np.asarray(y, dtype=float)).all() or not np.isfinite(sim.state).all():
                _fail(part, "NaN/inf input", "a NaN command propagated into the state; expected a RobofdiError")
    belief = sim.nominal_model()
    leaks = find_simulators(belief)
    if leaks:
        _fail(part, "no simulator", f"nominal_model() holds the simulator: {', '.join(leaks[:3])}")


# ---------------------------------------------------------------------------------------------------- system
def _record_arrays(rec) -> dict:
    out = {"time": rec.time, "truth/state": rec.truth_state}
    if rec.u_applied is not None:
        out["truth/u_applied"] = rec.u_applied
    out.update({f"signals/{k}": v for k, v in rec.signals.items()})
    for k, lab in rec.faults.items():
        out[f"faults/{k}/active"], out[f"faults/{k}/value"] = lab.active, lab.value
    for k, tr in rec.diagnosers.items():
        for f in ("time", "residual", "threshold", "alarm", "isolated", "estimate"):
            out[f"diagnosers/{k}/{f}"] = getattr(tr, f)
    return out


def check_record(rec, part: str = "record") -> None:
    """Every dataset of a record has a column name and a unit per column; every trace a name and unit per
    residual and estimate entry, and rows as long as its time."""
    widths = {"truth/state": rec.truth_state}
    if rec.u_applied is not None:
        widths["truth/u_applied"] = rec.u_applied
    widths.update({f"signals/{k}": v for k, v in rec.signals.items()})
    for path, a in widths.items():
        a = np.asarray(a)
        if len(a) != len(rec.time):
            _fail(part, "units and columns", f"{path}: {len(a)} rows for {len(rec.time)} time stamps")
        width = a.shape[1] if a.ndim == 2 else 1
        if path not in rec.columns:
            _fail(part, "units and columns", f"{path}: no column names")
        _names_units(part, path, rec.columns[path], rec.units.get(path), width)
    for name, lab in rec.faults.items():
        if len(lab.active) != len(rec.time) or len(lab.value) != len(rec.time):
            _fail(part, "units and columns", f"fault {name!r}: labels not one per time stamp")
        if not isinstance(lab.unit, str) or not lab.unit:
            _fail(part, "units and columns", f"fault {name!r}: no unit for its value")
    for name, tr in rec.diagnosers.items():
        n = len(tr.time)
        for what, a, comps in (("residual", tr.residual, tr.components), ("estimate", tr.estimate, tr.estimate_components),
                               ("alarm", tr.alarm, tr.components)):
            if np.shape(a) != (n, len(comps)):
                _fail(part, "units and columns", f"diagnoser {name!r} {what}: shape {np.shape(a)}, expected "
                                                 f"({n}, {len(comps)})")
        _names_units(part, f"diagnoser {name!r} residual", tr.components, tr.units.get("residual"), len(tr.components))
        _names_units(part, f"diagnoser {name!r} estimate", tr.estimate_components, tr.units.get("estimate"),
                     len(tr.estimate_components))


def check_system(system, options=None, seed: int = 0, faults=(), diagnosers=None) -> None:
    """Check a :class:`~robofdi.protocols.System` on ``options`` (default: its options type's defaults — pass
    cheap ones): the protocol, fault targets with limits, a calibration, a mission drawn twice from the same seed
    alike, its built parts (:class:`~robofdi.protocols.Parts`: a loop to run, a diagnosis per diagnoser), and one
    run (``faults``, default none) twice with ``seed`` — the built parts run, and ``run`` on the second mission:
    identical record arrays, units and columns on every dataset. Calibration goes through the system's own
    (cached) calibration. ``diagnosers``: check with a subset of the system's diagnosers (default: all of them)."""
    part = f"system {getattr(system, 'name', type(system).__name__)}"
    _protocol(part, system, System)
    options = system.options_type() if options is None else options
    if not isinstance(options, system.options_type):
        raise RobofdiError(f"{part}: field 'options' must be a {system.options_type.__name__}, got "
                           f"{type(options).__name__}")
    targets = system.targets(options)
    for family, table in targets.items():
        for target, limit in table.items():
            if not isinstance(limit, TargetLimit) or not (limit.limit > 0) or not isinstance(limit.unit, str):
                _fail(part, "units and columns", f"targets[{family!r}][{target!r}] must be a TargetLimit with a "
                                                 f"positive limit and a unit, got {limit!r}")
    names = list(system.diagnosers(options))
    if diagnosers is not None:                      # a subset, to keep an expensive calibration out of the check
        unknown = [d for d in diagnosers if d not in names]
        if unknown:
            raise RobofdiError(f"{part}: field 'diagnosers' has {unknown}, which the system does not run; "
                               f"expected some of {names}")
        names = list(diagnosers)
    keys = list(system.calibration_keys(options))
    if not names or not keys:
        _fail(part, "protocol", f"diagnosers {names} and calibration_keys {keys} must not be empty")
    key = keys[0]
    calibration, _ = system.calibrate(options, key, names)
    m1 = system.mission(options, key, np.random.default_rng(seed))
    m2 = system.mission(options, key, np.random.default_rng(seed))
    if not _same(m1.description, m2.description) or m1.duration != m2.duration:
        _fail(part, "same seed", "two missions drawn from the same seed differ")
    parts = system.build(options, calibration, key, m1, list(faults), seed, names)
    if not isinstance(parts, Parts):
        _fail(part, "protocol", f"build must return robofdi.protocols.Parts, got {type(parts).__name__}")
    if not callable(getattr(parts.loop, "run", None)):
        _fail(part, "protocol", "build: Parts.loop has no run method")
    missing = [n for n in names if n not in parts.diagnoses]
    if parts.diagnoses and missing:
        _fail(part, "protocol", f"build: the parts hold no diagnosis for {missing}")
    runs = [parts.run(), system.run(options, calibration, key, m2, list(faults), seed, names)]
    for rec in runs:
        check_record(rec, part)
        missing = [n for n in names if n not in rec.diagnosers]
        if missing:
            _fail(part, "units and columns", f"the record has no trace of diagnosers {missing}")
    a, b = (_record_arrays(r) for r in runs)
    if a.keys() != b.keys():
        _fail(part, "same seed", f"two runs with seed {seed} record different datasets: {sorted(a.keys() ^ b.keys())}")
    for path in a:
        if not _same(np.asarray(a[path]), np.asarray(b[path])):
            _fail(part, "same seed", f"two runs with seed {seed}: {path} differs")
