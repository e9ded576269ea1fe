"""The three-state motor of Saif & Xiong's Examples 4 and 5 (book ch. 1; Birk & Zeitz 1988): nonlinear SMO state
estimation (Case 3) and FDI of two actuator faults with the multiple-observer scheme and its logic table.

Plant (x1 rotor angle [rad], x2 speed deviation [rad/s], x3 field flux linkage [1])::

    ẋ1 = x2,  ẋ2 = −A1 x2 − A2 x3 sin x1 − A3 sin 2x1 + u1 + f_a1,  ẋ3 = −D1 x3 + D2 cos x1 + u2 + f_a2 + d2

A1 = 0.2703, A2 = 12.01, A3 = −48.04, D1 = 0.3222, D2 = 1.9, u1 = 36.19, u2 = 1.9333; Example 4 Case 3:
d2 = ΔD1 x3 + ΔD2 cos x1 (0.1, 0.6), y = x1; Example 5: no d, y = (x1, x3), f_a1 and f_a2 are actuator-additive
faults on u1 and u2 (the loop's fault injector). :class:`MotorPlant` integrates it with RK4 at 0.1 ms (Simulator
protocol; a nonlinear ODE, no MuJoCo body).

Observers (Saif & Xiong's, with the digest's reconstructions: +u1, +u2 in every row, λ3 for the Case 1 λ1):

* :func:`motor_smo` — Example 4 Case 3: x̂1' = x̂2 + λ1ψ(y1 − x̂1), x̂2' = −A1x̂2 − A2x̂3 sin y1 − A3 sin 2y1 + u1 +
  λ2ψ(ē2), x̂3' = −D1x̂3 + D2 cos y1 + u2 + λ3ψ(ē3), ē2 = (λ1ψ(ē1))_eq, ē3 = (λ2ψ(ē2))_eq / (−A2 sin y1); stage 3
  is held off (ē3 = 0) where |sin y1| < ``sin_guard`` (the division by sin y1, digest E4.3).
* :func:`motor_smo_case1` — Example 4 Case 1 (d1 and d2 both on, y = (x1, x3)): x̂1' = x̂2 + λ1ψ(y1 − x̂1),
  x̂2' = −A1x̂2 − A2y2 sin y1 − A3 sin 2y1 + u1 + λ2ψ((λ1ψ(ē1))_eq), x̂3' = −D1x̂3 + D2 cos y1 + u2 + λ3ψ(y2 − x̂3)
  (the chapter's last gain λ1 read as λ3); in sliding the equivalent controls of stages 2 and 3 are d1 and d2.
* :class:`MotorFDI` — Example 5: the same SMO with y2 measured (observer 2: r2 = (λ3ψ(ē3))_eq, r3 = ē3) plus the
  SMOO (99) z' = −D1y2 + D2 cos y1 + u2 + λψ(y2 − z), r1 = (λψ(y2 − z))_eq = f_a2. Residuals [r1, r2, r3].
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robofdi.checks import check_fields, is_number
from robofdi.errors import RobofdiError
from robofdi.sims.integrate import rk4
from robofdi.faults import Fault, Ramp
from robofdi.loop import ClosedLoop, Diagnosis, Rates
from robofdi.observers.sliding_mode import CascadeSMO, SMOSettings, Stage
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.seeding import stream
from robofdi.systems import register_system

__all__ = ["MOTOR", "MotorPlant", "motor_coordinates", "motor_coordinates_inverse", "motor_smo", "motor_smo_case1",
           "CASE1_DA", "MotorFDI",
           "MotorOptions", "run_motor", "MotorSystem", "EXAMPLE5_FAULTS", "fdi_rules"]

MOTOR = {"A1": 0.2703, "A2": 12.01, "A3": -48.04, "D1": 0.3222, "D2": 1.9, "dD1": 0.1, "dD2": 0.6,
         "u1": 36.19, "u2": 1.9333, "x0": (0.88, 0.0, 6.5), "xhat0": (0.8, 0.0, 5.0)}

#: Example 5 [assumed, the chapter gives only "abrupt f_a1 at t = 18 s"]: f_a1 ramps 0 → 2 over 5–10 s and steps
#: by +3 at 18 s; f_a2 ramps 0 → 1 over 12–16 s.
EXAMPLE5_FAULTS = (
    Fault("fa1_ramp", "actuator_additive", "u1", onset=5.0, magnitude=2.0, profile=Ramp(5.0)),
    Fault("fa1_step", "actuator_additive", "u1", onset=18.0, magnitude=3.0),
    Fault("fa2_ramp", "actuator_additive", "u2", onset=12.0, magnitude=1.0, profile=Ramp(4.0)),
)


#: Example 4 Case 1's d1 = ΔA1 x2 + ΔA2 x3 sin x1 + ΔA3 sin 2x1 [assumed: the chapter gives no ΔA; 10 % of A1..A3].
CASE1_DA = (0.1 * MOTOR["A1"], 0.1 * MOTOR["A2"], 0.1 * MOTOR["A3"])


def case1_d1(x, da=CASE1_DA) -> float:
    """d1 of Example 4 Case 1 (:data:`CASE1_DA`)."""
    return da[0] * x[1] + da[1] * x[2] * np.sin(x[0]) + da[2] * np.sin(2 * x[0])


def case1_d2(x, p=MOTOR) -> float:
    """d2 of Example 4 (Cases 1 and 3): ΔD1 x3 + ΔD2 cos x1."""
    return p["dD1"] * x[2] + p["dD2"] * np.cos(x[0])


def _f(x, u, p, d2: bool, d1: tuple | None = None):
    x1, x2, x3 = x
    dx3 = -p["D1"] * x3 + p["D2"] * np.cos(x1) + u[1]
    if d2:
        dx3 += case1_d2(x, p)
    dx2 = -p["A1"] * x2 - p["A2"] * x3 * np.sin(x1) - p["A3"] * np.sin(2 * x1) + u[0]
    if d1 is not None:
        dx2 += case1_d1(x, d1)
    return np.array([x2, dx2, dx3])


def motor_coordinates(x, p=MOTOR) -> np.ndarray:
    """Φ of Example 4 Case 3: ξ = (x1, x2, f2(x)), f2 = −A1x2 − A2x3 sin x1 − A3 sin 2x1 (the chain y, ẏ, ÿ)."""
    x1, x2, x3 = x
    return np.array([x1, x2, -p["A1"] * x2 - p["A2"] * x3 * np.sin(x1) - p["A3"] * np.sin(2 * x1)])


def motor_coordinates_inverse(xi, p=MOTOR) -> np.ndarray:
    """Φ⁻¹: x3 = (ξ3 + A1ξ2 + A3 sin 2ξ1) / (−A2 sin ξ1), defined where sin ξ1 ≠ 0."""
    s = np.sin(xi[0])
    if abs(s) < 1e-12:
        raise RobofdiError("motor_coordinates_inverse: sin ξ1 = 0, where the map Φ is singular (relative degree lost)")
    return np.array([xi[0], xi[1], (xi[2] + p["A1"] * xi[1] + p["A3"] * np.sin(2 * xi[0])) / (-p["A2"] * s)])


@dataclass(eq=False)
class MotorPlant:
    """Simulator protocol: the motor ODE (module docstring), RK4 at ``physics_dt`` inside each ``control_dt``.
    outputs: "x1" (Example 4) or "x1x3" (Example 5, Example 4 Case 1); d2: Example 4's unknown input on x3; d1:
    None, or (ΔA1, ΔA2, ΔA3) of Example 4 Case 1's unknown input on x2 (:data:`CASE1_DA`); noise: std per output."""

    outputs: str = "x1"
    d2: bool = True
    d1: tuple | None = None
    x0: tuple = MOTOR["x0"]
    noise: float = 0.0
    control_dt: float = 0.001
    physics_dt: float = 0.0001
    system = "motor"
    actuators = ["u1", "u2"]
    components: list = field(default_factory=list)
    component_kinds: dict = field(default_factory=dict)
    state_names = ["x1", "x2", "x3"]

    def __post_init__(self):
        if self.outputs not in ("x1", "x1x3"):
            raise RobofdiError(f"MotorPlant: field 'outputs' must be 'x1' or 'x1x3', got {self.outputs!r}")
        self.sensor_channels = ["rotor_angle"] if self.outputs == "x1" else ["rotor_angle", "flux"]
        self.units = {"state": ["rad", "rad/s", "1"], "u": ["1", "1"], "y": ["rad", "1"][:len(self.sensor_channels)]}
        self._sub = int(round(self.control_dt / self.physics_dt))
        self.reset()

    def reset(self, initial_state=None, seed=None):
        self.x = np.array(self.x0 if initial_state is None else initial_state, dtype=float)
        if self.x.shape != (3,) or not np.all(np.isfinite(self.x)):
            raise RobofdiError(f"MotorPlant.reset: field 'initial_state' must be 3 finite values, got {initial_state!r}")
        self._rng = np.random.default_rng(stream(seed, "sensor"))
        self.u_applied = np.zeros(2)
        return self._measure()

    def saturate(self, u):
        return np.asarray(u, dtype=float)

    def step(self, u):
        u = np.asarray(u, dtype=float)
        if u.shape != (2,) or not np.all(np.isfinite(u)):
            raise RobofdiError(f"MotorPlant: input 'u' must be 2 finite values (u1, u2), got {u!r}")
        self.u_applied = u.copy()
        self.x, _ = rk4(lambda t, x: _f(x, u, MOTOR, self.d2, self.d1), self.x, self.physics_dt, self._sub)
        return self._measure()

    def apply_component_fault(self, kind, target, value):
        raise RobofdiError(f"MotorPlant: no component faults (got {kind!r}); f_a1, f_a2 are actuator_additive on u1, u2")

    def nominal_model(self, mismatch=None):
        return dict(MOTOR)

    @property
    def state(self):
        return self.x.copy()

    @property
    def true_output(self):
        return self.x[[0]] if self.outputs == "x1" else self.x[[0, 2]]

    def _measure(self):
        y = self.true_output
        return y + self.noise * self._rng.standard_normal(y.size) if self.noise > 0 else y


