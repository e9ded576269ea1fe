"""The diagnosis schemes of Caccavale & Villani's robot chapter, plus the momentum baseline, built on one nominal
model with the chapter's experimental settings (Sec. 7) as defaults; and the consistency scheme
(:mod:`robofdi.observers.consistency`), which needs a design learnt from fault-free runs; and, only when asked
for (:data:`OPT_IN_SCHEMES`), the sliding-mode output observer on q̇ (:mod:`robofdi.observers.sliding_mode_arm`)."""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from robofdi import RobofdiError
from robofdi.checks import check_fields, is_int, is_number
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers.consistency import STEP_HOLD, ConsistencyDesign, ConsistencyResidual, design_consistency
from robofdi.observers.kinematic import RIPPLE_CYCLES, WINDOWS, ripple_orders
from robofdi.observers.diagnostic import Adaptive, DiagnosticObserver, Recursive, RippleModel, TimeDelayed
from robofdi.observers.momentum import MomentumObserver
from robofdi.observers.sliding_mode_arm import ArmSlidingModeObserver

__all__ = ["ArmSchemeSettings", "CONSISTENCY_TAILS", "SCHEMES", "BOOK_SCHEMES", "OPT_IN_SCHEMES", "ALL_SCHEMES", "arm_schemes",
           "SchemeCalibration", "scheme_calibration", "row_tails"]

#: The book's schemes (ch. 3) and the momentum baseline.
BOOK_SCHEMES = ("simple", "time_delayed", "recursive", "adaptive", "position_only", "momentum")
#: The schemes an arm run holds by default.
SCHEMES = BOOK_SCHEMES + ("consistency",)
#: Schemes built only when named (a scenario's ``schemes``, a campaign's ``diagnosers``): the default runs, the
#: demo and the suite's time do not change. "sliding_mode": the SMOO of Saif & Xiong eq. (54) on q̇.
OPT_IN_SCHEMES = ("sliding_mode",)
#: Every scheme :func:`arm_schemes` builds.
ALL_SCHEMES = SCHEMES + OPT_IN_SCHEMES
#: The tail laws the consistency scheme's thresholds may extrapolate (:func:`robofdi.decision.extreme_value_thresholds`
#: ``tail``): "gumbel" or "exponential" on every row; "exponential-bounds" the exponential tail on the rows divided by
#: a learnt operating-point bound (dynamic, step and payload rows: their block maxima spread from near 0 where the
#: bound fits a motion tightly) and the Gumbel fit on the kinematic rows (whose upper maxima 24 held-out motions
#: do not cover: robosuite panda's joint6_kin fell from 2.32 to 1.46, below a fault-free run's 1.53).
CONSISTENCY_TAILS = ("gumbel", "exponential", "exponential-bounds")


