"""robosuite's Panda diagnosed online: generalised-momentum residuals on the seven arm joints, from a nominal model
built from the environment's own MJCF, with thresholds calibrated on fault-free scripted Lift episodes that include
grasps and contacts; identification of a loss of effectiveness for the accommodation.

Belief. :func:`arm_model` compiles the MJCF robosuite built for the environment (``env.model.get_xml()``, afresh:
nothing the running simulator changes leaks in) and keeps the arm joints only
(:class:`~robofdi.models.multibody.MultibodyModel` with ``joints``): the gripper's finger joints are locked at their
reference (closed) and the hand, fingers and camera mounts are lumped into link 7 (the gripper mass is *lumped*, its
finger motion ignored); the cube is a free object on the world and is not in the model; the table is not a body of
the arm. Masses and inertias, damping and armature are perturbed (:class:`ModelMismatch`). Outside the belief: the
joints' Coulomb friction (robosuite sets ``frictionloss`` 0.1 N·m on every Panda joint), the finger motion, every
contact (cube, table), the grasped cube's mass, encoder quantisation and velocity noise.

Diagnosers (each a :class:`RobotDiagnoser`, stepped at every 2 ms physics substep by the wrapper through a
:class:`~robofdi.loop.DiagnosisBank`):

* ``momentum``: the discrete generalised-momentum residual (De Luca & Mattone 2003, eq. (10);
  :class:`~robofdi.observers.momentum.MomentumObserver`) fed with the commanded (pre-fault) torques and the
  measured joint state;
* ``momentum_friction``: the same with joint friction (Coulomb + viscous + Stribeck) identified by least squares
  from the calibration residuals (:func:`~robofdi.observers.momentum.identify_friction`).

Both decide with :class:`~robofdi.decision.ThresholdDecision` (thresholds 1.2 × max |r| over the fault-free
calibration episodes, 3-sample confirmation, one signature per joint). After isolation of joint i the loss of
effectiveness is identified as k̂ = −Σ r_i ū_i / Σ ū_i² over the samples since isolation (exponential forgetting,
0.5 s), with ū the command passed through the residual's own first-order dynamics (an actuator gain 1 − k makes
the unmodelled torque −k u); ``Health.estimate`` carries k̂ for :class:`~robofdi.ftc.EffectivenessCompensation`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import mujoco
import numpy as np

from robofdi.adapters.robosuite import FaultyRobosuiteEnv, RobotArm
from robofdi.decision import Signature, ThresholdDecision, calibrate_thresholds
from robofdi.errors import RobofdiError
from robofdi.models.manipulator import ModelMismatch
from robofdi.models.multibody import MultibodyModel
from robofdi.observers.momentum import MomentumObserver, identify_friction
from robofdi.loop import Diagnosis, DiagnosisBank, Rates
from robofdi.observers.residual import Residual
from robofdi.seeding import rng

__all__ = ["LiftLoop", "arm_model", "RobotDiagnoser", "LossIdentification", "substep_rates", "LiftScript", "make_lift",
           "run_lift_episode", "Episode",
           "LiftCalibration", "calibrate_lift", "lift_calibration", "run_lift", "DIAGNOSERS", "BELIEF", "EPISODE_STEPS",
           "PHASES", "CALIBRATION_SEEDS"]

os.environ.setdefault("MUJOCO_GL", "egl")

#: The diagnosers this module builds.
DIAGNOSERS = ("momentum", "momentum_friction")
#: The belief's deliberate errors (1-sigma relative): masses/inertias 5 %, damping 20 %, armature 10 %.
BELIEF = ModelMismatch(mass=0.05, inertia=0.05, damping=0.2, armature=0.1, seed=1)
#: Length of a scripted Lift episode in policy steps (20 Hz): 7 s.
EPISODE_STEPS = 140
#: Seeds of the fault-free calibration episodes (held-out evaluation uses other seeds).
CALIBRATION_SEEDS = tuple(range(1000, 1030))
#: The scripted phases, in order.
PHASES = ("approach", "descend", "grasp", "lift", "hold")
OBSERVER_GAIN = 50.0          # K_O [1/s]
MARGIN, CONFIRM = 1.2, 3
BLANKING = 0.05               # [s] start-up blanking of the residuals (and of the calibration samples)


def arm_model(env, mismatch: ModelMismatch | None = None, robot: int = 0) -> MultibodyModel:
    """The nominal arm model of robot ``robot`` compiled from the environment's own MJCF (module docstring);
    joint names without robosuite's prefix (``joint1`` …)."""
    arm = RobotArm(env, robot)
    try:
        m = mujoco.MjModel.from_xml_string(env.model.get_xml())
    except Exception as exc:
        raise RobofdiError(f"env: MuJoCo cannot compile the environment's MJCF: {' '.join(str(exc).split())}") from None
    model = MultibodyModel(m, f"robosuite-{arm.name}", mismatch, joints=arm.full_joints)
    model.joint_names = list(arm.joints)
    return model


