"""Motion design for any serial arm from its nominal model: joint ranges and motor torque limits in, smooth
quintic motions out whose nominal computed-torque feed-forward stays within a chosen fraction of the limits.

Durations use the time-scaling property of the inverse dynamics (Hollerbach, "Dynamic scaling of manipulator
trajectories", ASME J. Dyn. Syst. Meas. Control 106(1), 1984). A quintic q(t) = q₀ + p(t/T) Δq walks the same
path for every duration T, and with q̇ = p′Δq/T, q̈ = p″Δq/T² the nominal torque at path point s is

    τ(s; T) = g(q(s)) + a(s)/T + b(s)/T²,   a = D̂ p′Δq,   b = M̂(q) p″Δq + C(q, p′Δq) p′Δq,

a quadratic in x = 1/T. The shortest admissible T is 1/x*, with x* the first x > 0 at which some joint
reaches ±torque_fraction · limit at some sampled s; every longer duration is then admissible too.
The worst-case calibration motions follow Caccavale & Villani, "Fault Diagnosis for Industrial Robots"
(2003), Sec. 6: very low velocities, and high accelerations with wide displacements.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from robofdi import RobofdiError
from robofdi.control.trajectory import Quintic, Sequence
from robofdi.seeding import rng as seeded_rng

__all__ = ["MotionLimits", "joint_ranges", "fit_duration", "random_point_to_point", "calibration_motions", "SPEEDS"]

#: Duration factor ranges (× the shortest admissible duration) of ``random_point_to_point``'s ``speed``.
SPEEDS = {"fast": (1.0, 1.0), "normal": (1.3, 2.0), "slow": (2.5, 4.0)}

# Waypoints are chosen so that gravity alone uses at most this share of the torque budget anywhere on the
# way to them: the rest is left for acceleration, so segment durations stay short.
_GRAVITY_SHARE = 0.8
_MAX_TRIES = 400
# Self-collision is checked along straight joint paths every this many rad of the largest joint displacement.
_COLLISION_STEP = 0.05
# Clearance [m] a planned path keeps between links not joined to each other: the tracked motion deviates from the
# reference (fast motions on robosuite's Panda: paths that passed 3.5–12 mm from link 5 ran link 7 into it).
SELF_CLEARANCE = 0.015
#: One turn [rad]: the widest working range of a joint (MotionLimits).
TURN = 2 * np.pi
# The duration is fitted to (1 − this) × the budget at the sampled path points, to cover the torque between them
# (at 257 samples the excess between samples is of the order of 1e-5 of the budget).
_SAMPLING_HEADROOM = 1e-3


def _vector(name: str, value, n: int | None = None) -> tuple:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0 and n is not None:
        arr = np.full(n, float(arr))
    if arr.ndim != 1 or arr.size == 0 or (n is not None and arr.size != n):
        want = f"{n} values" if n is not None else "a non-empty 1-D sequence"
        raise RobofdiError(f"MotionLimits: field {name!r} must be {want}, got {np.shape(value)}")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class MotionLimits:
    """What a designed motion must respect, per joint.

    lower, upper: joint position range [rad] (from the MJCF: :func:`joint_ranges` or :meth:`from_model`);
    −inf/+inf for a continuous (unlimited) joint;
    torque_limit: motor torque limit [N·m] (> 0, may be inf);
    range_margin: fraction of each *working* range kept clear at *each* end, in [0, 0.5);
    torque_fraction: fraction of the torque limit the nominal feed-forward may use, in (0, 1]; the rest is
    left to the feedback and to the model error;
    max_speed: optional joint speed limit [rad/s], one value or one per joint, > 0 (inf: none);
    centre: optional centre [rad] of the working range of the joints whose range spans more than one turn, one
    value or one per joint (default: the middle of a finite range, 0 — the file's reference — of an unlimited one).

    The working range (:attr:`working_lower`, :attr:`working_upper`) is where motions are designed: the joint
    range itself when it spans at most one turn (2π); otherwise — continuous joints, and ranges such as ±2π —
    the one turn [centre − π, centre + π], moved inside the range if needed. One turn is enough: the rigid-body
    dynamics of a revolute joint (gravity, inertia, Coulomb and viscous terms) are 2π-periodic in its angle,
    so every pose the joint can take is covered (a slide joint's range in m wider than 2π is windowed alike).
    """

    lower: tuple
    upper: tuple
    torque_limit: tuple
    range_margin: float = 0.1
    torque_fraction: float = 0.6
    max_speed: tuple | None = None
    centre: tuple | None = None

    def __post_init__(self):
        lower = _vector("lower", self.lower)
        n = len(lower)
        upper = _vector("upper", self.upper, n)
        torque = _vector("torque_limit", self.torque_limit, n)
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "torque_limit", torque)
        lo, hi = np.array(lower), np.array(upper)
        bad = np.flatnonzero(~(lo < hi) | (lo == np.inf) | (hi == -np.inf))       # also NaN
        if bad.size:
            raise RobofdiError(f"MotionLimits: fields 'lower' < 'upper' must be joint ranges [rad] (−inf/+inf for a "
                               f"continuous joint), got joints {bad.tolist()} (0-based): {lower}, {upper}")
        if not np.all(np.array(torque) > 0):  # also rejects NaN
            raise RobofdiError(f"MotionLimits: field 'torque_limit' must be > 0 N·m per joint (inf allowed), got {torque}")
        if not (np.isfinite(self.range_margin) and 0.0 <= self.range_margin < 0.5):
            raise RobofdiError(f"MotionLimits: field 'range_margin' must be in [0, 0.5), got {self.range_margin!r}")
        if not (np.isfinite(self.torque_fraction) and 0.0 < self.torque_fraction <= 1.0):
            raise RobofdiError(f"MotionLimits: field 'torque_fraction' must be in (0, 1], got {self.torque_fraction!r}")
        if self.max_speed is not None:
            speed = _vector("max_speed", self.max_speed, n)
            if not all(v > 0 for v in speed):                  # also rejects NaN
                raise RobofdiError(f"MotionLimits: field 'max_speed' must be > 0 rad/s (inf: none), got {speed}")
            object.__setattr__(self, "max_speed", speed)
        if self.centre is not None:
            centre = _vector("centre", self.centre, n)
            if not np.all(np.isfinite(centre)):
                raise RobofdiError(f"MotionLimits: field 'centre' must be finite angles [rad], got {centre}")
            object.__setattr__(self, "centre", centre)

    @classmethod
    def from_ranges(cls, lower, upper, torque_limit, **kwargs) -> MotionLimits:
        """From joint ranges [rad] and torque limits [N·m]; keyword arguments as the dataclass fields."""
        return cls(tuple(np.ravel(lower)), tuple(np.ravel(upper)), tuple(np.ravel(torque_limit)), **kwargs)

    @classmethod
    def from_model(cls, model, **kwargs) -> MotionLimits:
        """From a :class:`~robofdi.models.ManipulatorModel`: the joint ranges of its file (±inf where unlimited),
        its motor torque limits and, where the file gives them, its velocity limits (``max_speed``)."""
        lower, upper = np.asarray(model.joint_range, dtype=float).T
        speed = np.asarray(getattr(model, "velocity_limit", np.full(model.n, np.inf)), dtype=float)
        if "max_speed" not in kwargs and np.any(np.isfinite(speed)):
            kwargs["max_speed"] = tuple(speed)
        return cls.from_ranges(lower, upper, model.torque_limit, **kwargs)

    @property
    def n(self) -> int:
        return len(self.lower)

    def _working(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = np.array(self.lower), np.array(self.upper)
        wide = ~(hi - lo <= TURN)                       # more than one turn, or unlimited
        if not wide.any():
            return lo, hi
        if self.centre is not None:
            c = np.array(self.centre)
        else:
            with np.errstate(invalid="ignore"):         # inf − inf where unlimited: replaced below
                c = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                             np.where(np.isfinite(lo), lo + np.pi, np.where(np.isfinite(hi), hi - np.pi, 0.0)))
        c = np.clip(c, lo + np.pi, hi - np.pi)          # the whole turn inside the range
        return np.where(wide, c - np.pi, lo), np.where(wide, c + np.pi, hi)

    @property
    def working_lower(self) -> np.ndarray:
        """Lower end of the working range [rad] (class docstring): ``lower``, or centre − π for a wide joint."""
        return self._working()[0]

    @property
    def working_upper(self) -> np.ndarray:
        """Upper end of the working range [rad] (class docstring): ``upper``, or centre + π for a wide joint."""
        return self._working()[1]

    @property
    def usable_lower(self) -> np.ndarray:
        """Lowest position a motion may reach [rad]: the working range's lower end + range_margin · its width."""
        lo, hi = self._working()
        return lo + self.range_margin * (hi - lo)

    @property
    def usable_upper(self) -> np.ndarray:
        """Highest position a motion may reach [rad]: the working range's upper end − range_margin · its width."""
        lo, hi = self._working()
        return hi - self.range_margin * (hi - lo)

    @property
    def torque_budget(self) -> np.ndarray:
        """torque_fraction · torque_limit [N·m]: the bound on the nominal feed-forward."""
        return self.torque_fraction * np.array(self.torque_limit)


def joint_ranges(mjcf: str | Path, joint_names=None) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) [rad] of the named joints (default: all, in file order) as MuJoCo compiles the MJCF.

    Raises RobofdiError naming the joint if it is missing or unlimited."""
    import mujoco

    from robofdi.mjcf import load_model, resolve_asset

    path = resolve_asset(mjcf)
    m = load_model(path)
    if joint_names is None:
        joint_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(m.njnt)]
    lower, upper = [], []
    for name in joint_names:
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0:
            raise RobofdiError(f"joint_ranges: joint {name!r} is not in {path.name}")
        if not m.jnt_limited[j]:
            raise RobofdiError(
                f"joint_ranges: joint {name!r} of {path.name} has no range; give one with MotionLimits.from_ranges")
        lower.append(m.jnt_range[j, 0])
        upper.append(m.jnt_range[j, 1])
    return np.array(lower), np.array(upper)


# ----------------------------------------------------------------------------------------------------------
# Durations
# ----------------------------------------------------------------------------------------------------------
def _profile(samples: int):
    """s ∈ [0, 1] and the quintic's p′(s), p″(s) for a unit duration."""
    s = np.linspace(0.0, 1.0, samples)
    dp = 30 * s**2 - 60 * s**3 + 30 * s**4
    ddp = 60 * s - 180 * s**2 + 120 * s**3
    return s, dp, ddp


def _gravity_along(model, q0: np.ndarray, q1: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Poses (S, n) on the straight joint-space path q0 → q1 and their static torque (S, n) [N·m]."""
    s = np.linspace(0.0, 1.0, samples)[:, None]
    poses = q0 + s * (q1 - q0)
    zero = np.zeros(len(q0))
    return poses, np.array([model.inverse_dynamics(q, zero, zero) for q in poses])


def _first_crossing(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest x > 0 with b x² + a x + c = 0, elementwise (inf where none); c is the value at x = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = a * a - 4 * b * c
        root = np.sqrt(np.where(disc >= 0, disc, np.nan))
        q = -0.5 * (a + np.where(a >= 0, 1.0, -1.0) * root)
        r1 = np.where(q != 0, c / q, np.nan)
        r2 = np.where(b != 0, q / b, np.nan)
        lin = np.where((b == 0) & (a != 0), -c / a, np.nan)
    roots = np.stack([r1, r2, lin])
    roots = np.where(np.isfinite(roots) & (roots > 0), roots, np.inf)
    return roots.min(axis=0)


def _check_pose(name: str, q, limits: MotionLimits) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.shape != (limits.n,) or not np.all(np.isfinite(q)):
        raise RobofdiError(f"{name}: must be {limits.n} finite joint angles [rad], got {q!r}")
    lo, hi = np.array(limits.lower), np.array(limits.upper)
    outside = np.flatnonzero((q < lo) | (q > hi))
    if outside.size:
        raise RobofdiError(f"{name}: joints {outside.tolist()} (0-based) are outside the range [lower, upper] = "
                           f"{[(limits.lower[i], limits.upper[i]) for i in outside]}")
    return q


def _check_model(model, limits: MotionLimits) -> MotionLimits:
    """``limits`` checked against the model, with the model's own velocity limits (``model.velocity_limit``
    [rad/s], inf = none; e.g. a URDF's ``<limit velocity>``) added to ``max_speed`` — the tighter one wins."""
    if model.n != limits.n:
        raise RobofdiError(f"motion design: the model has {model.n} joints but the MotionLimits {limits.n}")
    speed = getattr(model, "velocity_limit", None)
    if speed is None:
        return limits
    speed = np.asarray(speed, dtype=float)
    if speed.shape != (limits.n,) or not np.any(np.isfinite(speed)):
        return limits
    if limits.max_speed is not None:
        speed = np.minimum(speed, limits.max_speed)
        if np.array_equal(speed, limits.max_speed):
            return limits
    return replace(limits, max_speed=tuple(speed))


def _min_duration(model, q0, q1, limits: MotionLimits, samples: int) -> float:
    """Shortest torque- and speed-admissible duration [s] of the quintic q0 → q1 (no floor); raises if gravity
    alone exceeds the budget somewhere on the path."""
    budget = limits.torque_budget
    dq = q1 - q0
    s, dp, ddp = _profile(samples)
    poses = q0 + np.outer(s * s * s * (10 - 15 * s + 6 * s * s), dq)
    g, plus, minus = (np.empty((samples, limits.n)) for _ in range(3))
    zero = np.zeros(limits.n)
    for k, q in enumerate(poses):
        v1, a1 = dp[k] * dq, ddp[k] * dq
        g[k] = model.inverse_dynamics(q, zero, zero)
        plus[k] = model.inverse_dynamics(q, v1, a1)
        minus[k] = model.inverse_dynamics(q, -v1, a1)     # velocity-odd part = viscous term a
    over = np.abs(g) > budget
    if over.any():
        k, j = np.argwhere(over)[0]
        raise RobofdiError(
            f"fit_duration: the gravity torque of joint {j} (0-based) at pose {np.round(poses[k], 4).tolist()} is "
            f"{g[k, j]:.4g} N·m, beyond torque_fraction × limit = {budget[j]:.4g} N·m: no duration is feasible"
        )
    budget = (1.0 - _SAMPLING_HEADROOM) * budget
    if np.any(np.abs(g) >= budget):
        return np.inf
    a = 0.5 * (plus - minus)
    b = 0.5 * (plus + minus) - g
    x = min(_first_crossing(g - budget, a, b).min(), _first_crossing(g + budget, a, b).min())
    duration = 0.0 if np.isinf(x) else 1.0 / x
    if limits.max_speed is not None:   # peak quintic speed 15/8 |Δq| / T
        duration = max(duration, float(np.max(1.875 * np.abs(dq) / np.array(limits.max_speed))))
    return duration


def fit_duration(model, q_start, q_end, limits: MotionLimits, *, floor: float = 0.5, samples: int = 257,
                 max_duration: float = 60.0) -> float:
    """The shortest duration [s] of the quintic q_start → q_end (rad) whose nominal feed-forward
    τ = M̂ q̈ + n̂ stays within ``limits.torque_budget`` on every joint at ``samples`` evenly spaced path points
    (and within ``limits.max_speed``), rounded up to the millisecond and at least ``floor`` s. Every longer
    duration is admissible too (time scaling, see the module docstring).

    model: anything with ``n`` and ``inverse_dynamics(q, q̇, q̈)`` whose torque is quadratic in (q̇, q̈) at
    fixed q (rigid body plus viscous friction, as :class:`~robofdi.models.ManipulatorModel`).
    Raises RobofdiError if gravity alone exceeds the budget somewhere on the path, or if the duration would
    exceed ``max_duration``.
    """
    limits = _check_model(model, limits)
    if not (np.isfinite(floor) and floor > 0):
        raise RobofdiError(f"fit_duration: field 'floor' must be > 0 s, got {floor!r}")
    if not (np.isfinite(max_duration) and max_duration >= floor):
        raise RobofdiError(f"fit_duration: field 'max_duration' must be >= floor = {floor} s, got {max_duration!r}")
    if int(samples) != samples or samples < 3:
        raise RobofdiError(f"fit_duration: field 'samples' must be an integer >= 3, got {samples!r}")
    q0 = _check_pose("fit_duration: field 'q_start'", q_start, limits)
    q1 = _check_pose("fit_duration: field 'q_end'", q_end, limits)
    duration = max(floor, _min_duration(model, q0, q1, limits, int(samples)))
    if duration <= max_duration:
        duration = float(np.ceil(duration * 1000.0 - 1e-6) / 1000.0)
        duration = _verify(model, q0, q1, duration, limits, int(samples))
    if duration > max_duration:
        raise RobofdiError(
            f"fit_duration: the motion needs {duration:.3f} s, more than max_duration = {max_duration} s "
            "(gravity leaves almost no torque for acceleration on this path)"
        )
    return duration


def _verify(model, q0, q1, duration, limits, samples) -> float:
    """Direct check of the torque at the chosen duration; lengthens it by 2 % steps for models whose torque is
    not quadratic in (q̇, q̈) (the closed form is exact otherwise)."""
    budget = limits.torque_budget * (1 + 1e-9)
    for _ in range(200):
        seg = Quintic(tuple(q0), tuple(q1 - q0), duration)
        times = np.linspace(0.0, duration, samples)
        if all(np.all(np.abs(model.inverse_dynamics(*seg(t))) <= budget) for t in times):
            return duration
        duration = float(np.ceil(duration * 1020.0) / 1000.0)
    raise RobofdiError("fit_duration: no admissible duration found (the model's torque does not scale with time)")


# ----------------------------------------------------------------------------------------------------------
# Random point-to-point motions
# ----------------------------------------------------------------------------------------------------------
def _generator(seed, *names: str) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        raise RobofdiError("motion design: field 'seed' must be an integer >= 0, a SeedSequence or a numpy Generator, got None")
    return seeded_rng(seed, "motion", *names)


def _rigid_and_adjacent(m) -> tuple[np.ndarray, np.ndarray]:
    """(ngeom, ngeom) masks: geoms on bodies no joint moves apart (a base on its mount: the same contact at every
    pose, not the motion's doing), and geoms on a body and its parent (whose clearance is the joint's design)."""
    root = np.empty(m.nbody, dtype=int)
    for b in range(m.nbody):                  # parents come before their children in MuJoCo's body order
        root[b] = b if (b == 0 or m.body_jntnum[b] > 0) else root[m.body_parentid[b]]
    body = np.asarray(m.geom_bodyid, dtype=int)
    group = root[body]
    rigid = group[:, None] == group[None, :]
    parent = np.asarray(m.body_parentid, dtype=int)[body]
    adjacent = (parent[:, None] == body[None, :]) | (body[:, None] == parent[None, :])
    return rigid, adjacent & ~rigid


class _SelfCollision:
    """Contacts of the arm's own geometry at given joint positions: MuJoCo's collision detection
    (``mj_kinematics`` + ``mj_collision``: the file's contype/conaffinity, parent filter and excludes) on the
    model file the belief was read from (never the running simulator); the other joints at their reference.

    A pose collides when two geoms touch (closer than the file's margin), or when two links that are not a body
    and its parent come within ``clearance`` [m] (MuJoCo's margin on the scratch model). Pairs on bodies no
    joint moves apart (:func:`_rigid_and_adjacent`), and pairs no joint changes the distance of
    (:func:`robofdi.mjcf.fixed_distance_pairs`), never count: they are the same at every pose."""

    def __init__(self, path: Path, joint_names: tuple, clearance: float = SELF_CLEARANCE):
        import mujoco

        from robofdi.mjcf import fixed_distance_pairs, load_model

        self._mujoco = mujoco
        self.m = load_model(path)
        m = self.m
        self.active = bool(np.any((m.geom_contype != 0) | (m.geom_conaffinity != 0)))
        self.d = mujoco.MjData(m)
        self.qadr = np.array([m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in joint_names])
        self.rigid, self.adjacent = _rigid_and_adjacent(m)
        self.margin = m.geom_margin.copy()          # the file's own: a contact as the simulator reports it
        self.clearance = float(clearance)
        m.geom_margin[:] = np.maximum(self.margin, self.clearance)
        for g1, g2 in fixed_distance_pairs(m, [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joint_names],
                                           self.clearance):
            self.rigid[g1, g2] = self.rigid[g2, g1] = True

    def contacts(self, q) -> list[tuple[int, int, float]]:
        """(geom1, geom2, distance [m]) of every pair at pose q that counts (class docstring)."""
        m, d = self.m, self.d
        d.qpos[:] = m.qpos0
        d.qpos[self.qadr] = q
        self._mujoco.mj_kinematics(m, d)
        self._mujoco.mj_collision(m, d)
        out = []
        for c in d.contact[:d.ncon]:
            g1, g2, dist = int(c.geom1), int(c.geom2), float(c.dist)
            if self.rigid[g1, g2]:
                continue
            if dist < max(self.margin[g1], self.margin[g2]) or (not self.adjacent[g1, g2] and dist < self.clearance):
                out.append((g1, g2, dist))
        return out

    def free(self, poses: np.ndarray) -> bool:
        return not any(self.contacts(q) for q in poses)


def _self_collision(path: str, joint_names: tuple) -> _SelfCollision:
    return _self_collision_of(path, Path(path).stat().st_mtime_ns, joint_names)


@functools.lru_cache(maxsize=16)
def _self_collision_of(path: str, mtime_ns: int, joint_names: tuple) -> _SelfCollision:
    return _SelfCollision(Path(path), joint_names)          # keyed on the file's mtime: an edited file is re-read


def _collision_free(model, q0, q1) -> bool:
    """No self-contact on the straight joint path q0 → q1, sampled every _COLLISION_STEP rad of the largest joint
    displacement (always true for a model without a file, or a file with no colliding geom)."""
    path, names = getattr(model, "path", None), getattr(model, "joint_names", None)
    if path is None or names is None:
        return True
    check = _self_collision(str(path), tuple(names))
    if not check.active:
        return True
    steps = max(2, int(np.ceil(np.max(np.abs(q1 - q0)) / _COLLISION_STEP)) + 1)
    return check.free(q0 + np.linspace(0.0, 1.0, steps)[:, None] * (q1 - q0))


def _statically_fine(model, q0, q1, limits: MotionLimits, samples: int = 17) -> bool:
    """Gravity within _GRAVITY_SHARE of the budget on the whole straight path q0 → q1, and no self-collision on it
    (the arm's own geometry, :class:`_SelfCollision`: a motion into itself would be blocked, not tracked)."""
    _, g = _gravity_along(model, q0, q1, samples)
    return bool(np.all(np.abs(g) <= _GRAVITY_SHARE * limits.torque_budget)) and _collision_free(model, q0, q1)


def _draw_pose(model, limits: MotionLimits, rng: np.random.Generator, previous=None, what: str = "pose") -> np.ndarray:
    lo, hi = limits.usable_lower, limits.usable_upper
    for _ in range(_MAX_TRIES):
        q = rng.uniform(lo, hi)
        if _statically_fine(model, q if previous is None else previous, q, limits):
            return q
    raise RobofdiError(
        f"motion design: found no {what} inside the usable ranges, clear of self-collision, where gravity uses less "
        f"than {_GRAVITY_SHARE:.0%} of torque_fraction × limit after {_MAX_TRIES} draws; raise 'torque_fraction'"
    )


def _speed_factors(speed, count: int, rng: np.random.Generator) -> np.ndarray:
    if isinstance(speed, str) and speed in SPEEDS:
        lo, hi = SPEEDS[speed]
        return rng.uniform(lo, hi, count)
    number = isinstance(speed, (int, float, np.floating, np.integer)) and not isinstance(speed, bool)
    if not (number and np.isfinite(speed) and speed >= 1.0):
        raise RobofdiError(
            f"random_point_to_point: field 'speed' must be one of {sorted(SPEEDS)} or a number >= 1, got {speed!r}")
    return np.full(count, float(speed))


def _with_dwell(waypoints, durations, dwell: float) -> Sequence:
    """Quintic segments through the waypoints, each followed by a rest of ``dwell`` s (none if 0)."""
    poses, times = [waypoints[0]], []
    for wp, d in zip(waypoints[1:], durations):
        poses.append(wp)
        times.append(d)
        if dwell > 0:
            poses.append(wp)
            times.append(dwell)
    return Sequence.through(poses, times)


def random_point_to_point(model, limits: MotionLimits, seed, n_segments: int = 1, *, dwell: float = 0.25,
                          speed="normal", q_start=None, floor: float = 0.5) -> Sequence:
    """A seeded smooth motion: quintic segments through ``n_segments`` random waypoints drawn uniformly inside
    the usable ranges (range margin kept clear), from a random start pose (or ``q_start`` [rad]).

    Each segment lasts :func:`fit_duration` × a factor drawn from ``SPEEDS[speed]`` ("fast" = at the torque
    budget, "normal", "slow"; or a fixed factor >= 1), rounded up to the millisecond; the arm rests ``dwell`` s
    [>= 0] at every waypoint reached. seed: an int >= 0 (stream ``robofdi.seeding.rng(seed, "motion")``),
    a SeedSequence, or a numpy Generator. The same seed gives the same motion.
    """
    limits = _check_model(model, limits)
    if isinstance(n_segments, bool) or int(n_segments) != n_segments or n_segments < 1:
        raise RobofdiError(f"random_point_to_point: field 'n_segments' must be an integer >= 1, got {n_segments!r}")
    if not (np.isfinite(dwell) and dwell >= 0):
        raise RobofdiError(f"random_point_to_point: field 'dwell' must be >= 0 s, got {dwell!r}")
    rng = _generator(seed)
    factors = _speed_factors(speed, int(n_segments), rng)
    if q_start is None:
        start = _draw_pose(model, limits, rng, what="start pose")
    else:
        start = _check_pose("random_point_to_point: field 'q_start'", q_start, limits)
    waypoints, durations = [start], []
    for k in range(int(n_segments)):
        nxt = _draw_pose(model, limits, rng, previous=waypoints[-1], what="waypoint")
        base = fit_duration(model, waypoints[-1], nxt, limits, floor=floor)
        durations.append(float(np.ceil(base * factors[k] * 1000.0 - 1e-6) / 1000.0))
        waypoints.append(nxt)
    return _with_dwell(waypoints, durations, dwell)


# ----------------------------------------------------------------------------------------------------------
# Worst-case calibration motions (Caccavale & Villani Sec. 6)
# ----------------------------------------------------------------------------------------------------------
def _low_velocity(model, limits: MotionLimits, rng, total: float, fraction: float) -> Sequence:
    """Every joint sweeps ``fraction`` of its usable range and back, in ``total`` s, around a feasible centre."""
    lo, hi = limits.usable_lower, limits.usable_upper
    half = 0.5 * fraction * (hi - lo)
    signs = rng.choice([-1.0, 1.0], limits.n)
    centre = 0.5 * (lo + hi)
    for attempt in range(_MAX_TRIES):
        if attempt:
            centre = rng.uniform(lo + half, hi - half)
        a, b = centre - signs * half, centre + signs * half
        if _statically_fine(model, a, b, limits, samples=33):
            break
    else:
        raise RobofdiError(
            "calibration_motions: found no low-velocity sweep clear of self-collision where gravity leaves torque for motion; "
            "lower 'sweep_fraction' or raise 'torque_fraction'"
        )
    need = fit_duration(model, a, b, limits, floor=1e-3)
    if total / 2 < need:
        raise RobofdiError(
            f"calibration_motions: field 'low_velocity_time' must be >= {2 * need:.3f} s for this arm, got {total}")
    return Sequence.through([a, b, a], [total / 2, total / 2])


def _far_pose(model, limits: MotionLimits, rng, chosen: list, candidates: int) -> np.ndarray:
    """Among random feasible candidates, the one farthest (mean range-normalised |Δq|) from the chosen poses;
    the first pose is the one farthest from the middle of the ranges."""
    lo, hi = limits.usable_lower, limits.usable_upper
    width = hi - lo
    refs = chosen or [0.5 * (lo + hi)]
    best, best_d = None, -1.0
    for _ in range(candidates):
        q = rng.uniform(lo, hi)
        if not _statically_fine(model, chosen[-1] if chosen else q, q, limits):
            continue
        d = min(float(np.mean(np.abs(q - r) / width)) for r in refs)
        if d > best_d:
            best, best_d = q, d
    if best is None:
        best = _draw_pose(model, limits, rng, previous=chosen[-1] if chosen else None, what="high-acceleration waypoint")
    return best


def _collides_at_all(model) -> bool:
    path, names = getattr(model, "path", None), getattr(model, "joint_names", None)
    return path is not None and names is not None and _self_collision(str(path), tuple(names)).active


def _reach(model, limits: MotionLimits, centre: np.ndarray, i: int, end: float) -> np.ndarray:
    """The pose farthest from ``centre`` towards joint i's ``end`` (joint i alone, in tenths of the way) whose
    path from the centre is statically fine (:func:`_statically_fine`)."""
    best = centre.copy()
    for f in np.linspace(0.1, 1.0, 10):
        q = centre.copy()
        q[i] = centre[i] + f * (end - centre[i])
        if not _statically_fine(model, centre, q, limits, samples=9):
            break
        best = q
    return best


def _partial_sweeps(model, limits: MotionLimits, rng, least: float = 0.5, tries: int = 400):
    """Fallback of :func:`_top_speed` when no centre lets every joint sweep its whole usable range (self-collision
    or gravity in the way): from the first centre (the middle of the ranges, then random ones) where every joint
    can sweep at least ``least`` of its usable width, each joint sweeps as far as it can each way (in tenths)."""
    lo, hi = limits.usable_lower, limits.usable_upper
    centre = 0.5 * (lo + hi)
    for attempt in range(tries):
        if attempt:
            centre = rng.uniform(lo, hi)
        if not _statically_fine(model, centre, centre, limits):
            continue
        sweeps = [(_reach(model, limits, centre, i, lo[i]), _reach(model, limits, centre, i, hi[i])) for i in range(limits.n)]
        if all(b[i] - a[i] >= least * (hi[i] - lo[i]) for i, (a, b) in enumerate(sweeps)):
            return centre, sweeps
    raise RobofdiError(f"calibration_motions: found no centre pose from which every joint can sweep {least:.0%} of its "
                       f"usable range clear of self-collision with gravity leaving torque for motion after {tries} "
                       "draws; raise 'torque_fraction' or lower 'range_margin'")


def _top_speed(model, limits: MotionLimits, rng, factor: float) -> Sequence:
    """Each joint in turn sweeps its whole usable range and back, alone, at ``factor`` × the shortest admissible
    duration, from a centre pose where gravity leaves torque for the motion (the others hold it) and nothing
    collides; if no such centre is found (an arm folding into itself), each joint sweeps as much of its range as
    it can, at least half (:func:`_partial_sweeps`)."""
    lo, hi = limits.usable_lower, limits.usable_upper
    centre = 0.5 * (lo + hi)

    def ends(c, i):
        a, b = c.copy(), c.copy()
        a[i], b[i] = lo[i], hi[i]
        return a, b

    tries = _MAX_TRIES if not _collides_at_all(model) else _MAX_TRIES // 20
    for attempt in range(tries):
        if attempt:
            centre = rng.uniform(lo, hi)
        if all(_statically_fine(model, *ends(centre, i), limits, samples=33) for i in range(limits.n)):
            sweeps = [ends(centre, i) for i in range(limits.n)]
            break
    else:
        centre, sweeps = _partial_sweeps(model, limits, rng)
    path = [centre]
    for a, b in sweeps:
        path += [a, b, centre]
    durations = [float(np.ceil(factor * fit_duration(model, p, q, limits) * 1000.0 - 1e-6) / 1000.0)
                 for p, q in zip(path[:-1], path[1:])]
    return Sequence.through(path, durations)


def calibration_motions(model, limits: MotionLimits, seed, *, low_velocity_time: float = 16.0,
                        sweep_fraction: float = 1 / 3, waypoints: int = 3, n_random: int = 0,
                        random_segments: int = 3, top_speed: bool = False) -> dict[str, Sequence]:
    """The worst-case fault-free motions of Caccavale & Villani Sec. 6, derived from the ranges and limits.

    "low_velocity": every joint sweeps ``sweep_fraction`` of its usable range there and back, slowly, in
    ``low_velocity_time`` s in total (raises if that is too short for the torque budget).
    "high_acceleration": through ``waypoints`` (>= 2) far-apart random poses and back along the same path, every
    segment at the shortest admissible duration (:func:`fit_duration`: at the torque budget).
    "random_1" … "random_<n_random>": :func:`random_point_to_point` motions of ``random_segments`` segments,
    to cover the workspace.
    "top_speed" (with ``top_speed``): every joint alone sweeps its whole usable range and back at the fastest
    "normal" speed factor — a joint's top speed grows with its displacement, so this covers the speeds any
    "normal" random motion reaches (speed-dependent scales are then interpolated, not extrapolated).
    Each motion starts at rest at its ``start_pose``; seed (an int >= 0 or a
    SeedSequence) gives each motion its own stream ``rng(seed, "motion", "calibration", <name>)``.
    """
    limits = _check_model(model, limits)
    if not (np.isfinite(low_velocity_time) and low_velocity_time > 0):
        raise RobofdiError(f"calibration_motions: field 'low_velocity_time' must be > 0 s, got {low_velocity_time!r}")
    if not (np.isfinite(sweep_fraction) and 0 < sweep_fraction <= 1):
        raise RobofdiError(f"calibration_motions: field 'sweep_fraction' must be in (0, 1], got {sweep_fraction!r}")
    for name, value, least in (("waypoints", waypoints, 2), ("n_random", n_random, 0), ("random_segments", random_segments, 1)):
        if isinstance(value, bool) or int(value) != value or value < least:
            raise RobofdiError(f"calibration_motions: field {name!r} must be an integer >= {least}, got {value!r}")
    if isinstance(seed, np.random.Generator):
        raise RobofdiError("calibration_motions: field 'seed' must be an integer >= 0 or a SeedSequence (one stream per motion)")
    motions = {"low_velocity": _low_velocity(model, limits, _generator(seed, "calibration", "low_velocity"),
                                             float(low_velocity_time), float(sweep_fraction))}
    rng = _generator(seed, "calibration", "high_acceleration")
    chosen: list = []
    for _ in range(int(waypoints)):
        chosen.append(_far_pose(model, limits, rng, chosen, candidates=48))
    path = chosen + chosen[-2::-1]
    durations = [fit_duration(model, a, b, limits) for a, b in zip(path[:-1], path[1:])]
    motions["high_acceleration"] = Sequence.through(path, durations)
    for i in range(1, int(n_random) + 1):
        motions[f"random_{i}"] = random_point_to_point(
            model, limits, _generator(seed, "calibration", f"random_{i}"), int(random_segments))
    if top_speed:
        motions["top_speed"] = _top_speed(model, limits, _generator(seed, "calibration", "top_speed"),
                                          SPEEDS["normal"][0])
    return motions
