"""A ``gymnasium.Wrapper`` that injects robofdi faults into any Gymnasium environment's actions and observations.

::

    import gymnasium
    from robofdi.adapters.gymnasium import FaultyEnv

    env = FaultyEnv(gymnasium.make("Reacher-v5"), ["actuator_loss_of_effectiveness:actuator1:0.6@0.5",
                                                   "sensor_bias:obs[6]:0.2@0.3"], seed=0)
    obs, info = env.reset(seed=1)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    info["robofdi_faults"]     # (n_faults, 2): [active (0/1), value] per fault, order = env.fault_names

Targets. Actuator faults act on the entries of a 1-D ``Box`` action, after the policy and before the environment;
an environment built on MuJoCo (``env.unwrapped.model`` a ``mujoco.MjModel`` with one actuator per action entry)
names them by its actuator names (an unnamed actuator is ``actuator<i>``), any other ``action[<i>]``. The faulty
action is clipped to the action space (the actuator saturates) and the label holds what the environment really
received. Sensor faults act on observation entries: ``obs[<i>]`` (flat index) for a ``Box`` observation,
``<key>[<i>]`` (or ``<key>`` for one element) for a ``Dict`` of ``Box`` es; the faulty observation is clipped to the
observation space where it is bounded (a sensor saturates at its range). Component faults need per-environment
physics edits and are refused.

Timing: the fault clock is step k × ``dt`` [s] (``env.unwrapped.dt``, the control step of Gymnasium's MuJoCo
environments; ``dt`` overrides it; 1.0 — onsets counted in steps — when the environment has none). An action fault
is evaluated at the time the action is applied (k·dt), a sensor fault at the time of the observation it corrupts.
The core's :class:`~robofdi.faults.FaultInjector` does the work: every profile, ``end`` time and seeded randomness is
the core's.

Labels: ``info["robofdi_faults"]`` after ``reset`` and every ``step`` — a float64 array (n_faults, 2): column 0 is
1.0 while the fault is active, column 1 the change it made to its target (action or observation unit; 0 while
inactive). It is the truth: a policy or diagnoser must not read it. Vector environments stack it to
(num_envs, n_faults, 2) (:func:`make_vector`).

Seeds: ``reset(seed=s)`` restarts the fault randomness from ``robofdi.seeding.stream(seed, "reset", str(s))`` (so a
seeded reset replays the episode exactly, as Gymnasium's ``check_env`` demands); every later unseeded reset k draws
from that stream's child ``"episode", str(k)``. The environment's own randomness is the environment's (``reset(seed)``
is passed through).

Diagnosis (optional): ``diagnosis`` (a :class:`~robofdi.loop.DiagnosisBank` at the step rate) with ``measure`` (the
measurement y the diagnosers read from the *faulty* observation, e.g.
:class:`robofdi.adapters.gymnasium_diagnosis.JointReadout`) is pushed after ``reset`` and every ``step`` with y and the
action the policy commanded over the step that ended (zeros at reset); ``info["robofdi_diagnosis"]`` then holds,
per diagnoser, ``alarm`` (one bool per residual component) and ``isolated`` (the isolated faults, ``+``-joined, "" for
none). :meth:`FaultyEnv.record` gives the episode as a robofdi :class:`~robofdi.record.Record`.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from functools import partial

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.gymnasium needs gymnasium: pip install 'robofdi[gymnasium]'") from None

from robofdi.errors import RobofdiError
from robofdi.faults import Fault, FaultInjector, parse_fault_spec
from robofdi.loop import DiagnosisBank, Recorder
from robofdi.record import FaultLabels, Record
from robofdi.seeding import MAX_SEED, check_seed, stream

__all__ = ["FaultyEnv", "LABELS_KEY", "DIAGNOSIS_KEY", "action_channels", "observation_channels", "make_vector",
           "state_columns"]

#: The ``info`` entry that carries the ground-truth labels (as in the dm_control and robosuite adapters).
LABELS_KEY = "robofdi_faults"
#: The ``info`` entry that carries the diagnosers' alarms and isolation (with a ``diagnosis``).
DIAGNOSIS_KEY = "robofdi_diagnosis"


def _mujoco_model(env):
    """The ``mujoco.MjModel`` of a MuJoCo-based environment (``env.unwrapped.model``), else None."""
    try:
        import mujoco
    except ImportError:  # pragma: no cover - mujoco is a core dependency
        return None
    m = getattr(env.unwrapped, "model", None)
    return m if isinstance(m, mujoco.MjModel) else None


def action_channels(env) -> list[str]:
    """Names of the entries of ``env``'s 1-D ``Box`` action: its MuJoCo actuator names when it is MuJoCo-based with
    one actuator per entry (``actuator<i>`` when unnamed), else ``action[<i>]``; [] for any other action space."""
    space = env.action_space
    if not isinstance(space, spaces.Box) or len(space.shape) != 1:
        return []
    n = int(space.shape[0])
    m = _mujoco_model(env)
    if m is not None and m.nu == n:
        import mujoco

        return [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}" for i in range(n)]
    return [f"action[{i}]" for i in range(n)]


def state_columns(m) -> tuple[list[str], list[str]]:
    """Names and units of [qpos; qvel] of MuJoCo model ``m``: a hinge or slide joint's ``<name>`` [rad or m] and
    ``<name>_vel`` [rad/s or m/s]; a free or ball joint's ``<name>_qpos<i>`` / ``<name>_qvel<i>`` (mixed units)."""
    import mujoco

    pos, vel, pos_u, vel_u = [], [], [], []
    sizes = {mujoco.mjtJoint.mjJNT_FREE: (7, 6), mujoco.mjtJoint.mjJNT_BALL: (4, 3)}
    for j in range(m.njnt):
        name, kind = m.joint(j).name or f"joint{j}", int(m.jnt_type[j])
        if kind in sizes:
            nq, nv = sizes[kind]
            pos += [f"{name}_qpos{i}" for i in range(nq)]
            vel += [f"{name}_qvel{i}" for i in range(nv)]
            pos_u += ["m, 1"] * nq
            vel_u += ["m/s, rad/s"] * nv
        else:
            hinge = kind == mujoco.mjtJoint.mjJNT_HINGE
            pos.append(name)
            vel.append(f"{name}_vel")
            pos_u.append("rad" if hinge else "m")
            vel_u.append("rad/s" if hinge else "m/s")
    return pos + vel, pos_u + vel_u