@dataclass(frozen=True)
class ArmSchemeSettings:
    """K1 = K2 = 0.1 I; Γ_η = 0.1 diag(0.1 ×n, 2 ×(n−1), 3) [spec: erratum I₃ → I₆]; Q = 2 Γ_η⁻¹;
    momentum-observer bandwidth K_O [1/s]; residual space of the observers ("torque" or "state"); bandwidth K_O
    [1/s] of the consistency scheme's momentum rows, its target false-alarm rate [1/h] (thresholds by
    extreme-value theory, :func:`robofdi.decision.extreme_value_thresholds`) and its isolation confirmation
    window [samples] (:class:`robofdi.decision.ThresholdDecision` ``confirm``), the quiet time [s] after which an
    isolation may be revised (``release``), how much longer [s] a window that would name an encoder waits for the
    evidence of a velocity sensor (``defer``: a velocity-gain error's gain evidence needs 0.03–0.05 s of motion
    after the first alarm on arm6; a fault shorter than the window, 46 ms at 2 ms samples, is detected but not
    named while it lasts, and the acceptance mix's shortest encoder offsets last 50 ms), its kinematic windows [s]
    and the torque-ripple periods per motor revolution whose aliasing its kinematic rows cover (with the model's
    nominal gear ratios,
    :func:`robofdi.observers.kinematic.ripple_orders`; () = none), the random calibration motions it needs (half
    design it, half set its thresholds) and the tail law its thresholds extrapolate (:data:`CONSISTENCY_TAILS`);
    the sliding-mode scheme's switching gain Λ [rad/s²], integration sub-step [s], in-sample filter constant [s]
    and equivalent-control low-pass [s] at the diagnosis rate, by default the momentum baseline's bandwidth 1/K_O
    (:class:`robofdi.observers.sliding_mode_arm.ArmSlidingModeObserver`)."""

    T: float = 0.002
    K1: float = 0.1
    K2: float = 0.1
    momentum_gain: float = 50.0
    adaptive_step: float = 2.0      # the factor 2 of eq. (39)
    residual_space: str = "torque"
    consistency_gain: float = 100.0
    consistency_false_alarm_rate: float = 0.1
    consistency_confirm: int = 3
    consistency_release: float = 0.5
    consistency_defer: float = 0.04
    consistency_windows: tuple = WINDOWS
    consistency_ripple_cycles: tuple = RIPPLE_CYCLES
    consistency_calibration_motions: int = 6
    consistency_tail: str = "gumbel"
    smo_gain: float = 200.0
    smo_substep: float = 2e-6
    smo_tau: float = 2e-5
    smo_filter: float = 0.02

    def __post_init__(self):
        positive = ("T", "K1", "K2", "momentum_gain", "adaptive_step", "consistency_gain",
                    "consistency_false_alarm_rate", "smo_gain", "smo_substep", "smo_tau", "smo_filter")
        for name in ("consistency_windows", "consistency_ripple_cycles"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check_fields("ArmSchemeSettings", self, [
            *((name, is_number(getattr(self, name)) and getattr(self, name) > 0, "a finite number > 0") for name in positive),
            ("residual_space", self.residual_space in ("torque", "state"), "'torque' or 'state'"),
            ("consistency_confirm", is_int(self.consistency_confirm, 1), "an integer >= 1 [samples]"),
            ("consistency_release", is_number(self.consistency_release) and self.consistency_release >= 0,
             "a time >= 0 s"),
            ("consistency_defer", is_number(self.consistency_defer) and self.consistency_defer >= 0, "a time >= 0 s"),
            ("consistency_windows", len(self.consistency_windows) > 0
             and all(is_number(w) and w >= 0 for w in self.consistency_windows), "a non-empty list of times >= 0 s"),
            ("consistency_calibration_motions", is_int(self.consistency_calibration_motions, 2),
             "an integer >= 2 (half of them held out)"),
            ("consistency_tail", self.consistency_tail in CONSISTENCY_TAILS, f"one of {list(CONSISTENCY_TAILS)}"),
            ("consistency_ripple_cycles", all(is_number(c) and c > 0 for c in self.consistency_ripple_cycles),
             "a list of periods per motor revolution > 0 (empty: none)"),
        ])

    def gamma_eta(self, n: int) -> np.ndarray:
        return 0.1 * np.concatenate([np.full(n, 0.1), np.full(n - 1, 2.0), [3.0]])


def arm_schemes(model: ManipulatorModel, settings: ArmSchemeSettings = ArmSchemeSettings(),
                theta0: np.ndarray | None = None, schemes=BOOK_SCHEMES,
                consistency: ConsistencyDesign | None = None, designs: Mapping[str, object] | None = None) -> dict:
    """Fresh diagnosers by name (``schemes`` a subset of :data:`ALL_SCHEMES`); ``theta0`` initialises the adaptive
    ripple model (see :func:`robofdi.observers.spectral.ripple_initial_parameters`); ``designs``: the learnt
    designs by scheme name (:class:`SchemeCalibration` ``design``), e.g. the consistency scheme's
    (:func:`robofdi.observers.consistency.design_consistency`), which ``consistency`` may also give."""
    unknown = [s for s in schemes if s not in ALL_SCHEMES]
    if unknown:
        raise RobofdiError(f"arm_schemes: unknown scheme(s) {unknown}; expected a subset of {list(ALL_SCHEMES)}")
    consistency = consistency if consistency is not None else (designs or {}).get("consistency")
    if "consistency" in schemes and consistency is None:
        raise RobofdiError("arm_schemes: scheme 'consistency' needs its design (field 'consistency'), learnt from "
                           "fault-free runs by robofdi.observers.consistency.design_consistency")
    n, s = model.n, settings
    gamma = s.gamma_eta(n)
    common = dict(K1=s.K1, K2=s.K2, residual_space=s.residual_space)
    build = {
        "simple": lambda: DiagnosticObserver(model, s.T, None, **common),
        "time_delayed": lambda: DiagnosticObserver(model, s.T, TimeDelayed(), **common),
        "recursive": lambda: DiagnosticObserver(model, s.T, Recursive(gamma), **common),
        "adaptive": lambda: DiagnosticObserver(
            model, s.T, Adaptive(RippleModel(n, model.torque_limit), 2.0 / gamma, theta0, step=s.adaptive_step), **common
        ),
        "position_only": lambda: DiagnosticObserver(model, s.T, Recursive(gamma), velocity="backward_difference", **common),
        "momentum": lambda: MomentumObserver(model, s.T, s.momentum_gain),
        "consistency": lambda: ConsistencyResidual(model, consistency),
        "sliding_mode": lambda: ArmSlidingModeObserver(model, s.T, s.smo_gain, s.smo_substep, s.smo_tau,
                                                        s.smo_filter),
    }
    return {name: build[name]() for name in schemes}


@dataclass(frozen=True)
class SchemeCalibration:
    """How a scheme is calibrated on fault-free runs (:func:`robofdi.systems.arm.calibrate` follows it for every
    scheme alike).

    ``design``: None, or ``design(model, inputs, settings, skip)`` → the scheme's design, learnt from the design
    runs' diagnoser inputs (then the scheme's thresholds come from held-out runs the design never saw, and for a
    false-alarm rate from the design runs too);
    ``thresholds``: "margin" (ρ_i = margin · max |r_i| over the runs, Caccavale & Villani Sec. 6) or
    "false_alarm_rate" (extreme-value thresholds for ``settings.consistency_false_alarm_rate`` per hour, and
    evidence levels for the discriminating rows: their largest fault-free value, at least 1);
    ``confirm``: the isolation confirmation window [samples] of its decision; ``release``: the quiet samples
    after which its isolation may be revised (0: latched); ``overturn``: the samples a later alarm must persist
    to overturn the hypothesis it refines (0: never); ``defer``: the samples longer a confirmation window that
    would name a refinable hypothesis waits (0: none); ``random_motions`` and ``top_speed``:
    what the calibration suite must hold for it (random motions, half of them held out; the top-speed motion)."""

    design: Callable | None = None
    thresholds: str = "margin"
    confirm: int = 0
    random_motions: int = 0
    top_speed: bool = False
    release: int = 0
    overturn: int = 0
    defer: int = 0


def _design_consistency(model, inputs, settings: ArmSchemeSettings, skip: int) -> ConsistencyDesign:
    cycles = settings.consistency_ripple_cycles
    orders = ripple_orders(model.gear_ratio, cycles) if len(cycles) else None
    return design_consistency(model, inputs, settings.T, settings.consistency_gain, skip, settings.consistency_windows,
                              orders)


def row_tails(tail: str, diagnoser) -> list[str]:
    """The tail law of each of ``diagnoser``'s residual components under ``consistency_tail`` = ``tail``
    (:data:`CONSISTENCY_TAILS`, validated by :class:`ArmSchemeSettings`): its ``kinematic`` rows keep the Gumbel fit
    under "exponential-bounds"."""
    if tail != "exponential-bounds":
        return [tail] * len(diagnoser.components)
    kinematic = set(getattr(diagnoser, "kinematic", ()))
    return ["gumbel" if c in kinematic else "exponential" for c in diagnoser.components]


def scheme_calibration(name: str, settings: ArmSchemeSettings = ArmSchemeSettings()) -> SchemeCalibration:
    """The calibration rule of scheme ``name``: the book's margin rule for the book's schemes and the momentum
    baseline; a learnt design, held-out thresholds for a false-alarm rate, and a confirmation window for the
    consistency scheme (:mod:`robofdi.observers.consistency`); the margin rule for the sliding-mode scheme too (its
    residual, τ̂ = M̂ r_eq, is a torque like the momentum observer's)."""
    if name not in ALL_SCHEMES:
        raise RobofdiError(f"scheme_calibration: unknown scheme {name!r}; expected one of {list(ALL_SCHEMES)}")
    if name == "consistency":
        return SchemeCalibration(_design_consistency, "false_alarm_rate", settings.consistency_confirm,
                                 random_motions=settings.consistency_calibration_motions, top_speed=True,
                                 release=max(1, int(round(settings.consistency_release / settings.T))),
                                 overturn=int(round(2 * STEP_HOLD / settings.T)),
                                 defer=int(round(settings.consistency_defer / settings.T)))
    return SchemeCalibration()
