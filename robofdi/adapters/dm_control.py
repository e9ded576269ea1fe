"""A ``dm_env.Environment`` wrapper that injects robofdi faults into a dm_control (or any MuJoCo dm_env) environment.

::

    from dm_control import suite
    from robofdi.adapters.dm_control import FaultyEnvironment

    env = FaultyEnvironment(suite.load("cartpole", "swingup", task_kwargs={"random": 0}),
                            ["actuator_loss_of_effectiveness:slide:0.6@2.0",
                             "sensor_bias:velocity[1]:0.5@1.0-3.0~intermittent(0.4,0.5)"], seed=0)
    ts = env.reset()
    ts.observation["robofdi_faults"]      # (n_faults, 2): [active (0/1), value] per fault, order = env.fault_names

Targets. Actuator faults act on the action vector, named by the physics' actuator names (an unnamed actuator is
``actuator<i>``), after the policy and before MuJoCo; the faulty action is clipped to the action spec (the
actuator saturates) and the label holds what the plant really received. Sensor faults act on observation entries,
named ``"<key>[<i>]"`` (flat index into the entry) or ``"<key>"`` for an entry with one element. Component faults
are not supported by this adapter (they need per-domain physics edits) and are refused.

Timing: the fault clock is the physics time (rounded to 1 ns). An action fault is evaluated at the time the action is applied
(the time of the previous timestep); a sensor fault at the time of the observation it corrupts. The core's
:class:`~robofdi.faults.FaultInjector` does the work, so every profile (step, ramp, exponential rise,
intermittent, ...), the ``end`` (recovery) time and the per-fault seeded randomness are the core's.

Labels: dm_env's ``TimeStep`` has no free field, so the ground truth goes in the observation, as the extra entry
``"robofdi_faults"`` — a float64 array (n_faults, 2) declared in :meth:`observation_spec`, so dm_env's spec
checks cover it. Column 0 is 1.0 while the fault is active, column 1 the change it made to its target (in the
target's unit; 0 while inactive). A policy or diagnoser must not read this entry (truth, not belief);
:func:`strip_labels` removes it.

Seeds: episode k of a wrapper built with ``seed`` draws its fault randomness from
``robofdi.seeding.stream(seed, "episode", str(k))``, so the same seed (and the same task ``random``) replays the same
trajectories. The wrapped task's own randomness (initial states) is the task's: seed it with ``task_kwargs={"random": ...}``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

try:
    import dm_env
    from dm_env import specs
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.adapters.dm_control needs dm_control: pip install 'robofdi[dm_control]'") from None

from robofdi.errors import RobofdiError
from robofdi.faults import Fault, FaultInjector, parse_fault_spec
from robofdi.seeding import stream

__all__ = ["FaultyEnvironment", "LABELS_KEY", "actuator_names", "observation_channels", "strip_labels"]

#: The observation entry that carries the ground-truth labels.
LABELS_KEY = "robofdi_faults"


def actuator_names(physics) -> list[str]:
    """Names of the entries of the action vector: the MuJoCo actuator names (``actuator<i>`` when unnamed)."""
    import mujoco

    m = physics.model.ptr
    return [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}" for i in range(m.nu)]


def observation_channels(obs_spec: Mapping[str, specs.Array]) -> list[tuple[str, str, int]]:
    """(channel name, observation key, flat index) of every scalar of the observation, in spec order."""
    out = []
    for key, spec in obs_spec.items():
        size = int(np.prod(spec.shape, dtype=int))
        out.extend([(key, key, 0)] if size == 1 else [(f"{key}[{i}]", key, i) for i in range(size)])
    return out


def strip_labels(observation: Mapping) -> dict:
    """The observation without the ground-truth entry (what a policy or diagnoser may read)."""
    return {k: v for k, v in observation.items() if k != LABELS_KEY}


def _faults(faults) -> tuple[Fault, ...]:
    if isinstance(faults, (str, Fault)) or not isinstance(faults, Sequence):
        raise RobofdiError(f"FaultyEnvironment: field 'faults' must be a list of Fault or fault-spec strings, got {faults!r}")
    out = []
    for f in faults:
        if isinstance(f, str):
            f = parse_fault_spec(f)
        if not isinstance(f, Fault):
            raise RobofdiError(f"FaultyEnvironment: field 'faults' must hold Fault objects or spec strings, got {f!r}")
        if f.family == "component":
            raise RobofdiError(f"Fault {f.name!r}: kind {f.kind!r} is a component fault; the dm_control adapter takes "
                               "actuator faults (on the action) and sensor faults (on observation entries)")
        out.append(f)
    return tuple(out)


class FaultyEnvironment(dm_env.Environment):
    """``env`` with ``faults`` on its actions and observations and their labels in ``observation["robofdi_faults"]``
    (module docstring). ``env`` must be a dm_env environment with a MuJoCo ``physics`` (every dm_control suite
    environment) and a dict observation spec."""

    def __init__(self, env: dm_env.Environment, faults: Sequence[Fault | str], seed: int = 0):
        if not isinstance(env, dm_env.Environment):
            raise RobofdiError(f"FaultyEnvironment: field 'env' must be a dm_env.Environment, got {type(env).__name__}")
        physics = getattr(env, "physics", None)
        if physics is None or not hasattr(getattr(physics, "model", None), "ptr"):
            raise RobofdiError("FaultyEnvironment: field 'env' must have a MuJoCo 'physics' (a dm_control environment)")
        obs_spec = env.observation_spec()
        if not isinstance(obs_spec, Mapping):
            raise RobofdiError(f"FaultyEnvironment: the observation spec must be a dict of arrays, got {type(obs_spec).__name__}")
        if LABELS_KEY in obs_spec:
            raise RobofdiError(f"FaultyEnvironment: the observation already has an entry {LABELS_KEY!r} (wrapped twice?)")
        act_spec = env.action_spec()
        if not isinstance(act_spec, specs.Array) or len(act_spec.shape) != 1:
            raise RobofdiError(f"FaultyEnvironment: the action spec must be one 1-D array, got {act_spec!r}")
        self.actuators = actuator_names(physics)
        if len(self.actuators) != act_spec.shape[0]:
            raise RobofdiError(f"FaultyEnvironment: the action has {act_spec.shape[0]} entries but the physics "
                               f"{len(self.actuators)} actuators; expected one action entry per actuator")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise RobofdiError(f"FaultyEnvironment: field 'seed' must be an integer >= 0, got {seed!r}")
        self.env, self.seed, self.faults = env, int(seed), _faults(faults)
        self._channels = observation_channels(obs_spec)
        self.sensors = [c[0] for c in self._channels]
        self._lo = np.broadcast_to(getattr(act_spec, "minimum", -np.inf), act_spec.shape).astype(float)
        self._hi = np.broadcast_to(getattr(act_spec, "maximum", np.inf), act_spec.shape).astype(float)
        self._episode = -1
        self.injector = self._injector(0)          # validates every target now, with a clear error

    @property
    def physics(self):
        return self.env.physics

    @property
    def fault_names(self) -> list[str]:
        """Row order of the labels."""
        return [f.name for f in self.faults]

    def _injector(self, episode: int) -> FaultInjector:
        return FaultInjector(self.faults, self.actuators, self.sensors, stream(self.seed, "episode", str(episode)),
                             saturate=lambda u: np.clip(u, self._lo, self._hi))

    def _time(self) -> float:
        # rounded to 1 ns: MuJoCo's time is a running sum of timesteps, and 0.49999999999 must count as 0.5
        return round(float(self.env.physics.data.time), 9)

    def _observe(self, ts: dm_env.TimeStep) -> dm_env.TimeStep:
        obs = dict(ts.observation)
        if self.injector._by_family["sensor"]:
            flat = np.concatenate([np.asarray(obs[k], dtype=float).ravel() for k in dict.fromkeys(c[1] for c in self._channels)])
            faulty = self.injector.sense(self._time(), flat)
            start = 0
            for key in dict.fromkeys(c[1] for c in self._channels):
                value = np.asarray(obs[key])
                obs[key] = faulty[start:start + value.size].reshape(value.shape).astype(value.dtype)
                start += value.size
        labels = self.injector.labels
        obs[LABELS_KEY] = np.array([[float(labels[n][0]), float(labels[n][1])] for n in self.fault_names],
                                   dtype=np.float64).reshape(len(self.faults), 2)
        return ts._replace(observation=obs)

    def reset(self) -> dm_env.TimeStep:
        self._episode += 1
        self.injector = self._injector(self._episode)
        return self._observe(self.env.reset())

    def step(self, action) -> dm_env.TimeStep:
        t = self._time()
        action = np.asarray(action, dtype=float)
        faulty = self.injector.actuate(t, action) if self.injector._by_family["actuator"] else action
        return self._observe(self.env.step(faulty))

    def observation_spec(self):
        spec = dict(self.env.observation_spec())
        spec[LABELS_KEY] = specs.Array((len(self.faults), 2), np.float64, name=LABELS_KEY)
        return spec

    def action_spec(self):
        return self.env.action_spec()

    def reward_spec(self):
        return self.env.reward_spec()

    def discount_spec(self):
        return self.env.discount_spec()

    def close(self):
        self.env.close()