def _layout(space) -> list[tuple[str | None, int, spaces.Box]]:
    """(dict key or None, size, Box) of every part of an observation space that sensor faults can act on."""
    if isinstance(space, spaces.Box):
        return [(None, int(np.prod(space.shape, dtype=int)), space)]
    if isinstance(space, spaces.Dict) and all(isinstance(s, spaces.Box) for s in space.spaces.values()):
        return [(key, int(np.prod(s.shape, dtype=int)), s) for key, s in space.spaces.items()]
    return []


def observation_channels(space) -> list[str]:
    """Names of the scalars of an observation space: ``obs[<i>]`` of a ``Box`` (flat index); ``<key>[<i>]`` (``<key>``
    for one element) of a ``Dict`` of ``Box`` es; [] for any other space (no sensor faults there)."""
    names = []
    for key, size, _ in _layout(space):
        if key is None:
            names += [f"obs[{i}]" for i in range(size)]
        else:
            names += [key] if size == 1 else [f"{key}[{i}]" for i in range(size)]
    return names


def _latest(runner) -> dict:
    """The alarms and isolation of a :class:`~robofdi.loop.DiagnosisRunner`'s last diagnosis sample."""
    alarm, isolated = runner.latest()
    return {"alarm": alarm, "isolated": isolated}


def _faults(faults) -> tuple[Fault, ...]:
    if isinstance(faults, (str, Fault)) or not isinstance(faults, Sequence):
        raise RobofdiError(f"FaultyEnv: field 'faults' must be a list of Fault or fault-spec strings, got {faults!r}")
    out = []
    for f in faults:
        f = parse_fault_spec(f) if isinstance(f, str) else f
        if not isinstance(f, Fault):
            raise RobofdiError(f"FaultyEnv: field 'faults' must hold Fault objects or spec strings, got {f!r}")
        if f.family == "component":
            raise RobofdiError(f"Fault {f.name!r}: kind {f.kind!r} is a component fault; the Gymnasium adapter takes "
                               "actuator faults (on the action) and sensor faults (on observation entries)")
        out.append(f)
    return tuple(out)