class RobotDiagnoser:
    """One momentum residual (a :class:`~robofdi.protocols.Diagnoser`): ``update(y, u)`` with y = [q; q̇] measured
    at a substep and u = the commanded torque held over the previous substep [N·m] → the residual r, also the
    identification candidates (the unmodelled torque per joint). Keeps ū, the command through the residual's
    own first-order dynamics (:attr:`filtered_input`), for :class:`LossIdentification`."""

    def __init__(self, name: str, model: MultibodyModel, T: float, friction=None, gain: float = OBSERVER_GAIN):
        self.name, self.model, self.T = name, model, float(T)
        self.observer = MomentumObserver(model, T, gain, friction)
        self.inputs, self.measurements = list(self.observer.inputs), list(self.observer.measurements)
        self.components = list(model.joint_names)
        self.estimate_components, self.estimate_modes = list(self.components), ["level"] * model.n
        self.units = {"residual": ["N·m"] * model.n, "estimate": ["N·m"] * model.n}
        self._a = gain * T
        self.reset()

    def signatures(self) -> list[Signature]:
        return [Signature(j, frozenset([j])) for j in self.components]

    def reset(self) -> None:
        self.observer.reset()
        self._ubar = np.zeros(self.model.n)

    @property
    def filtered_input(self) -> np.ndarray:
        """ū after the last sample: u low-passed by the residual's own dynamics (gain K_O, sample time T)."""
        return self._ubar

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        res = self.observer.update(y, u)
        self._ubar = self._ubar + self._a * (np.asarray(u, dtype=float) - self._ubar)   # ū: the residual's LP of u
        return Residual(res.r, res.r)


class LossIdentification:
    """Loss of effectiveness of the isolated joints (an :class:`~robofdi.protocols.Identifier`): after isolation
    of joint i, k̂ = −Σ r_i ū_i / Σ ū_i² over the samples at which i is isolated (exponential forgetting,
    ``forgetting`` [s]; an actuator gain 1 − k makes the unmodelled torque −k u), clipped to [0, 0.95]. The
    recorded estimate is the residual of the isolated joints [N·m]; :meth:`magnitudes` (the health) is k̂."""

    def __init__(self, diagnoser: RobotDiagnoser, forgetting: float = 0.5):
        if not (np.isfinite(forgetting) and forgetting > 0):
            raise RobofdiError(f"LossIdentification: field 'forgetting' must be > 0 s, got {forgetting!r}")
        self.diagnoser, self.components = diagnoser, list(diagnoser.components)
        self._lam = float(np.exp(-diagnoser.T / forgetting))
        self.reset()

    def reset(self) -> None:
        n = len(self.components)
        self._s_ru, self._s_uu, self._loss = np.zeros(n), np.zeros(n), np.zeros(n)

    def update(self, candidates: np.ndarray, isolated) -> np.ndarray:
        n = len(self.components)
        estimate, loss = np.zeros(n), np.zeros(n)
        if isolated:
            r, ubar = candidates, self.diagnoser.filtered_input
            idx = [self.components.index(c) for c in isolated if c in self.components]
            lam = self._lam
            self._s_ru[idx] = lam * self._s_ru[idx] + r[idx] * ubar[idx]
            self._s_uu[idx] = lam * self._s_uu[idx] + ubar[idx] ** 2
            for i in idx:
                estimate[i] = r[i]
                loss[i] = float(np.clip(-self._s_ru[i] / self._s_uu[i], 0.0, 0.95)) if self._s_uu[i] > 1e-9 else 0.0
        self._loss = loss
        return estimate

    def magnitudes(self, estimate: np.ndarray, isolated) -> dict[str, float]:
        return {c: self._loss[i] for i, c in enumerate(self.components) if c in isolated}