def _smo_parts(p, lam, sin_guard, y2: bool):
    A1, A2, A3, D1, D2 = (p[k] for k in ("A1", "A2", "A3", "D1", "D2"))

    def affine(y, u):
        s1 = np.sin(y[0])
        M = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, -A1, -A2 * s1, 0.0], [0.0, 0.0, -D1, 0.0], [0.0, 0.0, 0.0, 0.0]])
        c = np.array([0.0, -A3 * np.sin(2 * y[0]) + u[0], D2 * np.cos(y[0]) + u[1],
                      (-D1 * y[1] + D2 * np.cos(y[0]) + u[1]) if y2 else 0.0])
        return M, c

    def g3(y):
        s1 = np.sin(y[0])
        return 0.0 if abs(s1) < sin_guard else 1.0 / (-A2 * s1)

    stages = [Stage(lam[0], 0, Wy=np.eye(2 if y2 else 1)[0], Cx=[1, 0, 0, 0], name="s1"),
              Stage(lam[1], 1, after=0, name="s2"), Stage(lam[2], 2, after=1, gain=g3, name="r2")]
    if y2:
        stages.append(Stage(lam[3], 3, Wy=[0.0, 1.0], Cx=[0, 0, 0, 1], name="r1"))
    return affine, stages, g3