class FaultyEnv(gymnasium.Wrapper, gymnasium.utils.RecordConstructorArgs):
    """``env`` with ``faults`` on its actions and observations and their labels in ``info["robofdi_faults"]``
    (module docstring). ``seed``: the root of the fault randomness (an integer >= 0). ``dt``: the fault clock's step
    [s] (default ``env.unwrapped.dt``, else 1.0). ``diagnosis`` / ``measure``: an optional
    :class:`~robofdi.loop.DiagnosisBank` stepped at every step on ``measure(observation)``."""

    def __init__(self, env: gymnasium.Env, faults: Sequence[Fault | str] = (), seed: int = 0, dt: float | None = None,
                 diagnosis: DiagnosisBank | None = None, measure: Callable[[np.ndarray], np.ndarray] | None = None):
        if not isinstance(env, gymnasium.Env):
            raise RobofdiError(f"FaultyEnv: field 'env' must be a gymnasium.Env, got {type(env).__name__}")
        gymnasium.utils.RecordConstructorArgs.__init__(self, faults=list(faults), seed=seed, dt=dt)  # env.spec remakes it
        gymnasium.Wrapper.__init__(self, env)
        self.seed = check_seed("FaultyEnv: field 'seed'", seed)
        self.faults = _faults(faults)
        self.actuators = action_channels(env)
        self.sensors = observation_channels(env.observation_space)
        if any(f.family == "actuator" for f in self.faults) and not self.actuators:
            raise RobofdiError(f"FaultyEnv: actuator faults need a 1-D Box action space, got {env.action_space}")
        if dt is None:
            dt = getattr(env.unwrapped, "dt", None)
            dt = 1.0 if dt is None else dt
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.number)) or not (np.isfinite(dt) and dt > 0):
            raise RobofdiError(f"FaultyEnv: field 'dt' must be a step duration > 0 s, got {dt!r}")
        self.dt = float(dt)
        if diagnosis is not None and not isinstance(diagnosis, DiagnosisBank):
            raise RobofdiError(f"FaultyEnv: field 'diagnosis' must be a robofdi.loop.DiagnosisBank, got "
                               f"{type(diagnosis).__name__}")
        if diagnosis is not None and not callable(measure):
            raise RobofdiError("FaultyEnv: field 'measure' must be a function observation -> measurement y when a "
                               "diagnosis is given (e.g. robofdi.adapters.gymnasium_diagnosis.JointReadout)")
        self.diagnosis, self.measure = diagnosis, measure
        if self.actuators:
            space = env.action_space
            self._lo = np.broadcast_to(space.low, space.shape).astype(float)
            self._hi = np.broadcast_to(space.high, space.shape).astype(float)
        self._root, self._episode, self._k = stream(self.seed, "reset", "none"), -1, 0
        self.injector = self._injector()             # validates every target now, with a clear error
        self._recorder: Recorder | None = None

    # ------------------------------------------------------------------------------------------------ names
    @property
    def fault_names(self) -> list[str]:
        """Row order of the labels."""
        return [f.name for f in self.faults]

    @property
    def time(self) -> float:
        """The fault clock now [s]: step k × dt, rounded to 1 ns."""
        return round(self._k * self.dt, 9)

    def _injector(self) -> FaultInjector:
        seed = stream(self._root, "episode", str(max(self._episode, 0)))
        saturate = (lambda u: np.minimum(np.maximum(u, self._lo), self._hi)) if self.actuators else None
        return FaultInjector(self.faults, self.actuators, self.sensors, seed, saturate=saturate)

    # ------------------------------------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._root, self._episode = stream(self.seed, "reset", str(check_seed("reset: field 'seed'", seed))), 0
        else:
            self._episode += 1
        self.injector = self._injector()
        self._k = 0
        obs, info = self.env.reset(seed=seed, options=options)
        self._recorder = Recorder(("time", "state", "obs_true", "obs", "u_cmd", "u", "labels"))
        if self.diagnosis is not None:
            self.diagnosis.reset()
        n_u = len(self.actuators) or int(np.prod(getattr(self.action_space, "shape", ()) or (1,), dtype=int))
        self._u_prev = np.zeros(n_u)
        return self._observe(obs, dict(info), None)

    def step(self, action):
        if self._recorder is None:
            raise RobofdiError("FaultyEnv: call reset() before step()")
        t = self.time
        sent = action
        if self.actuators:
            u_cmd = np.minimum(np.maximum(np.asarray(action, dtype=float).reshape(-1), self._lo), self._hi)
            if self.injector._by_family["actuator"]:
                u = self.injector.actuate(t, u_cmd)
                sent = np.minimum(np.maximum(u, self._lo), self._hi).astype(self.action_space.dtype)
            else:
                u = u_cmd
        else:
            u_cmd = u = np.asarray(action, dtype=float).reshape(-1)
        obs, reward, terminated, truncated, info = self.env.step(sent)
        self._k += 1
        obs, info = self._observe(obs, dict(info), (u_cmd, u))
        return obs, reward, terminated, truncated, info

    def _observe(self, obs, info: dict, inputs):
        """Sensor faults on ``obs`` at the time now, the labels (and the diagnosis) in ``info``: (obs, info)."""
        t, clean = self.time, obs
        if self.injector._by_family["sensor"]:
            flat = self._flatten(obs)
            obs = self._unflatten(self.injector.sense(t, flat), obs)
        labels = self.injector.labels
        info[LABELS_KEY] = np.array([[float(labels[n][0]), float(labels[n][1])] for n in self.fault_names],
                                    dtype=np.float64).reshape(len(self.faults), 2)
        u_cmd, u = inputs if inputs is not None else (self._u_prev, self._u_prev)
        if self.diagnosis is not None:
            self.diagnosis.push(self._k, t, np.asarray(self.measure(obs), dtype=float), self._u_prev)
            info[DIAGNOSIS_KEY] = {name: _latest(r) for name, r in self.diagnosis.runners.items()}
        if inputs is not None:
            self._u_prev = np.array(u_cmd, dtype=float)
        self._recorder.append(time=t, state=self._state(clean), obs_true=self._flatten(clean) if self.sensors else [],
                              obs=self._flatten(obs) if self.sensors else [], u_cmd=np.array(u_cmd, dtype=float),
                              u=np.array(u, dtype=float), labels=info[LABELS_KEY].copy())
        return obs, info

    def _flatten(self, obs) -> np.ndarray:
        if isinstance(obs, Mapping):
            return np.concatenate([np.asarray(obs[key], dtype=float).ravel() for key, _, _ in _layout(self.observation_space)])
        return np.asarray(obs, dtype=float).ravel()

    def _unflatten(self, flat: np.ndarray, like):
        """``flat`` back in the shape of observation ``like``, clipped to the space's bounds, in its dtypes."""
        out, start = {}, 0
        for key, size, box in _layout(self.observation_space):
            value = np.asarray(like if key is None else like[key])
            part = np.clip(flat[start:start + size].reshape(value.shape), box.low, box.high).astype(value.dtype)
            start += size
            if key is None:
                return part
            out[key] = part
        return {**like, **out}

    def _state(self, clean) -> np.ndarray:
        """The truth: MuJoCo's [qpos; qvel] for a MuJoCo environment, else the fault-free observation (flat)."""
        data = getattr(self.env.unwrapped, "data", None)
        if _mujoco_model(self.env) is not None and data is not None:
            return np.concatenate([data.qpos, data.qvel]).astype(float)
        try:
            return self._flatten(clean) if self.sensors else np.zeros(0)
        except (TypeError, ValueError):
            return np.zeros(0)

    # ------------------------------------------------------------------------------------------------ record
    def record(self, scenario: str = "gymnasium", meta: dict | None = None) -> Record:
        """The episode so far as a robofdi :class:`~robofdi.record.Record` at the step rate: truth/state (MuJoCo's
        qpos, qvel; else the fault-free observation), the commanded and applied actions, the fault-free and the
        faulty observation, the labels, and the traces of the wrapper's diagnosis."""
        rec = self._recorder
        if rec is None or not rec.rows["time"]:
            raise RobofdiError("FaultyEnv.record: nothing recorded yet (reset() first)")
        t = rec.array("time")
        n = len(t)
        labels = rec.array("labels").reshape(n, len(self.faults), 2)
        units = {"actuator": "1 (action)", "sensor": "observation unit"}
        u_cols = self.actuators or [f"action[{i}]" for i in range(rec.array("u").reshape(n, -1).shape[1])]
        state = rec.array("state").reshape(n, -1)
        m = _mujoco_model(self.env)
        if m is not None:
            s_cols, s_units = state_columns(m)
        else:
            s_cols, s_units = [f"state[{i}]" for i in range(state.shape[1])], ["1"] * state.shape[1]
        columns = {"truth/state": s_cols, "truth/u_applied": u_cols, "signals/u_cmd": u_cols, "signals/u": u_cols}
        unit = {"truth/state": s_units, "truth/u_applied": ["1"] * len(u_cols), "signals/u_cmd": ["1"] * len(u_cols),
                "signals/u": ["1"] * len(u_cols)}
        signals = {"u_cmd": rec.array("u_cmd").reshape(n, -1), "u": rec.array("u").reshape(n, -1)}
        if self.sensors:
            signals["y_true"], signals["y_meas"] = rec.array("obs_true").reshape(n, -1), rec.array("obs").reshape(n, -1)
            for key in ("y_true", "y_meas"):
                columns[f"signals/{key}"], unit[f"signals/{key}"] = list(self.sensors), ["1"] * len(self.sensors)
        spec = getattr(self.env, "spec", None)
        return Record(
            system=f"gymnasium-{spec.id if spec is not None else type(self.env.unwrapped).__name__}", scenario=scenario,
            seed=self.seed, rates={"control_hz": 1.0 / self.dt, "diagnosis_hz": 1.0 / self.dt, "input_hold": "first"},
            time=t, truth_state=state, u_applied=signals["u"],
            faults={f.name: FaultLabels(labels[:, i, 0] > 0, labels[:, i, 1], units[f.family])
                    for i, f in enumerate(self.faults)},
            signals=signals, diagnosers=self.diagnosis.traces() if self.diagnosis is not None else {},
            meta={"injection": "online", "duration": float(t[-1]), "faults": [f.to_dict() for f in self.faults],
                  "episode": self._episode, **(meta or {})},
            columns=columns, units=unit)


