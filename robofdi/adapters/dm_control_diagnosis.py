"""dm_control's cartpole diagnosed end to end: a generalised-momentum residual on every degree of freedom of the
underactuated cart-pole (1 actuator, 2 joints), from a nominal model read from the suite's own MJCF.

Why cartpole: it is the suite's canonical underactuated system — the motor drives the cart slider, the pole
hinge is free — and its observation (cart position, cos/sin of the pole angle, both velocities) is the full
state, so the diagnoser reads only what the policy reads. The residual (De Luca & Mattone 2003, eq. (10),
:class:`~robofdi.observers.momentum.MomentumObserver`) estimates the unmodelled generalised force on every joint;
an actuator fault δu enters as B δu, so it shows on the actuated rows only (the signature of actuator a is the
set of joints with B[:, a] ≠ 0), while the unactuated hinge row carries model error only — an alarm there is
explained by no actuator and stays "unknown". The belief is the MJCF with a :class:`ModelMismatch`; the plant is
the suite's MuJoCo physics (implicit joint damping, rail limits, semi-implicit Euler at 10 ms vs the observer's
forward-Euler discretisation).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import mujoco
import numpy as np

try:
    from dm_control import suite
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.dm_control_diagnosis needs dm_control: pip install 'robofdi[dm_control]'") from None

from robofdi.adapters.dm_control import LABELS_KEY, FaultyEnvironment
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.models.manipulator import ModelMismatch
from robofdi.models.multibody import MultibodyModel
from robofdi.observers.momentum import JointMomentumDiagnoser
from robofdi.loop import Diagnosis, DiagnosisBank, Rates, Recorder
from robofdi.record import FaultLabels
from robofdi.seeding import rng

__all__ = ["CartpoleLoop", "suite_model", "cartpole_measurement", "CartpoleDiagnoser", "ExcitationPolicy", "run_episode",
           "calibrate_cartpole", "cartpole_record", "MEASUREMENTS"]

os.environ.setdefault("MUJOCO_GL", "egl")


def suite_model(domain: str, mismatch: ModelMismatch | None = None) -> MultibodyModel:
    """The nominal :class:`MultibodyModel` of a suite domain, compiled from the domain's MJCF file."""
    module = getattr(suite, domain, None)
    if module is None or not hasattr(module, "get_model_and_assets"):
        raise RobofdiError(f"domain: {domain!r} is not a dm_control suite domain; expected e.g. cartpole")
    xml, assets = module.get_model_and_assets()
    return MultibodyModel(mujoco.MjModel.from_xml_string(xml, assets), domain, mismatch)


def cartpole_measurement(observation) -> np.ndarray:
    """y = [x, θ, ẋ, θ̇] from cartpole's observation (position = [x, cos θ, sin θ], velocity = [ẋ, θ̇]) [m, rad]."""
    p, v = np.asarray(observation["position"], dtype=float), np.asarray(observation["velocity"], dtype=float)
    return np.array([p[0], np.arctan2(p[2], p[1]), v[0], v[1]])


#: The cart-pole measurement a diagnoser reads (:func:`cartpole_measurement`) and its units.
MEASUREMENTS = ["x", "theta", "x_dot", "theta_dot"]
MEASUREMENT_UNITS = ["m", "rad", "m/s", "rad/s"]


class CartpoleDiagnoser(JointMomentumDiagnoser):
    """Momentum residual on both cart-pole joints (:class:`~robofdi.observers.momentum.JointMomentumDiagnoser`):
    y = :func:`cartpole_measurement` of the observation at sample k (channels :data:`MEASUREMENTS`), u = the action
    held over the step that ended there (ū(k−1), the commanded, fault-free action). Residual components: the joint
    names (``slider`` [N], ``hinge_1`` [N·m]); signatures: one per actuator; no identification candidates."""

    def __init__(self, model: MultibodyModel, sample_time: float, gain: float = 20.0):
        super().__init__(model, sample_time, gain, measurements=MEASUREMENTS, estimate=False)


class ExcitationPolicy:
    """A seeded smooth command (three sinusoids, random phases and frequencies 0.3–1.5 Hz) plus a PD pull of the
    cart to the rail centre, so episodes differ but keep clear of the rail ends. Reads the observation only."""

    def __init__(self, seed: int, amplitude: float = 0.6):
        g = rng(seed, "policy", "excitation")
        self.freq, self.phase = g.uniform(0.3, 1.5, 3), g.uniform(0, 2 * np.pi, 3)
        self.amplitude = amplitude

    def __call__(self, t: float, observation) -> np.ndarray:
        y = cartpole_measurement(observation)
        u = self.amplitude * np.mean(np.sin(2 * np.pi * self.freq * t + self.phase)) - 0.8 * y[0] - 0.3 * y[2]
        return np.array([np.clip(u, -1.0, 1.0)])


def _observation(ts) -> dict:
    """The policy's and the diagnoser's view of a time step: the observation without the labels (belief)."""
    return {key: v for key, v in ts.observation.items() if key != LABELS_KEY}


def _episode(env: FaultyEnvironment, bank: DiagnosisBank, policy, steps: int, rec: Recorder | None = None):
    """One episode of ``steps`` control steps, every diagnosis of ``bank`` stepped at every control step with
    y = the measurement now and ū(k−1) = the action sent at the previous step (zeros at the first)."""
    ts = env.reset()
    bank.reset()
    dt = env.env.control_timestep()
    data = env.physics.data
    u_prev = np.zeros(len(env.actuators))
    for k in range(steps + 1):
        obs = _observation(ts)
        action = policy(k * dt, obs)
        y = cartpole_measurement(obs)
        t = float(np.round(k * dt, 9))
        bank.push(k, t, y, u_prev)
        if rec is not None:
            rec.append(time=t, x=np.r_[data.qpos, data.qvel], y=y, u=action, labels=ts.observation[LABELS_KEY])
        u_prev = np.asarray(action, dtype=float)
        if k < steps:
            ts = env.step(action)