def motor_smo(settings: SMOSettings, lam=(200.0, 200.0, 200.0), xhat0=MOTOR["xhat0"], sin_guard: float = 0.05,
              p=MOTOR, keep_history: bool = True) -> CascadeSMO:
    """Example 4 Case 3's nonlinear SMO (51) (module docstring); residuals: the three equivalent controls."""
    affine, stages, _ = _smo_parts(p, lam, sin_guard, False)
    return CascadeSMO(4, affine, stages, settings, ["u1", "u2"], ["rotor_angle"], x0=list(xhat0) + [0.0],
                      state_names=["x1", "x2", "x3", "unused"], residual_units=["rad/s", "rad/s^2", "1/s"],
                      keep_history=keep_history, where="motor_smo")


def motor_smo_case1(settings: SMOSettings, lam=(200.0, 200.0, 200.0), xhat0=MOTOR["xhat0"], p=MOTOR,
                    keep_history: bool = True) -> CascadeSMO:
    """Example 4 Case 1's SMO (module docstring; measurements y = (x1, x3)). Residuals: the equivalent controls
    r_s1 = (λ1ψ(ē1))_eq (= e2 in sliding), r_d1 = (λ2ψ(ē2))_eq (= d1), r_d2 = (λ3ψ(y2 − x̂3))_eq (= d2). Stage 2
    reads stage 1, so stage it (``settings.activation`` or a :class:`~robofdi.observers.sliding_mode.SlidingDetector`)."""
    A1, A2, A3, D1, D2 = (p[k] for k in ("A1", "A2", "A3", "D1", "D2"))
    M = np.array([[0.0, 1.0, 0.0], [0.0, -A1, 0.0], [0.0, 0.0, -D1]])

    def affine(y, u):
        return M, np.array([0.0, -A2 * y[1] * np.sin(y[0]) - A3 * np.sin(2 * y[0]) + u[0], D2 * np.cos(y[0]) + u[1]])

    stages = [Stage(lam[0], 0, Wy=[1.0, 0.0], Cx=[1, 0, 0], name="r_s1"), Stage(lam[1], 1, after=0, name="r_d1"),
              Stage(lam[2], 2, Wy=[0.0, 1.0], Cx=[0, 0, 1], name="r_d2")]
    return CascadeSMO(3, affine, stages, settings, ["u1", "u2"], ["rotor_angle", "flux"], x0=list(xhat0),
                      state_names=["x1", "x2", "x3"], residual_units=["rad/s", "rad/s^2", "1/s"],
                      keep_history=keep_history, where="motor_smo_case1")