# ------------------------------------------------------------------------------------------------ the task
class LiftScript:
    """A scripted grasp for robosuite's Lift with the OSC_POSE controller: over the cube, down, close, lift, hold.
    Seeded variations (approach height, speed, grasp depth and wait, lift height) so that episodes differ.
    Reads robosuite's observation only (end-effector and cube positions). :attr:`phase` is the current phase."""

    def __init__(self, seed: int):
        g = rng(seed, "policy", "lift")
        self.above = g.uniform(0.06, 0.12)          # approach height over the cube [m]
        self.gain = g.uniform(0.6, 1.0)             # P gain on the position error, in units of 5 cm
        self.depth = g.uniform(-0.005, 0.01)        # grasp point below (−) / above the cube centre [m]
        self.wait = g.uniform(0.4, 0.7)             # closing time [s]
        self.height = g.uniform(0.15, 0.25)         # lift height [m]
        self.phase, self._t_phase, self._t = PHASES[0], 0.0, 0.0

    def _next(self, phase: str) -> None:
        self.phase, self._t_phase = phase, self._t

    def __call__(self, obs, dt: float = 0.05) -> np.ndarray:
        eef, cube = np.asarray(obs["robot0_eef_pos"]), np.asarray(obs["cube_pos"])
        self._t += dt
        grip = -1.0
        if self.phase == "approach":
            target = cube + [0, 0, self.above]
            if np.linalg.norm(target - eef) < 0.01 or self._t - self._t_phase > 3.0:
                self._next("descend")
        elif self.phase == "descend":
            target = cube + [0, 0, self.depth]
            if np.linalg.norm(target - eef) < 0.008 or self._t - self._t_phase > 2.5:
                self._next("grasp")
        if self.phase == "grasp":
            target, grip = eef.copy(), 1.0
            if self._t - self._t_phase > self.wait:
                self._next("lift")
                self._lift_from = eef.copy()
        if self.phase in ("lift", "hold"):
            target, grip = self._lift_from + [0, 0, self.height], 1.0
            if self.phase == "lift" and np.linalg.norm(target - eef) < 0.01:
                self._next("hold")
        action = np.zeros(7)
        action[:3] = np.clip(self.gain * (target - eef) / 0.05, -1.0, 1.0)
        action[6] = grip
        return action


def make_lift(seed: int = 0, **kwargs):
    """robosuite's Lift with the Panda, headless and light (no renderer, no cameras, no hard reset).

    robosuite draws part of the task at construction from the global ``np.random`` (Lift: the cube's size); without a
    hard reset that draw stays for every episode, so it is seeded here (``rng(seed, "task", "construction")``, the
    global state restored afterwards): two environments made with the same seed are the same."""
    import robosuite

    opts = dict(robots="Panda", has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False, hard_reset=False,
                horizon=10_000, ignore_done=True)
    opts.update(kwargs)
    state = np.random.get_state()
    np.random.seed(int(rng(seed, "task", "construction").integers(2**31)))
    try:
        return robosuite.make("Lift", **opts)
    finally:
        np.random.set_state(state)


@dataclass
class Episode:
    """One scripted episode: success, the first time the cube was lifted [s], the policy-step times [s], phases and
    cube heights above the table [m], the wrapper (history and diagnosers)."""

    success: bool
    lifted_at: float | None
    step_times: np.ndarray
    phases: list[str]
    cube_height: np.ndarray
    env: FaultyRobosuiteEnv


