"""A wrapper that injects robofdi faults into any robosuite environment, where a real robot fails.

::

    import robosuite
    from robofdi.adapters.robosuite import FaultyRobosuiteEnv

    env = FaultyRobosuiteEnv(robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                                            use_camera_obs=False, hard_reset=False),
                             ["actuator_loss_of_effectiveness:joint2:0.7@2.0", "sensor_bias:joint4_pos:0.01@3.0"], seed=0)
    obs = env.reset()
    obs, reward, done, info = env.step(action)
    info["robofdi_faults"]        # (n_faults, 2): [active (0/1), value] per fault, order = env.fault_names

Where each family acts (robosuite runs its controller at every physics substep; the wrapper hooks that substep):

* **actuator** faults (targets: the arm joints ``joint1`` … ``joint7``): on the joint torques the robot's controller
  wrote to ``data.ctrl`` — after the controller (and after the optional accommodation stage), before MuJoCo steps —
  clipped to the motors' ctrlrange (the label is what the plant really received).
* **sensor** faults (targets: ``joint<i>_pos`` [rad], ``joint<i>_vel`` [rad/s]): on the joint sensors. Every
  substep the joint state is measured (:class:`~robofdi.sims.arm.SensorModel`: 20-bit encoder, drive velocity
  noise, each channel its own seeded stream) and faulted; the controller computes its kinematics, Jacobians, mass
  matrix and gravity compensation at that measured state (the arm's qpos/qvel are swapped in for the controller's
  call and restored before the physics step), and the observations ``robot0_joint_pos``, ``_pos_cos``, ``_pos_sin``,
  ``_joint_vel`` and ``robot0_proprio-state`` carry it. The end-effector and object observables stay robosuite's own
  (computed from the simulator, as by an external tracker).
* **component** faults: ``component_friction`` on an arm joint (its Coulomb ``frictionloss`` and viscous damping ×
  (1 + value)); ``component_mass`` on ``payload`` (kg added at the end-effector body's centre of mass).

The gripper is not a fault target (a fault named after it is refused), and the wrapper refuses an environment whose
arm controller does not output joint torques or whose arm actuators are not torque motors.

Labels: ``info["robofdi_faults"]`` after every step, the same layout as the dm_control adapter (column 0: active,
column 1: the change the fault made to its target). The per-substep history (truth, commands, measurements, labels,
and the whole MuJoCo ``qpos``: arm, gripper fingers, objects) is kept for :meth:`FaultyRobosuiteEnv.record`.

Replay: the record names the environment's MJCF ``model.xml`` (``meta["mjcf"]``, with robosuite's joint-name prefix
in ``meta["mjcf_joint_prefix"]``); :meth:`FaultyRobosuiteEnv.write_mjcf` writes that file into the record's folder,
and :func:`robofdi.viz.write_replay_html` / ``robofdi view`` draw the run from it (its mesh files are robosuite's
installed assets, read when the model is loaded; nothing downloads).

Seeds: episode k draws its sensor noise and fault randomness from ``robofdi.seeding.stream(seed, "episode", str(k))``
and seeds robosuite's own task randomness (cube placement, initial joint noise, which robosuite draws from the
global ``np.random``) from the same stream, restoring the global state afterwards: the same seed replays the
same episodes. What robosuite draws once at construction (Lift's cube size, with ``hard_reset=False``) is not the
wrapper's: seed it around ``robosuite.make`` (as :func:`robofdi.adapters.robosuite_diagnosis.make_lift` does).

Diagnosis and accommodation (optional): ``diagnosis``, a :class:`~robofdi.loop.DiagnosisBank` at the substep rate,
is pushed at every substep with the measurement y and the command u held over the previous substep
(:mod:`robofdi.adapters.robosuite_diagnosis`); ``accommodation.update(u_cmd, health)`` (e.g.
:class:`~robofdi.ftc.EffectivenessCompensation`) sits between the controller and the actuator faults and gets the
bank's health one substep late. The history is a :class:`~robofdi.loop.Recorder`.
"""
from __future__ import annotations

import logging
from pathlib import Path
from collections.abc import Sequence

import numpy as np

import mujoco