class MotorFDI:
    """Diagnoser protocol: Example 5's two observers (module docstring) in one sub-stepped integration.
    Residuals r1 = (λψ(y2 − z))_eq (= f_a2), r2 = (λ3ψ(ē3))_eq (interval means of λψ, :class:`CascadeSMO`),
    r3 = ē3 = (λ2ψ(ē2))_eq/(−A2 sin y1), its 1 ms mean (the in-sample peak of the stage's low-pass z is no use
    here: it reads the filter's switching ripple, measured |r3| ≈ 12–16 against the 0.47 peak of the fault)."""

    def __init__(self, settings: SMOSettings, lam=(200.0, 200.0, 200.0, 200.0), xhat0=MOTOR["x0"],
                 sin_guard: float = 0.05, p=MOTOR):
        affine, stages, self._g3 = _smo_parts(p, lam, sin_guard, True)
        self.smo = CascadeSMO(4, affine, stages, settings, ["u1", "u2"], ["rotor_angle", "flux"],
                              x0=list(xhat0) + [xhat0[2]], where="MotorFDI")
        self.inputs, self.measurements = self.smo.inputs, self.smo.measurements
        self.components = ["r1", "r2", "r3"]
        self.estimate_components = ["u2"]
        self.estimate_modes = ["level"]
        self.units = {"residual": ["1/s", "1/s", "1"], "estimate": ["1"]}

    def reset(self):
        self.smo.reset()

    def signatures(self):
        from robofdi.decision import Signature

        return [Signature("u2", {"r1", "r2"}), Signature("u1", {"r2"}, {"r3"})]

    @property
    def state_estimate(self):
        return self.smo.state_estimate[:3]

    def update(self, y, u):
        from robofdi.observers.residual import Residual

        res = self.smo.update(y, u)
        m = res.r                                           # interval means of λψ per stage
        g = self._g3(np.asarray(y, dtype=float))
        return Residual(np.array([m[3], m[2], g * m[1]]), np.array([m[3]]))


