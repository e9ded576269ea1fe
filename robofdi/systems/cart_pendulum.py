"""The inverted pendulum on a motor-driven cart of Saif & Xiong's Example 3 (book ch. 1): sensor-fault detection with
the SMOO (residual 1) and the two-stage SMFO (residual 2), on the printed linearised model.

Plant (98), as printed: ẋ = A x + B u + B r_ref, y = (x1, x2, x3) + f_s, u = −K x̂ with the chapter's K (eig(A − BK)
≈ {−7.773, −4.000 ± 2.606j, −2.479}); the controller's observer [NOT GIVEN] is here a Luenberger observer on the
belief (poles −10 … −13). r_ref: a 0.2 m, 0.5 rad/s sine [assumed]. Sensor noise: Gaussian through two first-order
20 ms filters, clipped at the chapter's "max magnitude 0.01" (the digest: white noise at 1 kHz would make its
derivative dominate r2).

Observers::

    SMOO   ż = −1.399 y3 + λ ψ(y1 − z),  r1 = (λ ψ(y1 − z))_eq = 1.399 f_s3 + ḟ_s1        (λ = 5 [assumed])
    SMFO   x̂2' = x̂4 + λ1 ψ(y2 − x̂2),  x̂4' = 21.7 x̂2 − 0.2902 x̂4 + 6.236 y3 + 47.82 (u + r_ref) + λ2 ψ(ē2),
           r2 = ē2 = (λ1 ψ(y2 − x̂2))_eq = e4 + ḟ_s2                               (λ1 = 2000, λ2 = 500, sat 0.02)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.signal

from robofdi.errors import RobofdiError
from robofdi.sims.integrate import rk4
from robofdi.loop import ClosedLoop, Diagnosis, Rates
from robofdi.observers.residual import Residual
from robofdi.observers.sliding_mode import CascadeSMO, SMOSettings, Stage
from robofdi.seeding import stream

__all__ = ["PENDULUM", "CartPendulumPlant", "PendulumDiagnoser", "run_cart_pendulum"]

PENDULUM = {
    "A": np.array([[0, 0, -1.399, 0], [0, 0, 0, 1], [0, -0.1389, -0.546, 0.001905], [0, 21.7, 6.236, -0.2902]]),
    "B": np.array([[0.0], [0.0], [-4.192], [47.82]]),
    "K": np.array([[-3.7219, 3.615, 4.7994, 0.7849]]),
    "C": np.eye(4)[:3],
    "G": np.array([[0, 0], [0, 0], [1, 0], [0, 1.0]]),
}


@dataclass(eq=False)
class CartPendulumPlant:
    """Simulator protocol: the printed linear model, RK4 at 0.1 ms; u is the amplifier voltage from the controller,
    r_ref(t) is added inside the plant (the chapter: "added to the amplifier input")."""

    x0: tuple = (0.0, 0.05, 0.0, 0.0)
    noise: float = 0.01
    noise_tau: float = 0.02
    ref_amplitude: float = 0.2
    ref_frequency: float = 0.5
    control_dt: float = 0.001
    physics_dt: float = 0.0001
    system = "cart_pendulum"
    actuators = ["amplifier"]
    sensor_channels = ["base_position", "pendulum_angle", "base_velocity"]
    components: list = field(default_factory=list)
    component_kinds: dict = field(default_factory=dict)
    state_names = ["x1", "x2", "x3", "x4"]
    units = {"state": ["m", "rad", "m/s", "rad/s"], "u": ["V"], "y": ["m", "rad", "m/s"]}

    def __post_init__(self):
        self._sub = int(round(self.control_dt / self.physics_dt))
        self.reset()

    def r_ref(self, t):
        return self.ref_amplitude * np.sin(self.ref_frequency * t)

    def reset(self, initial_state=None, seed=None):
        self.x = np.array(self.x0 if initial_state is None else initial_state, dtype=float)
        if self.x.shape != (4,) or not np.all(np.isfinite(self.x)):
            raise RobofdiError(f"CartPendulumPlant.reset: field 'initial_state' must be 4 finite values, got {initial_state!r}")
        self._rng = np.random.default_rng(stream(seed, "sensor"))
        self._n, self._n1 = np.zeros(3), np.zeros(3)
        self.t = 0.0
        self.u_applied = np.zeros(1)
        return self._measure()

    def saturate(self, u):
        return np.clip(np.asarray(u, dtype=float), -10.0, 10.0)

    def step(self, u):
        u = np.asarray(u, dtype=float)
        if u.shape != (1,) or not np.isfinite(u[0]):
            raise RobofdiError(f"CartPendulumPlant: input 'u' must be one finite voltage, got {u!r}")
        self.u_applied = self.saturate(u)
        A, B, v = PENDULUM["A"], PENDULUM["B"][:, 0], self.u_applied[0]
        self.x, self.t = rk4(lambda t, x: A @ x + B * (v + self.r_ref(t)), self.x, self.physics_dt, self._sub, self.t)
        return self._measure()

    def apply_component_fault(self, kind, target, value):
        raise RobofdiError(f"CartPendulumPlant: no component faults (got {kind!r}); the chapter treats sensor faults")

    def nominal_model(self, mismatch=None):
        return dict(PENDULUM)

    @property
    def state(self):
        return self.x.copy()

    @property
    def true_output(self):
        return self.x[:3].copy()

    def _measure(self):
        if self.noise > 0:
            a = self.control_dt / self.noise_tau
            self._n1 += a * (5.0 * self.noise * self._rng.standard_normal(3) - self._n1)
            self._n += a * (self._n1 - self._n)
        return self.true_output + np.clip(self._n, -self.noise, self.noise)


class _ObserverController:
    """u = −K x̂ with a Luenberger observer on the (A, B) belief (the chapter's [17] observer is not given)."""

    def __init__(self, dt: float, model=None):
        self.model = model or PENDULUM
        A, C = self.model["A"], self.model["C"]
        self.L = scipy.signal.place_poles(A.T, C.T, [-10.0, -11.0, -12.0, -13.0]).gain_matrix.T
        self.dt = dt
        self.reset()

    def reset(self):
        self.x = np.zeros(4)
        self.u = np.zeros(1)

    def update(self, y, reference):
        A, B, C, K = (self.model[k] for k in ("A", "B", "C", "K"))
        self.x = self.x + self.dt * (A @ self.x + B[:, 0] * (self.u[0] + reference[0]) + self.L @ (y - C @ self.x))
        self.u = -K @ self.x
        return self.u


class PendulumDiagnoser:
    """Diagnoser protocol: residuals [r1 (SMOO), r2 (SMFO)] of the module docstring; the SMFO is told r_ref
    (known, added to the amplifier input) through ``reference``."""

    def __init__(self, lam_smoo: float = 5.0, lam=(2000.0, 500.0), boundary: float = 0.02, sample_time: float = 1e-3,
                 substep: float = 5e-6, tau: float = 5e-5, reference=None, model=None):
        names = ["base_position", "pendulum_angle", "base_velocity"]
        A, B = (model or PENDULUM)["A"], (model or PENDULUM)["B"][:, 0]
        a13 = float(A[0, 2])
        self.smoo = CascadeSMO(1, lambda y, u: (np.zeros((1, 1)), np.array([a13 * y[2]])),
                               [Stage(lam_smoo, 0, Wy=[1.0, 0.0, 0.0], Cx=[1.0], name="r1")],
                               SMOSettings(sample_time, substep, tau), ["amplifier"], names,
                               initial=lambda y: y[:1], where="PendulumDiagnoser SMOO (54)")
        ref = reference or (lambda t: 0.0)

        M = np.array([[0.0, 1.0], [A[3, 1], A[3, 3]]])

        def affine(y, u):
            return M, np.array([0.0, A[3, 0] * y[0] + A[3, 2] * y[2] + B[3] * u[0]])

        stages = [Stage(lam[0], 0, Wy=[0.0, 1.0, 0.0], Cx=[1.0, 0.0], name="r2"), Stage(lam[1], 1, after=0, name="s2")]
        self.smfo = CascadeSMO(2, affine, stages, SMOSettings(sample_time, substep, tau, "sat", boundary),
                               ["amplifier"], names, initial=lambda y: np.array([y[1], 0.0]), where="PendulumDiagnoser SMFO (70)")
        self._ref = ref
        self.T = sample_time
        self.inputs = ["amplifier"]
        self.measurements = ["base_position", "pendulum_angle", "base_velocity"]
        self.components = ["r1", "r2"]
        self.estimate_components, self.estimate_modes = [], []
        self.units = {"residual": ["m/s", "rad/s"], "estimate": []}
        self.reset()

    def reset(self):
        self.smoo.reset()
        self.smfo.reset()
        self.k = -1

    def signatures(self):
        from robofdi.decision import Signature

        return [Signature("base_position", {"r1"}), Signature("base_velocity", {"r1"}),
                Signature("pendulum_angle", {"r2"})]

    def update(self, y, u):
        from robofdi.observers.residual import check_measurement

        y = check_measurement(y, 3, "y")
        u = check_measurement(u, 1, "u")
        self.k += 1
        t_mid = (self.k - 0.5) * self.T
        r1 = self.smoo.update(y, u).r
        r2 = self.smfo.update(y, u + self._ref(max(t_mid, 0.0))).r
        return Residual(np.array([r1[0], r2[0]]), np.zeros(0))


@dataclass(eq=False)
class CartPoleMujoco(CartPendulumPlant):
    """Simulator protocol: ``assets/cart_pole.xml`` in MuJoCo (nonlinear, the rig of Example 3 in shape only), the
    same sensors and r_ref as :class:`CartPendulumPlant`; its belief is its own linearisation at the upright
    (:func:`mujoco_cart_pole_model`)."""

    system = "cart_pole_mujoco"

    def __post_init__(self):
        import mujoco

        from robofdi import ASSETS

        self._mj = mujoco
        self.model_mj = mujoco.MjModel.from_xml_path(str(ASSETS / "cart_pole.xml"))
        self.data = mujoco.MjData(self.model_mj)
        self.physics_dt = float(self.model_mj.opt.timestep)
        super().__post_init__()

    def reset(self, initial_state=None, seed=None):
        y = super().reset(initial_state, seed)
        mj, d = self._mj, self.data
        mj.mj_resetData(self.model_mj, d)
        d.qpos[:], d.qvel[:] = self.x[:2], self.x[2:]
        mj.mj_forward(self.model_mj, d)
        return y

    def step(self, u):
        u = np.asarray(u, dtype=float)
        if u.shape != (1,) or not np.isfinite(u[0]):
            raise RobofdiError(f"CartPoleMujoco: input 'u' must be one finite voltage, got {u!r}")
        self.u_applied = self.saturate(u)
        for _ in range(self._sub):
            self.data.ctrl[0] = self.u_applied[0] + self.r_ref(self.t)
            self._mj.mj_step(self.model_mj, self.data)
            self.t += self.physics_dt
        self.x = np.r_[self.data.qpos, self.data.qvel].astype(float)
        return self._measure()

    def nominal_model(self, mismatch=None):
        return mujoco_cart_pole_model()


def mujoco_cart_pole_model() -> dict:
    """The MuJoCo cart-pole linearised at the upright by central differences of mj_forward's qacc (A, B), C as in
    Example 3 (x1, x2, x3 measured), K an LQR gain (Q = diag(10, 10, 1, 1), R = 1; the chapter's K is its rig's)."""
    import mujoco
    import scipy.linalg

    from robofdi import ASSETS

    m = mujoco.MjModel.from_xml_path(str(ASSETS / "cart_pole.xml"))
    d = mujoco.MjData(m)

    def f(x, u):
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u
        mujoco.mj_forward(m, d)
        return np.r_[x[2:], d.qacc]

    e, I4 = 1e-6, np.eye(4)
    A = np.column_stack([(f(e * I4[i], [0.0]) - f(-e * I4[i], [0.0])) / (2 * e) for i in range(4)])
    B = ((f(np.zeros(4), [e]) - f(np.zeros(4), [-e])) / (2 * e))[:, None]
    P = scipy.linalg.solve_continuous_are(A, B, np.diag([10.0, 10.0, 1.0, 1.0]), np.eye(1))
    return {"A": A, "B": B, "K": B.T @ P, "C": np.eye(4)[:3], "G": PENDULUM["G"]}


def run_cart_pendulum(faults=(), duration: float = 10.0, seed: int = 0, run_key: str = "run", noise: float = 0.01,
                      plant: str = "printed"):
    """One run on the printed linear model (``plant="printed"``) or the MuJoCo cart-pole ("mujoco") → (record,
    diagnoser); the diagnoser and the controller use the plant's belief (the printed model, or the linearisation)."""
    if plant not in ("printed", "mujoco"):
        raise RobofdiError(f"run_cart_pendulum: field 'plant' must be 'printed' or 'mujoco', got {plant!r}")
    model = PENDULUM if plant == "printed" else mujoco_cart_pole_model()
    plant = CartPendulumPlant(noise=noise) if plant == "printed" else CartPoleMujoco(noise=noise)
    diag = PendulumDiagnoser(reference=plant.r_ref, model=model)
    ctrl = _ObserverController(plant.control_dt, model)
    loop = ClosedLoop(plant, ctrl, lambda t: np.array([plant.r_ref(t)]), faults=faults,
                      diagnoses={"smo": Diagnosis(diag)}, rates=Rates(1000.0, 1000.0, "first"),
                      reference_columns=["r_ref"], reference_units=["V"])
    return loop.run(duration, seed=seed, run_key=run_key, scenario="ch1-cart-pendulum"), diag