from robofdi.errors import RobofdiError, all_finite
from robofdi.faults import Fault, FaultInjector, parse_fault_spec
from robofdi.loop import DiagnosisBank, Recorder
from robofdi.mjcf import actuator_kind, is_torque_motor
from robofdi.protocols import HEALTHY
from robofdi.record import FaultLabels, Record
from robofdi.seeding import stream
from robofdi.sims.arm import SensorModel
from robofdi.sims.noise import ChannelNoise

# robosuite's import-time advice (a private macro file, optional robot packages, a GR1 IK) and its per-environment
# INFO lines are not for robofdi's users: its logger is muted while importing, then keeps warnings and errors.
_ROBOSUITE_LOG = logging.getLogger("robosuite_logs")
_ROBOSUITE_LOG.disabled = True
try:
    import robosuite  # noqa: F401
    from robosuite.controllers.parts.arm.osc import OperationalSpaceController
    from robosuite.controllers.parts.generic.joint_pos import JointPositionController
    from robosuite.controllers.parts.generic.joint_tor import JointTorqueController
    from robosuite.controllers.parts.generic.joint_vel import JointVelocityController
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.robosuite needs robosuite: pip install 'robofdi[robosuite]'") from None
finally:
    _ROBOSUITE_LOG.disabled = False
    _ROBOSUITE_LOG.setLevel(logging.WARNING)

__all__ = ["FaultyRobosuiteEnv", "LABELS_KEY", "TORQUE_CONTROLLERS", "RobotArm", "MJCF_FILE", "qpos_columns", "write_mjcf"]

#: The ``info`` entry that carries the ground-truth labels (as in the dm_control adapter).
LABELS_KEY = "robofdi_faults"
#: The file name of the environment's MJCF in a run folder (``record.meta["mjcf"]``, see ``write_mjcf``).
MJCF_FILE = "model.xml"
#: robosuite's arm controllers whose output robosuite writes to the arm actuators as joint torques.
TORQUE_CONTROLLERS = (OperationalSpaceController, JointPositionController, JointVelocityController, JointTorqueController)