def run_lift_episode(env: FaultyRobosuiteEnv, policy_seed: int, steps: int = EPISODE_STEPS) -> Episode:
    """Reset ``env`` and run the scripted grasp for ``steps`` policy steps; success is robosuite's
    ``_check_success()`` (cube more than 4 cm above the table) at the end."""
    obs = env.reset()
    script = LiftScript(policy_seed)
    dt = 1.0 / float(env.env.control_freq)
    table = float(env.env.table_offset[2])
    times, phases, heights, lifted_at = [], [], [], None
    for _ in range(steps):
        times.append(env.time)
        phases.append(script.phase)
        heights.append(float(obs["cube_pos"][2]) - table)
        obs, _, _, _ = env.step(script(obs, dt))
        if lifted_at is None and env.env._check_success():
            lifted_at = env.time
    return Episode(bool(env.env._check_success()), lifted_at, np.array(times), phases, np.array(heights), env)


# ------------------------------------------------------------------------------------------------ calibration
@dataclass
class LiftCalibration:
    """Thresholds per diagnoser (N·m per joint), the identified friction, the calibration episodes' seeds."""

    thresholds: dict
    friction: object
    seeds: tuple
    belief: ModelMismatch
    success: int

    def diagnosis(self, model: MultibodyModel, T: float, health_source: str | None = None,
                  diagnosers=None) -> DiagnosisBank:
        """Calibrated diagnoses on ``model`` (built by :func:`arm_model` with :attr:`belief`) stepped at every
        substep of period ``T``; default: every diagnoser this calibration has thresholds for."""
        blank = int(round(BLANKING / T))
        out = {}
        for name in (tuple(self.thresholds) if diagnosers is None else diagnosers):
            if name not in self.thresholds:
                raise RobofdiError(f"diagnosers: {name!r} has no calibrated thresholds; expected some of {list(self.thresholds)}")
            d = RobotDiagnoser(name, model, T, self.friction if name == "momentum_friction" else None)
            decision = ThresholdDecision(d.components, np.asarray(self.thresholds[name]), d.signatures(),
                                         blanking=blank, confirm=CONFIRM)
            out[name] = Diagnosis(d, decision, LossIdentification(d))
        return DiagnosisBank(out, substep_rates(T), health_source)


def substep_rates(T: float) -> Rates:
    """The wrapper's rates: control and diagnosis at every physics substep of period ``T`` [s]."""
    return Rates(1.0 / T, 1.0 / T, "first")


def calibrate_lift(env_factory=make_lift, seeds=CALIBRATION_SEEDS, belief: ModelMismatch = BELIEF,
                   steps: int = EPISODE_STEPS, progress=None, diagnosers=DIAGNOSERS) -> LiftCalibration:
    """Fault-free scripted Lift episodes (one per seed: its own cube pose, initial joint noise, script variation
    and sensor noise): friction identified on the plain residuals, then thresholds = 1.2 × max |r| for each of
    ``diagnosers`` (after the start-up blanking). Without ``momentum_friction`` the second pass is skipped."""
    seeds = tuple(int(s) for s in seeds)
    if len(seeds) < 2:
        raise RobofdiError(f"seeds: expected at least 2 calibration episodes, got {len(seeds)}")
    unknown = [d for d in diagnosers if d not in DIAGNOSERS]
    if unknown or not diagnosers:
        raise RobofdiError(f"diagnosers: expected some of {list(DIAGNOSERS)}, got {list(diagnosers)}")
    raw = env_factory()
    model = arm_model(raw, belief)
    T = float(raw.sim.model.opt.timestep)
    blank = int(round(BLANKING / T))

    def residuals(name, friction=None):
        out, vels, success = [], [], 0
        bank = DiagnosisBank({name: Diagnosis(RobotDiagnoser(name, model, T, friction))}, substep_rates(T))
        for s in seeds:
            env = FaultyRobosuiteEnv(raw, (), seed=s, diagnosis=bank)
            try:
                success += run_lift_episode(env, s, steps).success
            finally:
                env.detach()
            out.append(bank.traces()[name].residual)
            vels.append(np.array(env.history["y_meas"])[:, model.n:])
            if progress is not None:
                progress(1)
        return out, vels, success

    try:
        plain, vels, success = residuals("momentum")
        friction = identify_friction(plain, vels, OBSERVER_GAIN, T, skip=blank)
        runs = {"momentum": plain}
        if "momentum_friction" in diagnosers:
            runs["momentum_friction"] = residuals("momentum_friction", friction)[0]
    finally:
        raw.close()
    thresholds = {name: calibrate_thresholds(runs[name], MARGIN, blank).tolist() for name in diagnosers}
    return LiftCalibration(thresholds, friction, seeds, belief, success)


