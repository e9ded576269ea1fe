"""The flexible-joint arm of Saif & Xiong's Example 2 (book ch. 1) with the 4-stage sliding-mode observer: the link
angle and both speeds estimated from the motor encoder alone, gravity −3.33 sin θ_l treated as the unknown input.

The observer, in the chapter's original coordinates (its reconstructions: λ2 in ē3, +19.5 y − 19.5 x̂3 in the x̂4
row, +21.6 u in the x̂2 row; the gravity term is not in the observer)::

    x̂1' = x̂2 + λ1 ψ(y − x̂1)                                    ē2 = (λ1 ψ(ē1))_eq        (= e2 in sliding)
    x̂2' = −48.6 y − 1.25 x̂2 + 48.6 x̂3 + 21.6 u + λ2 ψ(ē2)       ē3 = (λ2 ψ(ē2))_eq / 48.6 (= e3)
    x̂3' = x̂4 + λ3 ψ(ē3)                                         ē4 = (λ3 ψ(ē3))_eq        (= e4)
    x̂4' = 19.5 y − 19.5 x̂3 + λ4 ψ(ē4)

λ = (800, 120, 120, 1400), stages 2–4 switched on at 0.2, 0.8 and 1.8 s, x(0) = [1, 1, 1, 1], x̂(0) = 0 (the
chapter's). ψ = sign and τ = 1e-5 s, h = 1e-8 s: the chapter's "saturation 0.02" with these gains is unstable
(Routh: 96,000 < 1,134,400; :func:`robofdi.observers.sliding_mode.boundary_layer_routh`), so the observer runs the
ideal sign with a low-pass equivalent control, which needs the fine sub-step. u = 0 unless ``u_amplitude``
(a sine of ``u_frequency``), since the chapter gives no input.

:class:`FlexibleJointSystem` (``flexible-joint``) is the system face: ``robofdi run flexible-joint --fault …``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robofdi.checks import check_fields, is_number
from robofdi.loop import ClosedLoop, Diagnosis, Rates
from robofdi.observers.sliding_mode import CascadeSMO, SlidingDetector, SMOSettings, Stage
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.record import Record
from robofdi.sims.flexible_joint import FlexibleJointArm
from robofdi.systems import register_system

__all__ = ["FlexibleJointOptions", "flexible_joint_smo", "run_flexible_joint", "FlexibleJointSystem", "GAINS",
           "ACTIVATION", "DIAGNOSER"]

GAINS = (800.0, 120.0, 120.0, 1400.0)
ACTIVATION = (0.0, 0.2, 0.8, 1.8)
DIAGNOSER = "smo"


@dataclass(frozen=True)
class FlexibleJointOptions:
    """duration [s]; gains λ1..λ4; activation: switch-on time per stage [s]; tau: equivalent-control filter [s];
    substep: Euler step inside each 1 ms diagnosis sample [s]; switching: "sign" or "sat" (ε = ``boundary``);
    x0: the plant's initial state; u_amplitude [V], u_frequency [rad/s]: the motor input; extra_term: add
    0.5 sign(ω_l) to the link's unknown input (the digest's E2.4: another bounded term, observer unchanged)."""

    duration: float = 3.0
    gains: tuple = GAINS
    activation: tuple = ACTIVATION
    tau: float = 1e-5
    substep: float = 1e-8
    switching: str = "sign"
    boundary: float = 0.02
    x0: tuple = (1.0, 1.0, 1.0, 1.0)
    u_amplitude: float = 0.0
    u_frequency: float = 2.0
    extra_term: bool = False

    def __post_init__(self):
        object.__setattr__(self, "gains", tuple(float(g) for g in self.gains))
        object.__setattr__(self, "activation", tuple(float(a) for a in self.activation))
        object.__setattr__(self, "x0", tuple(float(v) for v in self.x0))
        check_fields("flexible-joint", self, [
            ("duration", is_number(self.duration) and 0 < self.duration <= 60, "a time in (0, 60] s"),
            ("gains", len(self.gains) == 4 and all(g > 0 for g in self.gains), "4 gains > 0"),
            ("activation", len(self.activation) == 4, "4 switch-on times [s]"),
            ("u_amplitude", is_number(self.u_amplitude), "a voltage amplitude"),
            ("u_frequency", is_number(self.u_frequency) and self.u_frequency >= 0, "a frequency >= 0 rad/s")])


def flexible_joint_smo(options: FlexibleJointOptions = FlexibleJointOptions(), sample_time: float = 1e-3,
                       keep_history: bool = True, detector: SlidingDetector | None = None) -> CascadeSMO:
    """The chapter's 4-stage observer (module docstring) as a :class:`CascadeSMO`; residuals r1..r4 are the
    stages' equivalent controls (≈ e2 [rad/s], 48.6·e3 [rad/s²], e4 [rad/s], the link's unknown input [rad/s²]).
    ``detector``: stage the cascade with a :class:`SlidingDetector` instead of ``options.activation``."""
    l1, l2, l3, l4 = options.gains
    M = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, -1.25, 48.6, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, -19.5, 0.0]])

    def affine(y, u):
        return M, np.array([0.0, -48.6 * y[0] + 21.6 * u[0], 0.0, 19.5 * y[0]])

    stages = [Stage(l1, 0, Wy=[1.0], Cx=[1.0, 0.0, 0.0, 0.0], name="r1"), Stage(l2, 1, after=0, name="r2"),
              Stage(l3, 2, after=1, gain=lambda y: 1.0 / 48.6, name="r3"), Stage(l4, 3, after=2, name="r4")]
    settings = SMOSettings(sample_time, options.substep, options.tau, options.switching, options.boundary,
                           None if detector is not None else options.activation, detector)
    return CascadeSMO(4, affine, stages, settings, ["motor"], ["motor_angle"],
                      state_names=["theta_m", "omega_m", "theta_l", "omega_l"],
                      residual_units=["rad/s", "rad/s^2", "rad/s", "rad/s^2"], keep_history=keep_history,
                      where="flexible_joint_smo")


class _Input:
    """The motor voltage u(t) = a sin(ω t) (open loop; the chapter gives no input)."""

    def __init__(self, amplitude: float, frequency: float):
        self.a, self.w = amplitude, frequency

    def __call__(self, t: float) -> np.ndarray:
        return np.array([self.a * np.sin(self.w * t)])

    def update(self, y, reference) -> np.ndarray:
        return np.asarray(reference, dtype=float)


class _ExtraTermArm(FlexibleJointArm):
    """E2.4: the link's unknown input −3.33 sin θ_l + 0.5 sign(ω_l) (the added term applied as a joint torque)."""

    def step(self, u):
        ql = self.model.joint("link_joint").dofadr[0]
        J_l = 48.6 * 0.01 / 19.5
        self.data.qfrc_applied[ql] = 0.5 * J_l * np.sign(self.data.qvel[ql])
        return super().step(u)


