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
           "calibrate_cartpole"]

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
