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

import mujoco
import numpy as np

try:
    from dm_control import suite
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.dm_control_diagnosis needs dm_control: pip install 'robofdi[dm_control]'") from None

from robofdi.adapters.dm_control import LABELS_KEY, FaultyEnvironment
from robofdi.decision import Signature, ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.models.manipulator import ModelMismatch
from robofdi.models.multibody import MultibodyModel
from robofdi.observers.momentum import MomentumObserver
from robofdi.seeding import rng

__all__ = ["suite_model", "cartpole_measurement", "CartpoleDiagnoser", "ExcitationPolicy", "run_episode",
           "calibrate_cartpole", "cartpole_record"]

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


class CartpoleDiagnoser:
    """Momentum residual on both cart-pole joints, fed with observations and the commanded (fault-free) actions.

    Residual components: the joint names (``slider`` [N], ``hinge_1`` [N·m]); signatures: one per actuator."""

    def __init__(self, model: MultibodyModel, sample_time: float, gain: float = 20.0):
        self.model = model
        self.observer = MomentumObserver(model, sample_time, gain)
        self.components = list(model.joint_names)
        self.signatures = [Signature(a, frozenset(j for j, b in zip(model.joint_names, model.B[:, k]) if b != 0))
                           for k, a in enumerate(model.actuator_names)]
        self.reset()

    def reset(self) -> None:
        self.observer.reset()
        self._tau = np.zeros(self.model.n)

    def update(self, observation, action) -> np.ndarray:
        """Residual after ``observation``; ``action`` is the command sent at this sample (used at the next one)."""
        r = self.observer.update(cartpole_measurement(observation), self._tau).r
        self._tau = self.model.joint_torque(action)
        return r


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


def run_episode(env: FaultyEnvironment, diagnoser: CartpoleDiagnoser, policy, steps: int):
    """(times [s], residuals (N, n), labels (N, n_faults, 2)) of one episode of ``steps`` control steps."""
    ts = env.reset()
    diagnoser.reset()
    dt = env.env.control_timestep()
    times, res, labels = [], [], []
    for k in range(steps + 1):
        obs = {key: v for key, v in ts.observation.items() if key != LABELS_KEY}  # belief: no labels
        action = policy(k * dt, obs)
        res.append(diagnoser.update(obs, action))
        times.append(k * dt)
        labels.append(ts.observation[LABELS_KEY])
        if k < steps:
            ts = env.step(action)
    return np.array(times), np.array(res), np.array(labels)


def cartpole_env(faults=(), seed: int = 0, task: str = "swingup") -> FaultyEnvironment:
    """The suite's cartpole ``task`` (initial state drawn from ``seed``'s "task" stream) with ``faults``."""
    task_seed = int(rng(seed, "task", "cartpole").integers(2**31))
    return FaultyEnvironment(suite.load("cartpole", task, task_kwargs={"random": task_seed}), list(faults), seed=seed)


def calibrate_cartpole(diagnoser: CartpoleDiagnoser, seeds, steps: int, skip: int, margin: float = 1.2) -> ThresholdDecision:
    """Thresholds margin × max |r| over fault-free episodes (one per seed), ignoring the first ``skip`` samples."""
    runs = [run_episode(cartpole_env((), s), diagnoser, ExcitationPolicy(s), steps)[1] for s in seeds]
    return ThresholdDecision(diagnoser.components, calibrate_thresholds(runs, margin, skip), diagnoser.signatures,
                             blanking=skip, confirm=3)


def cartpole_record(faults, seed: int, diagnoser: CartpoleDiagnoser, decision: ThresholdDecision, steps: int,
                    policy_seed: int | None = None, name: str = "momentum", scenario: str = "dm_control-cartpole"):
    """One cartpole episode (:func:`cartpole_env` with ``faults`` and ``seed``, :class:`ExcitationPolicy` of
    ``policy_seed``) diagnosed by ``diagnoser`` + ``decision``, as a robofdi :class:`~robofdi.record.Record` at the
    10 ms control step: truth/state the physics' [x, θ, ẋ, θ̇], y_meas the observation's (the diagnoser's input),
    the diagnoser's trace under ``name``."""
    from robofdi.record import DiagnoserTrace, FaultLabels, Record

    env = cartpole_env(faults, seed)
    policy = ExcitationPolicy(seed if policy_seed is None else policy_seed)
    ts = env.reset()
    diagnoser.reset()
    decision.reset()
    dt = env.env.control_timestep()
    rows = {k: [] for k in ("time", "x", "y", "u", "labels", "r", "alarm", "isolated")}
    data = env.physics.data
    for k in range(steps + 1):
        obs = {key: v for key, v in ts.observation.items() if key != LABELS_KEY}
        action = policy(k * dt, obs)
        r = diagnoser.update(obs, action)
        alarms = decision.update(r)
        for key, value in (("time", k * dt), ("x", np.r_[data.qpos, data.qvel]), ("y", cartpole_measurement(obs)), ("u", action),
                           ("labels", ts.observation[LABELS_KEY]), ("r", r), ("alarm", alarms.alarm),
                           ("isolated", "+".join(alarms.isolated))):
            rows[key].append(value)
        if k < steps:
            ts = env.step(action)
    t = np.round(np.array(rows["time"]), 9)
    labels = np.array(rows["labels"]).reshape(len(t), len(env.faults), 2)
    comps = diagnoser.components
    units = {"actuator": "1 (action)", "sensor": "observation unit"}
    trace = DiagnoserTrace(time=t, residual=np.array(rows["r"]), threshold=np.asarray(decision.threshold, dtype=float),
                           alarm=np.array(rows["alarm"], dtype=bool), isolated=np.array(rows["isolated"], dtype=object),
                           estimate=np.zeros((len(t), 0)), components=list(comps), estimate_components=[],
                           units={"residual": ["N", "N·m"], "estimate": []})
    state, y = np.array(rows["x"]), np.array(rows["y"])
    u = np.array(rows["u"])
    return Record(system="dm_control-cartpole", scenario=scenario, seed=int(seed),
                  rates={"control_hz": 1.0 / dt, "diagnosis_hz": 1.0 / dt}, time=t, truth_state=state,
                  faults={f.name: FaultLabels(labels[:, i, 0] > 0, labels[:, i, 1], units.get(f.family, ""))
                          for i, f in enumerate(env.faults)},
                  signals={"u_cmd": u, "y_meas": y}, diagnosers={name: trace}, u_applied=u,
                  meta={"faults": [f.to_dict() for f in env.faults], "duration": float(t[-1]), "injection": "online"},
                  columns={"truth/state": ["x", "theta", "x_dot", "theta_dot"], "truth/u_applied": env.actuators,
                           "signals/u_cmd": env.actuators, "signals/y_meas": ["x", "theta", "x_dot", "theta_dot"]},
                  units={"truth/state": ["m", "rad", "m/s", "rad/s"], "truth/u_applied": ["1"],
                         "signals/u_cmd": ["1"], "signals/y_meas": ["m", "rad", "m/s", "rad/s"]})