def run_episode(env: FaultyEnvironment, diagnoser: CartpoleDiagnoser, policy, steps: int):
    """(times [s], residuals (N, n), labels (N, n_faults, 2)) of one episode of ``steps`` control steps."""
    dt = env.env.control_timestep()
    bank = DiagnosisBank({"momentum": Diagnosis(diagnoser)}, Rates(1.0 / dt, 1.0 / dt, "first"))
    rec = Recorder(("time", "x", "y", "u", "labels"))
    _episode(env, bank, policy, steps, rec)
    trace = bank.traces()["momentum"]
    return np.arange(steps + 1) * dt, trace.residual, np.array(rec.rows["labels"])


def cartpole_env(faults=(), seed: int = 0, task: str = "swingup") -> FaultyEnvironment:
    """The suite's cartpole ``task`` (initial state drawn from ``seed``'s "task" stream) with ``faults``."""
    task_seed = int(rng(seed, "task", "cartpole").integers(2**31))
    return FaultyEnvironment(suite.load("cartpole", task, task_kwargs={"random": task_seed}), list(faults), seed=seed)


def calibrate_cartpole(diagnoser: CartpoleDiagnoser, seeds, steps: int, skip: int, margin: float = 1.2) -> ThresholdDecision:
    """Thresholds margin × max |r| over fault-free episodes (one per seed), ignoring the first ``skip`` samples."""
    runs = [run_episode(cartpole_env((), s), diagnoser, ExcitationPolicy(s), steps)[1] for s in seeds]
    return ThresholdDecision(diagnoser.components, calibrate_thresholds(runs, margin, skip), diagnoser.signatures(),
                             blanking=skip, confirm=3)


def cartpole_record(faults, seed: int, diagnoser: CartpoleDiagnoser, decision: ThresholdDecision, steps: int,
                    policy_seed: int | None = None, name: str = "momentum", scenario: str = "dm_control-cartpole"):
    """One cartpole episode (:func:`cartpole_env` with ``faults`` and ``seed``, :class:`ExcitationPolicy` of
    ``policy_seed``) diagnosed by ``diagnoser`` + ``decision``, as a robofdi :class:`~robofdi.record.Record` at the
    10 ms control step: truth/state the physics' [x, θ, ẋ, θ̇], y_meas the observation's (the diagnoser's input),
    the diagnoser's trace under ``name``."""
    from robofdi.record import Record

    env = cartpole_env(faults, seed)
    policy = ExcitationPolicy(seed if policy_seed is None else policy_seed)
    dt = env.env.control_timestep()
    bank = DiagnosisBank({name: Diagnosis(diagnoser, decision)}, Rates(1.0 / dt, 1.0 / dt, "first"))
    rec = Recorder(("time", "x", "y", "u", "labels"))
    _episode(env, bank, policy, steps, rec)
    t = rec.array("time")
    labels = np.array(rec.rows["labels"]).reshape(len(t), len(env.faults), 2)
    units = {"actuator": "1 (action)", "sensor": "observation unit"}
    state, y = rec.array("x"), rec.array("y")
    u = rec.array("u")
    return Record(system="dm_control-cartpole", scenario=scenario, seed=int(seed),
                  rates={"control_hz": 1.0 / dt, "diagnosis_hz": 1.0 / dt}, time=t, truth_state=state,
                  faults={f.name: FaultLabels(labels[:, i, 0] > 0, labels[:, i, 1], units.get(f.family, ""))
                          for i, f in enumerate(env.faults)},
                  signals={"u_cmd": u, "y_meas": y}, diagnosers=bank.traces(), u_applied=u,
                  meta={"faults": [f.to_dict() for f in env.faults], "duration": float(t[-1]), "injection": "online"},
                  columns={"truth/state": ["x", "theta", "x_dot", "theta_dot"], "truth/u_applied": env.actuators,
                           "signals/u_cmd": env.actuators, "signals/y_meas": list(MEASUREMENTS)},
                  units={"truth/state": ["m", "rad", "m/s", "rad/s"], "truth/u_applied": ["1"],
                         "signals/u_cmd": ["1"], "signals/y_meas": list(MEASUREMENT_UNITS)})


@dataclass
class CartpoleLoop:
    """One cartpole episode, built (the loop of :meth:`robofdi.protocols.System.build`): ``diagnoser`` with its
    ``decision`` under ``name``, the ``faults``, ``steps`` control steps of 10 ms, the policy's seed. ``run`` has
    :meth:`robofdi.loop.ClosedLoop.run`'s signature; the episode's length is ``steps`` (``duration`` is not used)."""

    diagnoser: CartpoleDiagnoser
    decision: ThresholdDecision
    faults: tuple = ()
    steps: int = 200
    policy_seed: int | None = None
    name: str = "momentum"

    @property
    def diagnoses(self) -> dict:
        return {self.name: Diagnosis(self.diagnoser, self.decision)}

    def run(self, duration=None, initial_state=None, *, seed: int = 0, run_key: str = "campaign",
            scenario: str = "dm_control-cartpole", meta: dict | None = None, progress=None):
        return cartpole_record(self.faults, seed, self.diagnoser, self.decision, self.steps, self.policy_seed,
                               self.name, scenario)
