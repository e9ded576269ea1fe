"""Gymnasium's MuJoCo environments diagnosed online: a generalised-momentum residual on the joints the observation
reports, from a nominal model compiled from the environment's own MJCF file.

For an environment whose actuators are motors on joints (Reacher, Pusher, InvertedPendulum, ...), a
:class:`JointReadout` says where the joint positions (or their cos/sin) and velocities sit in the observation; the
belief is a :class:`~robofdi.models.multibody.MultibodyModel` of the environment's MJCF *file* (``env.unwrapped.fullpath``,
never the running simulator's model) with a :class:`~robofdi.models.manipulator.ModelMismatch`, over those joints
(every other joint, e.g. Reacher's target slides, is locked). The residual (De Luca & Mattone 2003, eq. (10),
:class:`~robofdi.observers.momentum.MomentumObserver`) estimates the unmodelled generalised force on every joint;
an actuator fault δu enters as B δu, so the signature of actuator a is the set of joints with B[:, a] ≠ 0. The
diagnoser reads the faulty observation (what the policy reads) and the action the policy commanded; the plant is
Gymnasium's MuJoCo physics (its integrator, joint limits, contacts) — everything a real controller would face.

::

    from robofdi.adapters.gymnasium_diagnosis import calibrate, diagnose_episode, momentum_diagnoser

    diagnoser = momentum_diagnoser("Reacher-v5")
    decision = calibrate("Reacher-v5", diagnoser, seeds=range(3), steps=150)
    record = diagnose_episode("Reacher-v5", ["actuator_additive:actuator1:0.1@1.5"], seed=7,
                              diagnoser=diagnoser, decision=decision, steps=150)
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

try:
    import gymnasium
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.gymnasium_diagnosis needs gymnasium: pip install 'robofdi[gymnasium]'") from None

from robofdi.adapters.gymnasium import FaultyEnv
from robofdi.decision import ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.loop import Diagnosis, DiagnosisBank, Rates
from robofdi.models.manipulator import ModelMismatch
from robofdi.models.multibody import MultibodyModel
from robofdi.observers.momentum import JointMomentumDiagnoser
from robofdi.record import Record
from robofdi.seeding import rng

__all__ = ["JointReadout", "READOUTS", "readout_for", "env_model", "JointMomentumDiagnoser", "momentum_diagnoser",
           "ExcitationPolicy", "calibrate", "diagnose_episode", "make_env"]


def _indices(name: str, value) -> tuple[int, ...] | None:
    if value is None:
        return None
    out = tuple(value)
    if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) and i >= 0 for i in out):
        raise RobofdiError(f"JointReadout: field {name!r} must hold observation indices >= 0, got {value!r}")
    return tuple(int(i) for i in out)


@dataclass(frozen=True)
class JointReadout:
    """Where joints ``joints`` sit in a flat observation: their positions at ``position`` [rad or m] — or, for
    revolute joints reported as cos q and sin q, at ``cos`` and ``sin`` — and their velocities at ``velocity``
    [rad/s or m/s]. Called on an observation it returns y = [q; q̇] (q = atan2(sin, cos) for the second form)."""

    joints: tuple[str, ...]
    velocity: tuple[int, ...]
    position: tuple[int, ...] | None = None
    cos: tuple[int, ...] | None = None
    sin: tuple[int, ...] | None = None

    def __post_init__(self):
        joints = tuple(self.joints)
        if not joints or not all(isinstance(j, str) and j for j in joints):
            raise RobofdiError(f"JointReadout: field 'joints' must be a non-empty list of joint names, got {self.joints!r}")
        object.__setattr__(self, "joints", joints)
        for name in ("velocity", "position", "cos", "sin"):
            object.__setattr__(self, name, _indices(name, getattr(self, name)))
        trig = self.cos is not None or self.sin is not None
        if (self.position is None) == (not trig) or (trig and (self.cos is None or self.sin is None)):
            raise RobofdiError("JointReadout: give the joint positions either as 'position' or as both 'cos' and 'sin'")
        for name in ("velocity", "position", "cos", "sin"):
            value = getattr(self, name)
            if value is not None and len(value) != len(joints):
                raise RobofdiError(f"JointReadout: field {name!r} has {len(value)} indices for {len(joints)} joints")

    @property
    def measurements(self) -> list[str]:
        return [f"{j}_pos" for j in self.joints] + [f"{j}_vel" for j in self.joints]

    def __call__(self, observation) -> np.ndarray:
        o = np.asarray(observation, dtype=float).ravel()
        top = max(max(getattr(self, k) or (0,)) for k in ("velocity", "position", "cos", "sin"))
        if o.size <= top:
            raise RobofdiError(f"JointReadout: the observation has {o.size} entries; the readout reads index {top}")
        q = o[list(self.position)] if self.position is not None else np.arctan2(o[list(self.sin)], o[list(self.cos)])
        return np.concatenate([q, o[list(self.velocity)]])


#: Readouts of Gymnasium's MuJoCo environments whose actuators drive joints (by the environment's name, any version
#: with that observation layout: Reacher v4/v5, Pusher v4/v5, InvertedPendulum v4/v5).
READOUTS = {
    "Reacher": JointReadout(("joint0", "joint1"), velocity=(6, 7), cos=(0, 1), sin=(2, 3)),
    "Pusher": JointReadout(("r_shoulder_pan_joint", "r_shoulder_lift_joint", "r_upper_arm_roll_joint", "r_elbow_flex_joint",
                            "r_forearm_roll_joint", "r_wrist_flex_joint", "r_wrist_roll_joint"),
                           velocity=tuple(range(7, 14)), position=tuple(range(7))),
    "InvertedPendulum": JointReadout(("slider", "hinge"), velocity=(2, 3), position=(0, 1)),
}


def readout_for(env) -> JointReadout:
    """The :data:`READOUTS` entry of ``env`` (by its spec's name), or an error naming the known ones."""
    spec = getattr(env, "spec", None)
    name = getattr(spec, "name", None)
    if name not in READOUTS:
        raise RobofdiError(f"env: no joint readout known for {getattr(spec, 'id', type(env).__name__)!r}; expected one of "
                           f"{', '.join(READOUTS)} or a JointReadout of your own")
    return READOUTS[name]


def env_model(env, readout: JointReadout | None = None, mismatch: ModelMismatch | None = None) -> MultibodyModel:
    """The nominal :class:`MultibodyModel` of a Gymnasium MuJoCo environment ``env`` over ``readout``'s joints,
    compiled from the environment's own MJCF file (``env.unwrapped.fullpath``) with ``mismatch``."""
    path = getattr(env.unwrapped, "fullpath", None)
    if not isinstance(path, str):
        raise RobofdiError(f"env: {type(env.unwrapped).__name__} is not a Gymnasium MuJoCo environment (no MJCF 'fullpath')")
    readout = readout_for(env) if readout is None else readout
    spec = getattr(env, "spec", None)
    return MultibodyModel(mujoco.MjModel.from_xml_path(path), getattr(spec, "id", "gymnasium"), mismatch,
                          joints=list(readout.joints))


def make_env(env_id: str, steps: int, faults=(), seed: int = 0, diagnosis: DiagnosisBank | None = None,
             readout: JointReadout | None = None, **kwargs) -> FaultyEnv:
    """``gymnasium.make(env_id, max_episode_steps=steps, **kwargs)`` in a :class:`FaultyEnv` with ``faults``, the fault
    ``seed``, and ``diagnosis`` reading the environment's :func:`readout_for` (or ``readout``)."""
    env = gymnasium.make(env_id, max_episode_steps=steps, **kwargs)
    readout = readout_for(env) if readout is None else readout
    return FaultyEnv(env, list(faults), seed=seed, diagnosis=diagnosis, measure=readout)


def momentum_diagnoser(env_id: str, mismatch: ModelMismatch | None = None, gain: float = 10.0,
                       readout: JointReadout | None = None, **kwargs) -> JointMomentumDiagnoser:
    """A :class:`JointMomentumDiagnoser` of ``env_id`` at its step (``env.unwrapped.dt``) from :func:`env_model`
    (default mismatch: 5 % mass and inertia, 10 % damping and armature errors)."""
    env = gymnasium.make(env_id, **kwargs)
    try:
        mismatch = ModelMismatch(mass=0.05, inertia=0.05, damping=0.1, armature=0.1) if mismatch is None else mismatch
        return JointMomentumDiagnoser(env_model(env, readout, mismatch), float(env.unwrapped.dt), gain)
    finally:
        env.close()


class ExcitationPolicy:
    """A seeded reaching motion for fully actuated arms (Reacher, Pusher): each joint tracks
    q_ref = q_mid + a · (mean of three sinusoids, random phases, 0.2–0.8 Hz) with a computed-torque PD on the nominal
    model (natural frequency ``omega`` [rad/s], damping 0.7), clipped to the action space. Reads the observation only."""

    def __init__(self, model: MultibodyModel, readout: JointReadout, seed: int, amplitude: float = 0.8, omega: float = 6.0):
        g = rng(seed, "policy", "excitation")
        n = model.n
        self.model, self.readout, self.omega = model, readout, float(omega)
        self.freq, self.phase = g.uniform(0.2, 0.8, (n, 3)), g.uniform(0, 2 * np.pi, (n, 3))
        lo, hi = model.joint_range[:, 0], model.joint_range[:, 1]
        bounded = np.isfinite(lo) & np.isfinite(hi)
        self.mid = (np.where(bounded, lo, 0.0) + np.where(bounded, hi, 0.0)) / 2
        self.amplitude = np.where(bounded, np.minimum(amplitude, 0.35 * (hi - lo)), amplitude)
        self.B_pinv = np.linalg.pinv(model.B)
        gain = np.abs(model.B).sum(axis=0)                     # joint force per unit action [N·m or N]
        self.lo, self.hi = model.torque_range[:, 0] / gain, model.torque_range[:, 1] / gain

    def __call__(self, t: float, observation) -> np.ndarray:
        y = self.readout(observation)
        n = self.model.n
        q, v = y[:n], y[n:]
        ref = self.mid + self.amplitude * np.mean(np.sin(2 * np.pi * self.freq * t + self.phase), axis=1)
        e = np.arctan2(np.sin(ref - q), np.cos(ref - q))
        acc = self.omega ** 2 * e - 2 * 0.7 * self.omega * v
        tau = self.model.mass_matrix(q) @ acc + self.model.damping * v + self.model.gravity(q)
        return np.clip(self.B_pinv @ tau, self.lo, self.hi)


def _rates(diagnoser: JointMomentumDiagnoser) -> Rates:
    """One diagnosis sample per environment step."""
    return Rates(1.0 / diagnoser.observer.T, 1.0 / diagnoser.observer.T, "first")


def _episode(env: FaultyEnv, policy, seed: int) -> None:
    obs, _ = env.reset(seed=seed)
    done, k = False, 0
    while not done:
        obs, _, terminated, truncated, _ = env.step(policy(k * env.dt, obs).astype(env.action_space.dtype))
        k += 1
        done = terminated or truncated


def calibrate(env_id: str, diagnoser: JointMomentumDiagnoser, seeds: Sequence[int], steps: int, margin: float = 1.5,
              skip: int = 5, readout: JointReadout | None = None, **kwargs) -> ThresholdDecision:
    """Thresholds ``margin`` × max |r| over fault-free episodes of ``steps`` steps (one per seed, each its own
    :class:`ExcitationPolicy`), ignoring the first ``skip`` samples; a :class:`ThresholdDecision` with the
    diagnoser's signatures, confirmed over 3 samples."""
    runs = []
    for s in seeds:
        bank = DiagnosisBank({"momentum": Diagnosis(diagnoser)}, _rates(diagnoser))
        env = make_env(env_id, steps, (), int(s), bank, readout, **kwargs)
        _episode(env, ExcitationPolicy(diagnoser.model, env.measure, int(s)), int(s))
        runs.append(bank.traces()["momentum"].residual)
        env.close()
    if not runs:
        raise RobofdiError("calibrate: field 'seeds' must name at least one fault-free episode")
    return ThresholdDecision(diagnoser.components, calibrate_thresholds(runs, margin, skip), diagnoser.signatures(),
                             blanking=skip, confirm=3)


def diagnose_episode(env_id: str, faults, seed: int, diagnoser: JointMomentumDiagnoser, decision: ThresholdDecision,
                     steps: int, name: str = "momentum", readout: JointReadout | None = None, **kwargs) -> Record:
    """One episode of ``env_id`` (``steps`` steps, reset with ``seed``, :class:`ExcitationPolicy` of ``seed``) with
    ``faults`` injected and ``diagnoser`` + ``decision`` online, as a robofdi :class:`~robofdi.record.Record`."""
    bank = DiagnosisBank({name: Diagnosis(diagnoser, decision)}, _rates(diagnoser))
    env = make_env(env_id, steps, faults, int(seed), bank, readout, **kwargs)
    try:
        _episode(env, ExcitationPolicy(diagnoser.model, env.measure, int(seed)), int(seed))
        return env.record(scenario=f"gymnasium-{env_id}", meta={"env_id": env_id, "mjcf": env.unwrapped.fullpath})
    finally:
        env.close()