def flexible_joint_parts(options: FlexibleJointOptions = FlexibleJointOptions(), faults=(), seed: int = 0,
                         run_key: str = "run") -> Parts:
    """One open-loop run on the MuJoCo arm with the SMO online at 1 kHz, built (:class:`~robofdi.protocols.Parts`)."""
    arm = (_ExtraTermArm if options.extra_term else FlexibleJointArm)(x0=options.x0)
    smo = flexible_joint_smo(options, arm.control_dt)
    inp = _Input(options.u_amplitude, options.u_frequency)
    loop = ClosedLoop(arm, inp, inp, faults=faults, diagnoses={DIAGNOSER: Diagnosis(smo)}, rates=Rates(1000.0, 1000.0, "first"),
                      reference_columns=["motor_voltage"], reference_units=["V"])
    return Parts(loop, options.duration, None, seed, run_key, "ch1-flexible-joint",
                 {"observer": "4-stage SMO (Saif & Xiong Example 2)", "tau": options.tau, "substep": options.substep,
                  "switching": options.switching})


def run_flexible_joint(options: FlexibleJointOptions = FlexibleJointOptions(), faults=(), seed: int = 0,
                       run_key: str = "run") -> tuple[Record, CascadeSMO]:
    """One open-loop run on the MuJoCo arm with the SMO online at 1 kHz → (record, the observer with its history)."""
    parts = flexible_joint_parts(options, faults, seed, run_key)
    return parts.run(), parts.diagnoses[DIAGNOSER].diagnoser


@register_system
class FlexibleJointSystem:
    """The flexible-joint arm of Saif & Xiong's Example 2 (MuJoCo) with its 4-stage sliding-mode observer."""

    name = "flexible-joint"
    options_type = FlexibleJointOptions

    def diagnosers(self, options):
        return (DIAGNOSER,)

    def targets(self, options):
        return {"actuator": {"motor": TargetLimit(10.0, "V")}, "sensor": {"motor_angle": TargetLimit(np.pi, "rad")}}

    def calibration_keys(self, options):
        return [0]

    def calibrate(self, options, key, diagnosers):
        return None, False

    def mission(self, options, key, generator):
        return Mission(float(options.duration), None, {"u_amplitude": options.u_amplitude})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        return flexible_joint_parts(options, faults, seed, run_key="campaign")

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        return self.build(options, calibration, key, mission, faults, seed, diagnosers).run()