def lift_calibration(seeds=CALIBRATION_SEEDS, belief: ModelMismatch = BELIEF, steps: int = EPISODE_STEPS,
                     progress=None, cache: bool = True) -> tuple[LiftCalibration, bool]:
    """:func:`calibrate_lift`, computed once per (seeds, belief, steps, robofdi's code and robosuite's version) through
    :mod:`robofdi.calibration`, the one calibration cache; returns (calibration, True if it came from the cache)."""
    import robosuite

    from robofdi.calibration import cached

    seeds = tuple(int(s) for s in seeds)

    def compute():
        return calibrate_lift(seeds=seeds, belief=belief, steps=steps, progress=progress)

    description = {"seeds": seeds, "belief": repr(belief), "steps": steps, "robosuite": robosuite.__version__,
                   "env": "make_lift(0)", "observer_gain": OBSERVER_GAIN, "margin": MARGIN, "blanking": BLANKING,
                   "confirm": CONFIRM}
    return cached("robosuite-lift", description, compute, cache=cache)


def run_lift(calibration: LiftCalibration, faults=(), seed: int = 0, accommodation: bool = False,
             health_source: str = "momentum", diagnosers=None, env=None, steps: int = EPISODE_STEPS,
             scenario: str = "robosuite-lift", meta: dict | None = None, policy_seed: int | None = None):
    """One scripted Lift episode (cube pose, script and noise from ``seed``) with ``faults`` and the calibrated
    diagnosers online; ``accommodation``: :class:`~robofdi.ftc.EffectivenessCompensation` fed by the health of
    ``health_source`` (one substep late). ``env``: a robosuite Lift to reuse (default a new one). Returns
    (:class:`Episode`, :class:`~robofdi.record.Record`). ``policy_seed``: the script's variations (default ``seed``)."""
    from robofdi.ftc import EffectivenessCompensation

    raw = make_lift() if env is None else env
    model = arm_model(raw, calibration.belief)
    T = float(raw.sim.model.opt.timestep)
    diagnosis = calibration.diagnosis(model, T, health_source if accommodation else None, diagnosers)
    acc = EffectivenessCompensation(model.joint_names) if accommodation else None
    wrapped = FaultyRobosuiteEnv(raw, list(faults), seed=seed, diagnosis=diagnosis, accommodation=acc)
    try:
        ep = run_lift_episode(wrapped, seed if policy_seed is None else int(policy_seed), steps)
        record = wrapped.record(scenario, diagnosis.traces(), {
            "success": ep.success, "lifted_at": ep.lifted_at, "primary_diagnoser": health_source,
            "health_source": health_source if accommodation else None,
            "identified_loss": {name: {j: float(v) for j, v in r.health.estimate.items()}
                                for name, r in diagnosis.runners.items()}, **(meta or {})})
    finally:
        wrapped.detach()
        if env is None:
            raw.close()
    return ep, record


@dataclass
class LiftLoop:
    """One scripted Lift episode, built (the loop of :meth:`robofdi.protocols.System.build`): the calibrated
    diagnosers, ``faults``, the accommodation switch and its health source, the robosuite ``env`` (the simulator) to
    reuse, ``steps`` and the script's seed. ``run`` has :meth:`robofdi.loop.ClosedLoop.run`'s signature and
    returns :func:`run_lift`'s record (the episode's length is ``steps``; ``duration`` is not used)."""

    calibration: LiftCalibration
    faults: tuple = ()
    accommodation: bool = False
    health_source: str = "momentum"
    diagnosers: tuple | None = None
    env: object = None
    steps: int = EPISODE_STEPS
    policy_seed: int | None = None

    @property
    def simulator(self):
        return self.env

    def run(self, duration=None, initial_state=None, *, seed: int = 0, run_key: str = "campaign",
            scenario: str = "robosuite-lift", meta: dict | None = None, progress=None):
        return run_lift(self.calibration, self.faults, seed, accommodation=self.accommodation,
                        health_source=self.health_source, diagnosers=self.diagnosers, env=self.env, steps=self.steps,
                        scenario=scenario, meta=meta, policy_seed=self.policy_seed)[1]
