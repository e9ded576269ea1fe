"""Multiple-model decision: detection on the nominal model's residual, isolation by the switching index —
Guo, Jiang, Zhang & Wang (2008) eqs. (21)–(22)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from robofdi.decision.isolation import Alarms
from robofdi.errors import RobofdiError

__all__ = ["SwitchingIndexDecision", "NisBankDecision", "SupervisorStatusDecision"]


@dataclass
class SwitchingIndexDecision:
    """Decision protocol for a bank whose residual is [‖r₀‖ (nominal), ‖r₁‖, …, ‖r_m‖] (one per fault model).

    Detection: ‖r₀‖ > ``threshold[0]`` (calibrated on fault-free runs; eq. (22), whose inequality is garbled).
    Isolation: the active model argminᵢ Jᵢ(t), Jᵢ(t) = c₁‖rᵢ(t)‖² + c₂/(c₃t + 1) Σ_τ≤t ‖rᵢ(τ)‖² dt — eq. (21), t
    counted from the first sample; reported from the first alarm on (isolation before a fault is meaningless:
    every lock model explains fault-free data, spec B.2). ``models``: the hypothesis name of each bank model.
    ``threshold``: the decision's thresholds per residual component (only the nominal one is used for alarms; the
    others are reported as +inf-like large values for the record).
    """

    components: Sequence[str]
    threshold: np.ndarray
    models: Sequence[str]
    dt: float
    c: tuple[float, float, float] = (1.0, 1.0, 1.0)
    blanking: int = 0
    index: np.ndarray = field(default=None, init=False)

    def __post_init__(self):
        self.components = tuple(self.components)
        m = len(self.components)
        if m < 2 or len(self.models) != m - 1:
            raise RobofdiError(f"SwitchingIndexDecision: field 'models' must name the {m - 1} bank models after "
                               f"the nominal residual, got {list(self.models)}")
        self.threshold = np.array(self.threshold, dtype=float)
        if self.threshold.shape != (m,) or not np.all(self.threshold > 0):
            raise RobofdiError(f"SwitchingIndexDecision: field 'threshold' must be {m} values > 0, got {self.threshold}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise RobofdiError(f"SwitchingIndexDecision: field 'dt' must be a sample time > 0 s, got {self.dt!r}")
        if len(self.c) != 3 or not all(np.isfinite(v) and v > 0 for v in self.c):
            raise RobofdiError(f"SwitchingIndexDecision: field 'c' must be three constants c₁, c₂, c₃ > 0, got {self.c}")
        self.reset()

    def reset(self) -> None:
        self._k = 0
        self._integral = np.zeros(len(self.models))
        self._detected = False
        self._active = None
        self.index = np.zeros(len(self.models))

    def update(self, residual: np.ndarray) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != (len(self.components),) or not np.all(np.isfinite(r)):
            raise RobofdiError(f"SwitchingIndexDecision: residual must be {len(self.components)} finite values")
        c1, c2, c3 = self.c
        t = self._k * self.dt
        self._k += 1
        sq = r[1:] ** 2
        self._integral += sq * self.dt
        self.index = c1 * sq + c2 / (c3 * t + 1.0) * self._integral
        alarm = np.zeros(len(self.components), dtype=bool)
        if self._k > self.blanking:
            alarm[0] = r[0] > self.threshold[0]
        self._detected |= bool(alarm[0])
        if not self._detected:
            return Alarms(alarm=alarm)
        i = int(np.argmin(self.index))
        alarm[1 + i] = True                       # the active model's component marks the isolated hypothesis
        best = self.models[i]
        new = (best,) if best != self._active else ()
        self._active = best
        return Alarms(alarm=alarm, isolated=(best,), new=new)


@dataclass
class NisBankDecision:
    """Decision for a bank of Kalman filters whose residual is the windowed NIS [NIS₀ (nominal), NIS₁, …, NIS_m]
    — Bar-Shalom's NIS test applied to a hypothesis bank (Antonelli's survey, Roby 2 [2, 3]; digest §3.1):

    Detection: NIS₀ > ``threshold[0]`` (the χ² bound); while NIS₀ alarms, H_j is declared when NIS_j is the
    smallest of all (the nominal included) — latched, the first declaration stands, and its component alarms from
    then on (the fault filters' own NIS exceed the bound in fault-free runs by design: no alarm on them). ``models``: the
    hypothesis name of each fault filter."""

    components: Sequence[str]
    threshold: np.ndarray
    models: Sequence[str]
    blanking: int = 0

    def __post_init__(self):
        self.components = tuple(self.components)
        m = len(self.components)
        if m < 2 or len(self.models) != m - 1:
            raise RobofdiError(f"NisBankDecision: field 'models' must name the {m - 1} fault filters after the "
                               f"nominal one, got {list(self.models)}")
        self.threshold = np.array(self.threshold, dtype=float)
        if self.threshold.shape != (m,) or not np.all(self.threshold > 0):
            raise RobofdiError(f"NisBankDecision: field 'threshold' must be {m} values > 0, got {self.threshold}")
        self.reset()

    def reset(self) -> None:
        self._k = 0
        self._declared: tuple[str, ...] = ()

    def update(self, residual: np.ndarray) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != (len(self.components),) or not np.all(np.isfinite(r)):
            raise RobofdiError(f"NisBankDecision: residual must be {len(self.components)} finite values")
        self._k += 1
        if self._k <= self.blanking:
            return Alarms(alarm=np.zeros(len(r), dtype=bool))
        alarm = np.zeros(len(r), dtype=bool)
        alarm[0] = r[0] > self.threshold[0]
        new = ()
        if not self._declared and alarm[0]:
            j = int(np.argmin(r))
            if j > 0:
                self._declared = new = (self.models[j - 1],)
        if self._declared:                        # the declared hypothesis's component marks the isolation
            alarm[1 + list(self.models).index(self._declared[0])] = True
        return Alarms(alarm=alarm, isolated=self._declared, new=new)


@dataclass
class SupervisorStatusDecision:
    """Decision for a bank that carries its own supervisor (:class:`robofdi.observers.effector_bank.HybridEffectorFDI`,
    Bošković & Mehra §5.4): the residual ends with one status per effector (0 healthy, 1 identifying, 2 committed);
    an effector alarms and is isolated while its status is > 0.5 (the supervisor's switch); the switching
    indices before it are recorded, never thresholded. Isolated effectors are listed in the order they switched."""

    components: Sequence[str]
    effectors: Sequence[str]
    threshold: np.ndarray = field(default=None)

    def __post_init__(self):
        self.components = tuple(self.components)
        self.effectors = tuple(self.effectors)
        status = [f"status:{e}" for e in self.effectors]
        if list(self.components[-len(status):]) != status:
            raise RobofdiError(f"SupervisorStatusDecision: the residual must end with the statuses {status}")
        self._first = len(self.components) - len(status)
        self.threshold = np.concatenate([np.full(self._first, np.inf), np.full(len(status), 0.5)])
        self.reset()

    def reset(self) -> None:
        self._order: list[str] = []

    def update(self, residual: np.ndarray) -> Alarms:
        r = np.asarray(residual, dtype=float)
        if r.shape != (len(self.components),) or not np.all(np.isfinite(r)):
            raise RobofdiError(f"SupervisorStatusDecision: residual must be {len(self.components)} finite values")
        alarm = r > self.threshold
        on = [e for e, a in zip(self.effectors, alarm[self._first:]) if a]
        new = tuple(e for e in on if e not in self._order)
        self._order += list(new)
        return Alarms(alarm=alarm, isolated=tuple(e for e in self._order if e in on), new=new)