def fdi_rules():
    """Example 5's logic table: r1 = r2 ≠ 0 → f_a2 (u2); r1 = 0, r2 ≠ 0 → f_a1 (u1); r1 ≠ r2, both ≠ 0 → both."""
    from robofdi.decision.peak import LogicRule

    return [LogicRule(("u2",), {"r1": True, "r2": True}, agree=(("r1", "r2"),)),
            LogicRule(("u1",), {"r1": False, "r2": True}),
            LogicRule(("u1", "u2"), {"r1": True, "r2": True}, differ=(("r1", "r2"),))]


@dataclass(frozen=True)
class MotorOptions:
    """example: 4 (Case 3 estimation, y = x1, d2 on) or 5 (FDI, y = (x1, x3)); duration [s]; gains λ; tau [s];
    substep [s]; activation of the stages [s] (Example 4; the chapter gives none)."""

    example: int = 5
    duration: float = 20.0
    gains: tuple = (200.0, 200.0, 200.0, 200.0)
    tau: float = 1e-4
    substep: float = 1e-7
    activation: tuple = (0.0, 0.05, 0.2)

    def __post_init__(self):
        object.__setattr__(self, "gains", tuple(float(g) for g in self.gains))
        object.__setattr__(self, "activation", tuple(float(a) for a in self.activation))
        check_fields("motor", self, [("example", self.example in (4, 5), "4 or 5"),
                                     ("duration", is_number(self.duration) and 0 < self.duration <= 120, "a time in (0, 120] s"),
                                     ("gains", len(self.gains) == 4 and min(self.gains) > 0, "4 gains > 0"),
                                     ("activation", len(self.activation) == 3, "3 switch-on times [s]")])


class _Constant:
    def __init__(self, u):
        self.u = np.asarray(u, dtype=float)

    def __call__(self, t):
        return self.u

    def update(self, y, reference):
        return self.u


def run_motor(options: MotorOptions = MotorOptions(), faults=(), seed: int = 0, run_key: str = "run"):
    """One run of Example 4 (→ record, the SMO with its history) or Example 5 (→ record, the MotorFDI)."""
    parts = motor_parts(options, faults, seed, run_key)
    return parts.run(), parts.diagnoses["smo"].diagnoser


def motor_parts(options: MotorOptions = MotorOptions(), faults=(), seed: int = 0, run_key: str = "run") -> Parts:
    """One run of Example 4 or 5, built (:class:`~robofdi.protocols.Parts`)."""
    T = 1e-3
    if options.example == 4:
        plant = MotorPlant("x1", True)
        diag = motor_smo(SMOSettings(T, options.substep, options.tau, activation=options.activation), options.gains[:3])
    else:
        plant = MotorPlant("x1x3", False)
        diag = MotorFDI(SMOSettings(T, options.substep, options.tau, activation=options.activation + (0.0,)),
                        options.gains)
    u = _Constant([MOTOR["u1"], MOTOR["u2"]])
    loop = ClosedLoop(plant, u, u, faults=faults, diagnoses={"smo": Diagnosis(diag)}, rates=Rates(1000.0, 1000.0, "first"),
                      reference_columns=["u1", "u2"], reference_units=["1", "1"])
    return Parts(loop, options.duration, None, seed, run_key, f"ch1-motor-example{options.example}", {})


@register_system
class MotorSystem:
    """The three-state motor of Saif & Xiong's Examples 4–5 (ODE) with the SMO / the two-observer FDI scheme."""

    name = "motor"
    options_type = MotorOptions

    def diagnosers(self, options):
        return ("smo",)

    def targets(self, options):
        return {"actuator": {"u1": TargetLimit(5.0, "1"), "u2": TargetLimit(2.0, "1")},
                "sensor": {"rotor_angle": TargetLimit(np.pi, "rad")}}

    def calibration_keys(self, options):
        return [0]

    def calibrate(self, options, key, diagnosers):
        return None, False

    def mission(self, options, key, generator):
        return Mission(float(options.duration), None, {})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        return motor_parts(options, faults, seed, run_key="campaign")

    def run(self, options, calibration, key, mission, faults, seed, diagnosers):
        return self.build(options, calibration, key, mission, faults, seed, diagnosers).run()