def qpos_columns(m) -> tuple[list[str], list[str]]:
    """Names and units of the MuJoCo model ``m``'s qpos entries: a hinge or slide joint's name; a free joint's
    ``<name>_x``, ``_y``, ``_z`` [m] and ``_qw`` … ``_qz`` [1]; a ball joint's ``<name>_qw`` … ``_qz``."""
    names, units = [], []
    for j in range(m.njnt):
        name, kind = m.joint(j).name or f"joint{j}", int(m.jnt_type[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            names += [f"{name}_{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
            units += ["m"] * 3 + ["1"] * 4
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            names += [f"{name}_{c}" for c in ("qw", "qx", "qy", "qz")]
            units += ["1"] * 4
        else:
            names.append(name)
            units.append("rad" if kind == mujoco.mjtJoint.mjJNT_HINGE else "m")
    return names, units


def write_mjcf(env, folder) -> Path:
    """Write robosuite environment ``env``'s MJCF (its simulator's ``get_xml()``) as ``folder/model.xml``, the model
    that a record's ``meta["mjcf"]`` names for the replay; returns its path."""
    path = Path(folder) / MJCF_FILE
    path.write_text(env.sim.model.get_xml(), encoding="utf-8")
    return path


def _controller_name(controller) -> str:
    """robosuite's name of an arm controller (OSC_POSE, …); the class name for others (a gripper's reuses names)."""
    name = getattr(controller, "name", None) if isinstance(controller, TORQUE_CONTROLLERS) else None
    return str(name or type(controller).__name__)


class RobotArm:
    """The arm of robot ``robot`` of a robosuite environment: joint names (without robosuite's naming prefix),
    MuJoCo addresses, motor limits, the gripper's names (excluded), the end-effector body. Checks that the arm's
    controller outputs joint torques and that the arm actuators are torque motors."""

    def __init__(self, env, robot: int = 0, part: str = "right"):
        robots = getattr(env, "robots", None)
        if not robots or not hasattr(env, "sim"):
            raise RobofdiError(f"env: expected a robosuite robot environment (robosuite.make(...)), got {type(env).__name__}")
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < len(robots):
            raise RobofdiError(f"robot: expected an index in 0..{len(robots) - 1}, got {robot!r}")
        r = robots[robot]
        controllers = getattr(r, "part_controllers", {})
        if part not in controllers:
            raise RobofdiError(f"part: robot {r.name} has no arm {part!r}; expected one of {list(controllers)}")
        self.robot, self.part, self.name = r, part, str(r.name)
        controller = controllers[part]
        if not isinstance(controller, TORQUE_CONTROLLERS):
            raise RobofdiError(f"part {part!r}: controller {_controller_name(controller)} of {r.name} does not output "
                               f"joint torques; expected one of {', '.join(c.__name__ for c in TORQUE_CONTROLLERS)} "
                               "(OSC_POSE, OSC_POSITION, JOINT_POSITION, IK_POSE, JOINT_VELOCITY, JOINT_TORQUE)")
        self.controller = _controller_name(controller)
        prefix = r.robot_model.naming_prefix
        self.prefix = prefix
        self.full_joints = list(r.robot_joints)
        self.joints = [j[len(prefix):] if j.startswith(prefix) else j for j in self.full_joints]
        self.n = len(self.joints)
        grippers = getattr(r, "gripper_joints", {}) or {}
        gripper_names = set()
        for arm, names in grippers.items():
            g = r.gripper[arm]
            for name in list(names) + list(getattr(g, "actuators", [])):
                gripper_names |= {name, name[len(g.naming_prefix):] if name.startswith(g.naming_prefix) else name}
        self.gripper_names = gripper_names
        self.eef_body = r.robot_model.eef_name[part] if isinstance(r.robot_model.eef_name, dict) else r.robot_model.eef_name
        self.bind(env.sim)

    def bind(self, sim) -> None:
        """(Re)read MuJoCo addresses from ``sim`` (robosuite's hard reset builds a new one)."""
        m = sim.model._model
        r = self.robot
        self.qpos = np.array([sim.model.get_joint_qpos_addr(j) for j in self.full_joints], dtype=int)
        self.dofs = np.array([sim.model.get_joint_qvel_addr(j) for j in self.full_joints], dtype=int)
        self.actuators = np.array(r._ref_actuators_indexes_dict[self.part], dtype=int)
        for k, a in enumerate(self.actuators):
            joint = int(m.actuator_trnid[a, 0])
            label = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, int(a)) or f"#{a}"
            if int(m.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT) or m.jnt_dofadr[joint] != self.dofs[k]:
                raise RobofdiError(f"actuator {label!r} does not drive arm joint {self.joints[k]!r} through a joint "
                                   "transmission; expected one torque motor per arm joint")
            if not is_torque_motor(m, int(a)):
                raise RobofdiError(f"controller {self.controller!r} does not output joint torques to {self.joints[k]!r}: "
                                   f"its actuator {label!r} is {actuator_kind(m, int(a))}; expected a torque motor")
        gear = m.actuator_gear[self.actuators, 0] * m.actuator_gainprm[self.actuators, 0]
        self.gain = gear.copy()
        self.ctrl_range = m.actuator_ctrlrange[self.actuators].copy()
        self.torque_range = np.sort(self.ctrl_range * gear[:, None], axis=1)
        self.joint_range = m.jnt_range[[sim.model.joint_name2id(j) for j in self.full_joints]].copy()
        body = sim.model.body_name2id(self.eef_body)
        while m.body_mass[body] <= 0 and m.body_parentid[body] > 0:     # a massless frame: its parent link carries it
            body = int(m.body_parentid[body])
        self.payload_body = int(body)

    @property
    def sensor_channels(self) -> list[str]:
        return [f"{j}_pos" for j in self.joints] + [f"{j}_vel" for j in self.joints]

    def check_target(self, f: Fault) -> None:
        """A one-line error for a fault on a joint the robot does not have or on the gripper."""
        if f.family == "actuator":
            ok, what = f.target in self.joints, f"{self.name} has joints {self.joints[0]}..{self.joints[-1]}"
        elif f.family == "sensor":
            first, last = self.joints[0], self.joints[-1]
            ok, what = f.target in self.sensor_channels, (f"{self.name}'s joint sensors are {first}_pos..{last}_pos "
                                                          f"and {first}_vel..{last}_vel")
        elif f.kind == "component_friction":
            ok, what = f.target in self.joints, f"{self.name} has joints {self.joints[0]}..{self.joints[-1]}"
        elif f.kind == "component_mass":
            ok, what = f.target == "payload", "the robosuite adapter takes component_mass on 'payload' (at the end effector)"
        else:
            raise RobofdiError(f"fault {f.name!r}: kind {f.kind!r} is not supported by the robosuite adapter; expected "
                               "actuator and sensor kinds, component_friction or component_mass")
        if ok:
            return
        stem = f.target.rsplit("_", 1)[0] if f.family == "sensor" else f.target
        if f.target in self.gripper_names or stem in self.gripper_names or "gripper" in f.target or "finger" in f.target:
            raise RobofdiError(f"fault target {f.target!r}: the gripper is excluded from diagnosis (faults on the arm "
                               f"joints {self.joints[0]}..{self.joints[-1]} only)")
        raise RobofdiError(f"fault target {f.target!r}: {what}")


def _faults(faults) -> tuple[Fault, ...]:
    if isinstance(faults, (str, Fault)) or not isinstance(faults, Sequence):
        raise RobofdiError(f"FaultyRobosuiteEnv: field 'faults' must be a list of Fault or fault-spec strings, got {faults!r}")
    out = []
    for f in faults:
        f = parse_fault_spec(f) if isinstance(f, str) else f
        if not isinstance(f, Fault):
            raise RobofdiError(f"FaultyRobosuiteEnv: field 'faults' must hold Fault objects or spec strings, got {f!r}")
        out.append(f)
    return tuple(out)


class FaultyRobosuiteEnv:
    """``env`` with ``faults`` on its arm's torques, joint sensors and components, and labels in every step's
    ``info["robofdi_faults"]`` (module docstring). ``sensors``: the joint sensor model (default: 20-bit encoders,
    1e-3 rad/s velocity noise; ``SensorModel.ideal()`` for exact readings). ``diagnosis`` / ``accommodation``:
    optional (a :class:`~robofdi.loop.DiagnosisBank` at the substep rate; an accommodation), stepped at every
    substep. ``robot`` / ``part``: which robot of the environment and which of its
    controlled parts (robosuite's part names: ``right``, ``left`` for a second arm)."""

    def __init__(self, env, faults: Sequence[Fault | str] = (), seed: int = 0, robot: int = 0,
                 sensors: SensorModel | None = None, diagnosis=None, accommodation=None, part: str = "right"):
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise RobofdiError(f"FaultyRobosuiteEnv: field 'seed' must be an integer >= 0, got {seed!r}")
        sensors = SensorModel() if sensors is None else sensors
        if not isinstance(sensors, SensorModel):
            raise RobofdiError(f"FaultyRobosuiteEnv: field 'sensors' must be a SensorModel, got {type(sensors).__name__}")
        if getattr(env, "_robofdi_wrapped", False):
            raise RobofdiError("FaultyRobosuiteEnv: this environment is already wrapped")
        self.arm = RobotArm(env, robot, part)
        self.env, self.seed, self.faults, self.sensors = env, int(seed), _faults(faults), sensors
        for f in self.faults:
            self.arm.check_target(f)
        if diagnosis is not None and not isinstance(diagnosis, DiagnosisBank):
            raise RobofdiError(f"FaultyRobosuiteEnv: field 'diagnosis' must be a robofdi.loop.DiagnosisBank, got "
                               f"{type(diagnosis).__name__}")
        self.diagnosis, self.accommodation = diagnosis, accommodation
        self.component_kinds = {"component_friction": tuple(self.arm.joints), "component_mass": ("payload",)}
        self._episode = -1
        self.injector = self._injector(0)            # validates names, magnitudes, profiles now
        self._controller_pre_action = env._pre_action
        env._pre_action = self._substep              # robosuite calls it at every physics substep
        env._robofdi_wrapped = True
        self._nominal = None
        self._recorder: Recorder | None = None
        self._reading = (None, None, None)

    # ------------------------------------------------------------------------------------------------ setup
    @property
    def sim(self):
        return self.env.sim

    @property
    def history(self) -> dict[str, list] | None:
        """The rows recorded since the last reset (per-substep lists), None before the first reset."""
        return None if self._recorder is None else self._recorder.rows

    @property
    def fault_names(self) -> list[str]:
        return [f.name for f in self.faults]

    @property
    def time(self) -> float:
        """Simulation time [s], rounded to 1 ns (MuJoCo's time is a running sum of timesteps)."""
        return round(float(self.env.sim.data.time), 9)

    def _injector(self, episode: int) -> FaultInjector:
        lo, hi = self.arm.torque_range[:, 0], self.arm.torque_range[:, 1]
        return FaultInjector(self.faults, self.arm.joints, self.arm.sensor_channels, stream(self.seed, "episode", str(episode)),
                             component_kinds=self.component_kinds, saturate=lambda u: np.minimum(np.maximum(u, lo), hi))

    def _remember_nominal(self) -> None:
        m = self.sim.model._model
        if self._nominal is not None and self._nominal[0] is m:
            (_, fl, dmp, mass) = self._nominal           # same model (no hard reset): undo last episode's components
            m.dof_frictionloss[self.arm.dofs], m.dof_damping[self.arm.dofs] = fl, dmp
            if m.body_mass[self.arm.payload_body] != mass:
                m.body_mass[self.arm.payload_body] = mass
                mujoco.mj_setConst(m, self.sim.data._data)
        else:
            self._nominal = (m, m.dof_frictionloss[self.arm.dofs].copy(), m.dof_damping[self.arm.dofs].copy(),
                             float(m.body_mass[self.arm.payload_body]))
        self._components = {}

    # ------------------------------------------------------------------------------------------------ episode
    def reset(self):
        """Reset robosuite (task randomness from this episode's stream), the injector, the sensors, the diagnosis."""
        self._episode += 1
        run = stream(self.seed, "episode", str(self._episode))
        self.injector = self._injector(self._episode)
        self._noise_q = ChannelNoise(run, self.arm.sensor_channels[:self.arm.n]) if self.sensors.position_noise else None
        self._noise_v = ChannelNoise(run, self.arm.sensor_channels[self.arm.n:]) if self.sensors.velocity_noise else None
        state = np.random.get_state()
        np.random.seed(int(np.random.default_rng(stream(run, "task")).integers(2**31)))
        try:
            obs = self.env.reset()
        finally:
            np.random.set_state(state)
        self.arm.bind(self.sim)
        self._remember_nominal()
        self.health, self._u_prev = HEALTHY, np.zeros(self.arm.n)
        self._reading = (None, None, None)
        if self.diagnosis is not None:
            self.diagnosis.reset()
        if self.accommodation is not None:
            self.accommodation.reset()
        self._recorder = Recorder(("time", "state", "u_cmd", "u", "u_applied", "y_true", "y_meas", "labels", "qpos"))
        return self._observe(obs)

    def step(self, action):
        """One robosuite step (its substeps run through :meth:`_substep`); the labels go in ``info``."""
        if self.history is None:
            raise RobofdiError("FaultyRobosuiteEnv: call reset() before step()")
        obs, reward, done, info = self.env.step(action)
        info = dict(info)
        labels = self.injector.labels
        info[LABELS_KEY] = np.array([[float(labels[n][0]), float(labels[n][1])] for n in self.fault_names],
                                    dtype=np.float64).reshape(len(self.faults), 2)
        return self._observe(obs), reward, done, info

    def close(self):
        self.detach()
        self.env.close()

    def write_mjcf(self, folder) -> Path:
        """:func:`write_mjcf` of the wrapped environment."""
        return write_mjcf(self.env, folder)

    def detach(self):
        """Give the robosuite environment back its own substep (it can then be wrapped again); returns it."""
        self.env.__dict__.pop("_pre_action", None)
        self.env.__dict__.pop("_robofdi_wrapped", None)
        return self.env

    def __getattr__(self, name):               # everything else is robosuite's (action_spec, _check_success, ...)
        if name == "env":
            raise AttributeError(name)
        return getattr(self.env, name)

    # ------------------------------------------------------------------------------------------------ sensors
    def measure(self) -> tuple[np.ndarray, np.ndarray]:
        """(y_true, y_meas) = ([q; q̇] true, measured with noise and sensor faults) now, drawn once per instant."""
        t = self.time
        if self._reading[0] == t:
            return self._reading[1], self._reading[2]
        d, a, s = self.sim.data._data, self.arm, self.sensors
        q, v = d.qpos[a.qpos].copy(), d.qvel[a.dofs].copy()
        y_true = np.concatenate([q, v])
        if s.position_resolution > 0:
            q = np.round(q / s.position_resolution) * s.position_resolution
        if self._noise_q is not None:
            q = q + s.position_noise * self._noise_q.draw()
        if self._noise_v is not None:
            v = v + s.velocity_noise * self._noise_v.draw()
        y = self.injector.sense(t, np.concatenate([q, v]))
        if not all_finite(y):
            raise RobofdiError(f"joint sensors: non-finite reading at t = {t:.4f} s")
        self._reading = (t, y_true, y)
        return y_true, y

    def _observe(self, obs):
        _, y = self.measure()
        n, p, obs = self.arm.n, self.arm.prefix, dict(obs)
        values = {f"{p}joint_pos": y[:n], f"{p}joint_pos_cos": np.cos(y[:n]), f"{p}joint_pos_sin": np.sin(y[:n]),
                  f"{p}joint_vel": y[n:]}
        for key, value in values.items():
            if key in obs:
                obs[key] = value.astype(np.asarray(obs[key]).dtype)
        proprio = f"{p}proprio-state"
        if proprio in obs:
            parts = [np.atleast_1d(obs[k]) for k, o in self.env._observables.items()
                     if o.modality == f"{p}proprio" and k in obs]
            obs[proprio] = np.concatenate(parts)
        return obs

    # ------------------------------------------------------------------------------------------------ substep
    def _substep(self, action, policy_step=False):
        """Replaces robosuite's ``_pre_action``: measure, diagnose, run the controller at the measured state,
        accommodate, inject the actuator faults into data.ctrl, set the components."""
        m, d, a = self.sim.model._model, self.sim.data._data, self.arm
        t = self.time
        qpos = d.qpos.copy()
        y_true, y = self.measure()
        if self.diagnosis is not None:
            self.diagnosis.push(len(self._recorder.rows["time"]), t, y, self._u_prev)
            self.health = self.diagnosis.health             # one substep late
        health = self.health
        swap = not np.array_equal(y, y_true)
        if swap:                                           # the controller sees the measured joint state
            q_true, v_true = d.qpos[a.qpos].copy(), d.qvel[a.dofs].copy()
            d.qpos[a.qpos], d.qvel[a.dofs] = y[:a.n], y[a.n:]
            mujoco.mj_fwdPosition(m, d)
            mujoco.mj_fwdVelocity(m, d)
        self._controller_pre_action(action, policy_step)
        if swap:
            d.qpos[a.qpos], d.qvel[a.dofs] = q_true, v_true
            mujoco.mj_step1(m, d)
        u_cmd = d.ctrl[a.actuators] * a.gain                # the controller's torques [N·m], after robosuite's clip
        u = self.accommodation.update(u_cmd, health) if self.accommodation is not None else u_cmd
        u_plant = self.injector.actuate(t, u)
        ctrl = np.clip(u_plant / a.gain, a.ctrl_range[:, 0], a.ctrl_range[:, 1])
        d.ctrl[a.actuators] = ctrl
        if self.injector.has_component_faults:
            for kind, target, value in self.injector.components(t):
                self._apply_component(kind, target, value)
        self._u_prev = np.array(u, dtype=float)
        self._recorder.append(time=t, state=y_true, u_cmd=u_cmd, u=self._u_prev, u_applied=ctrl * a.gain,
                              y_true=y_true, y_meas=y, labels=[self.injector.labels[n] for n in self.fault_names],
                              qpos=qpos)

    def _apply_component(self, kind: str, target: str, value: float) -> None:
        if self._components.get((kind, target)) == value:
            return
        self._components[(kind, target)] = value
        m, (_, fl, dmp, mass) = self.sim.model._model, self._nominal
        if kind == "component_friction":
            if not value > -1:
                raise RobofdiError(f"component_friction on {target!r}: expected a relative rise > -1, got {value}")
            k = self.arm.joints.index(target)
            m.dof_frictionloss[self.arm.dofs[k]] = fl[k] * (1 + value)
            m.dof_damping[self.arm.dofs[k]] = dmp[k] * (1 + value)
        else:
            if not value >= 0:
                raise RobofdiError(f"component_mass on 'payload': expected an added mass >= 0 kg, got {value}")
            m.body_mass[self.arm.payload_body] = mass + value
            mujoco.mj_setConst(m, self.sim.data._data)

    # ------------------------------------------------------------------------------------------------ record
    def record(self, scenario: str = "robosuite", diagnosers: dict | None = None, meta: dict | None = None) -> Record:
        """The episode so far as a robofdi :class:`Record` at the substep rate (truth, commands, measurements,
        labels; ``diagnosers``: name → :class:`DiagnoserTrace`, default the traces of the wrapper's diagnosis)."""
        h, a, rec = self.history, self.arm, self._recorder
        if not h or not h["time"]:
            raise RobofdiError("FaultyRobosuiteEnv.record: no substep recorded yet (reset() and step() first)")
        n, steps = a.n, len(h["time"])
        joints, channels = list(a.joints), a.sensor_channels
        units_u, units_y = ["N·m"] * n, ["rad"] * n + ["rad/s"] * n
        labels = np.array(h["labels"], dtype=float).reshape(steps, len(self.faults), 2)
        fault_unit = {f.name: {"actuator": "N·m", "sensor": "rad" if f.target.endswith("_pos") else "rad/s"}.get(
            f.family, "1" if f.kind == "component_friction" else "kg") for f in self.faults}
        dt = float(self.sim.model.opt.timestep)
        columns = {"truth/state": channels, "truth/u_applied": joints, "signals/reference": ["action_step"]}
        units = {"truth/state": units_y, "truth/u_applied": units_u, "signals/reference": ["1"]}
        for key in ("u_cmd", "u", "u_diag"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = joints, units_u
        for key in ("y_true", "y_meas"):
            columns[f"signals/{key}"], units[f"signals/{key}"] = channels, units_y
        columns["signals/qpos"], units["signals/qpos"] = qpos_columns(self.sim.model._model)
        u = rec.array("u")
        if diagnosers is None and self.diagnosis is not None:
            diagnosers = self.diagnosis.traces()
        return Record(
            system=f"robosuite-{type(self.env).__name__}-{a.name}", scenario=scenario, seed=self.seed,
            rates={"physics_dt": dt, "control_hz": 1.0 / dt, "diagnosis_hz": 1.0 / dt,
                   "policy_hz": float(getattr(self.env, "control_freq", 0.0)), "input_hold": "first"},
            time=rec.array("time"), truth_state=rec.array("state"), u_applied=rec.array("u_applied"),
            faults={f.name: FaultLabels(labels[:, i, 0] > 0, labels[:, i, 1], fault_unit[f.name])
                    for i, f in enumerate(self.faults)},
            signals={"reference": np.floor(rec.array("time")[:, None] * getattr(self.env, "control_freq", 1.0) + 1e-6),
                     "u_cmd": rec.array("u_cmd"), "u": u, "u_diag": u, "y_true": rec.array("y_true"),
                     "y_meas": rec.array("y_meas"), "qpos": rec.array("qpos")},
            diagnosers=dict(diagnosers or {}),
            meta={"injection": "online", "duration": float(h["time"][-1]), "faults": [f.to_dict() for f in self.faults],
                  "controller": a.controller, "episode": self._episode, "mjcf": MJCF_FILE,
                  "mjcf_joint_prefix": a.prefix,
                  "accommodation": type(self.accommodation).__name__ if self.accommodation is not None else None,
                  **(meta or {})},
            columns=columns, units=units)