def _make_faulty(env_id: str, faults: tuple, seed: int, kwargs: dict) -> FaultyEnv:
    return FaultyEnv(gymnasium.make(env_id, **kwargs), list(faults), seed=seed)


def make_vector(env_id: str, num_envs: int, faults: Sequence[Fault | str] = (), seed: int = 0,
                vectorization_mode: str = "sync", **kwargs) -> gymnasium.vector.VectorEnv:
    """``num_envs`` copies of ``gymnasium.make(env_id, **kwargs)``, each in a :class:`FaultyEnv` with ``faults`` and
    its own fault seed (sub-environment i: drawn from ``stream(seed, "vector", str(i))``), in a Gymnasium
    ``SyncVectorEnv`` (``vectorization_mode="sync"``) or ``AsyncVectorEnv`` (``"async"``, one process each). The
    labels arrive stacked in ``info["robofdi_faults"]`` (num_envs, n_faults, 2)."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise RobofdiError(f"make_vector: field 'num_envs' must be an integer >= 1, got {num_envs!r}")
    if vectorization_mode not in ("sync", "async"):
        raise RobofdiError(f"make_vector: field 'vectorization_mode' must be 'sync' or 'async', got {vectorization_mode!r}")
    faults = _faults(faults)
    seeds = [int(np.random.default_rng(stream(check_seed("make_vector: field 'seed'", seed), "vector", str(i)))
                 .integers(MAX_SEED)) for i in range(num_envs)]
    fns = [partial(_make_faulty, env_id, faults, s, dict(kwargs)) for s in seeds]
    if vectorization_mode == "sync":
        return gymnasium.vector.SyncVectorEnv(fns)
    return gymnasium.vector.AsyncVectorEnv(fns)
