"""The consistency residual: what a robotics engineer deploys on an arm, beyond the book's schemes.

Two structurally separated residual sets, each normalised by its own fault-free scale (dimensionless, ≤ 1 on
the design runs):

* ``joint<i>`` — dynamic consistency: the generalised-momentum residual (De Luca & Mattone 2003, eq. (10)) with
  friction and the payload the arm carries identified from fault-free runs
  (:func:`~robofdi.observers.momentum.identify_friction_and_load`: a tool or load the robot file lacks is a
  pose-dependent torque no friction term or bound feature follows), divided by an operating-point bound
  (:mod:`robofdi.decision.envelope`). It estimates the unmodelled joint torque, so an actuator fault raises
  exactly its own joint, and no estimation runs inside it that could absorb a slow fault.
  The bound's torque feature is the smaller of the command ū and the torque the motion took, ū + r (the
  command and the residual's estimate of what else acted, at the previous sample), so that no actuator fault
  inflates the bound that should reveal it: the command grows as the controller answers a slow fault (on
  robosuite's iiwa joint 7, |τ| weighs 0.3: an 11 N·m fault raised its own bound by 3.5 N·m), and ū + r grows
  with an abrupt one before the controller answers it (the median abrupt delay went from 1.5 to 3–3.5 samples
  on panda and arm7).
* ``joint<i>_kin`` — kinematic consistency between the joint's position and velocity sensors
  (:mod:`robofdi.observers.kinematic`), which no actuator fault can raise. But for the onset: a torque step at a
  time s before the sample instant makes the trapezoid's increment e_k = −(T/2 + τ_s − s/2) ν_k at that sample
  alone, as much as a reading's step of ν_k where s is small, and the windows would hold it for their length (a
  hard-over on arm6's wrist: e = 143 µrad, its 0.1 s window 1.3× its threshold for 0.1 s, the fault named a
  velocity sensor). So at the onset of a velocity change, the first sample in :data:`STEP_HOLD` whose |ν_k|
  exceeds its fault-free bound, the windows sum e_k shrunk towards 0 by up to −(T/2 + τ_s) ν_k: a reading's step
  of ν_k then shows in the windows from the next sample on (−T ν_k a sample), a torque step not at all. Only the
  onset: a noisy velocity reading makes such a ν and such an e at every spike, and its later spikes are its
  evidence (a first version at every sample called a velocity-noise fault an actuator's). The rows' ``e`` and the
  step rows see e_k as it is.
* ``joint<i>_step`` — the velocity innovation ν_k [rad/s]: the velocity step on joint i alone that best explains
  the torque impulse w_k = (r_k − r_{k−1}) / K_O, the part of the measured momentum change the dynamics cannot
  explain (the momentum observer's one-step prediction error, r_k − r_{k−1} = K_O (p_k − p_{k−1} −
  T (ū − β − r_{k−1}))): ν_i = M_iᵀ W w / M_iᵀ W M_i (:meth:`ConsistencyResidual.velocity_innovation`). A
  velocity-sensor step of b on joint i gives w = M_i b, so ν_i = b (other joints' rows see the inertial
  coupling's share of it); a drifting or offset encoder gives none (the true velocity is
  untouched), except that a large encoder step moves M(q) q̇ at once, and the observer and the controller answer
  it over the next samples (a 30 mrad step changes the gravity torque): from a sample whose kinematic increment
  is more than a velocity step of ν can make (twice (T/2 + τ_s)|ν|, plus its fault-free scale), and changed by
  more than the last two samples' ν can make, ν is not counted for :data:`STEP_HOLD`. A velocity-sensor step
  passes the test at its onset (ν = b explains e_k) and after it (the increment persists at −T b), and the held
  peak keeps that sample: the row is the peak of |ν| over :data:`STEP_HOLD`, over its fault-free bound at the
  joint's speed (the step scale, c₀ + c₁ |q̇_i|: the innovation grows with speed). ν counts only where the
  kinematic increments do not refute a reading's step of it: such a step moves e_k by −(T/2 + τ_s) ν at once,
  and where e_k moved from e_{k−1} by more than half of that away from it (plus the noise of such a move, learnt),
  the velocity change was real — a torque, which is the dynamic row's to judge (a fault-free torque impulse the
  model lacks raised robosuite kinova3's base step row to 1.09× its threshold: ν = −38 mrad/s, where the
  increment moved 4.5 µrad, not the 76 µrad a reading's step makes).
* ``payload`` — the payload hypothesis (:mod:`robofdi.observers.payload`): how much of the normalised dynamic
  residuals a mass at the payload point explains beyond what one joint could,
  √max(0, (y·ρ)²/(y·y) − max_i ρ_i²), with ρ_i = r_i / bound_i and y_i = LP(Y)_i / bound_i the filtered torque per
  kg of a payload; its estimate is the least-squares mass δm̂ [kg]. It is 0 for an actuator fault (ρ along one
  joint) and grows with a payload change that loads several joints.

A velocity-gain error g that starts while its joint is slow steps the reading by only g·q̇: nothing agrees on it,
and its kinematic row alarms like an encoder drift's. As the joint moves, though, its increments follow the
velocity, e_k ≈ −T g q̇_k, which no drift does: the step row also holds the gain evidence of
:func:`_gain_evidence` — how much more of the increments over the last :data:`GAIN_WINDOW` a gain explains than an
encoder drift, each from its own onset, against what neither explains — over its fault-free scale
(``gain_scale``: :data:`GAIN_MARGIN` × its largest value on the design runs), counted only where the encoder's
increments do not jump (:data:`GAIN_JUMPS`: a noisy encoder is no gain error) and not once the encoder has
stepped (:data:`ENCODER_STEP`: an encoder scale error g steps the reading by g·q at its onset, and its increments
then follow the velocity as a velocity-gain error's do, with the opposite sign of g). It builds up over a few tens
of samples of motion after the first alarm, so the decision waits that long before it names an encoder
(:class:`~robofdi.decision.ThresholdDecision` ``defer``), and where the motion comes later still, evidence that
persists overturns the encoder hypothesis it refines.

A velocity reading that drifts by d has no step at onset either, and its kinematic row alarms like an encoder's.
Its increments e_k = −T d (t − t₀) grow steadily away from zero, which no encoder drift's (constant) or offset's
(a spike, or falling as it rises to its value) do: the step row also holds the trend evidence of
:func:`_trend_evidence` — the smallest change of the increments' mean between four consecutive
:data:`TREND_WINDOW` windows, where all three move away from zero, over the noise of a mean — over its fault-free
scale (``trend_scale``, :data:`TREND_MARGIN` × its largest value on the design runs). It counts the same
samples as the gain evidence, and none once the encoder has stepped. It needs about four windows of motion
after the onset, so the first call is the encoder and the decision overturns it.

A frozen velocity sensor (its reading held) has no step at onset, so ν says nothing; the kinematic row alarms as
the joint moves on, and alone it would call it an encoder fault. A drive's velocity estimate carries noise and
never repeats: the step row also holds the run of consecutive samples whose velocity reading did not change
(|Δq̇| ≤ :data:`FROZEN_CHANGE`), over :data:`FROZEN_SAMPLES` — the stuck-value check of sensor validation. On
fault-free data with noise it is 0; with noise-free sensors calibration sees the runs and the threshold rises.

A position step smaller than the windows' scales (a few encoder counts) shows only in the single-sample kinematic
term, for one sample: such a sample — one whose increment is more than a velocity step of ν can make, the test
above — is held in ``joint<i>_kin`` for :data:`STEP_HOLD`, so that the step persists long enough to be
isolated. The test is what keeps actuator faults out: an actuator step bends the trajectory within one sample,
which the trapezoid integrates with an error of the order of T·ν, and the same ν explains it.

Why three row sets: kinematically an encoder drift of rate ρ and a velocity bias of −ρ are identical (both add
a mean −T b to e_k), so only the dynamics can tell them apart, and only at the onset — a real velocity cannot
jump by b in one sample without a torque to accelerate it.

Signatures (the hypotheses): actuator fault on joint i raises ``joint<i>`` (the step rows may follow, through
M⁻¹, where the increments do not refute its ν); a position-sensor fault raises ``joint<i>_kin`` (the dynamic
rows may follow through gravity); a velocity-sensor fault raises ``joint<i>_kin`` and ``joint<i>_step`` (the
dynamic rows may follow: the measured velocity enters the momentum M(q) q̇; so may the other step rows, through
the inertial coupling); a payload change raises ``payload`` (the dynamic and step rows may follow), so by
parsimony it replaces the actuator faults of the joints it loads.

The step rows' alarm threshold carries the false-alarm rate, so it sits 1.4–3.5× above the fault-free bound of
|ν|; a velocity bias of 0.02–0.05 rad/s then left its step row below it and was isolated as an encoder drift. As
evidence, once a kinematic row has alarmed, a step row counts from its fault-free bound (1; ``discriminating``;
:class:`~robofdi.decision.ThresholdDecision`'s ``evidence``). A step below that bound still counts when the
kinematic increments confirm it: they measure the same velocity step with the encoder's noise, and ν decides
only which of a velocity step and an encoder change it is nearer (``_step_rows``' agreement).

Everything it needs from fault-free data is one :class:`ConsistencyDesign`, computed once per robot by
:func:`design_consistency` from a motion suite.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from robofdi.decision.envelope import LOW_SPEED_VELOCITY, REST_VELOCITY, design_envelope
from robofdi.errors import RobofdiError
from robofdi.jit import kernel
from robofdi.models.friction import JointFriction
from robofdi.models.manipulator import ManipulatorModel
from robofdi.observers.kinematic import (
    WINDOWS, KinematicConsistency, design_window_scales, identify_noise_walk, identify_ripple, identify_skew,
    kinematic_increments, window_reach,
)
from robofdi.observers.momentum import MomentumObserver, identify_friction_and_load
from robofdi.observers import payload as payload_module
from robofdi.observers.payload import PayloadRegressor
from robofdi.observers.residual import Residual, shared_measurement

__all__ = ["ConsistencyDesign", "ConsistencyResidual", "design_consistency", "DEFAULT_GAIN", "STEP_HOLD",
           "FROZEN_CHANGE", "FROZEN_SAMPLES", "GAIN_WINDOW", "GAIN_HORIZON",
           "GAIN_ONSET_RATIO", "GAIN_FLOOR", "GAIN_MARGIN", "GAIN_JUMPS",
           "ENCODER_STEP", "TREND_WINDOW", "TREND_FLOOR", "TREND_MARGIN", "PAYLOAD_SHARE"]

#: Momentum-observer bandwidth K_O [1/s] of the consistency residual: fast enough that an abrupt fault of twice
#: the smallest detectable size crosses its bound within a few 2 ms samples.
DEFAULT_GAIN = 150.0
#: How long [s] a one-sample step is held: a position step seen only by the single-sample kinematic term in
#: ``joint<i>_kin`` (the shortest kinematic window, over which larger steps stay in a window sum anyway), and the
#: velocity innovation in ``joint<i>_step`` (a velocity step the step row sees is large enough for the kinematic
#: row to alarm within a few samples: the hold only has to reach into the confirmation window).
STEP_HOLD = 0.1
#: Time constant [s] of the exponential window over which the step row compares a gain with a drift
#: (:func:`_step_rows`' gain evidence).
GAIN_WINDOW = 0.2
#: How far back [s] the gain evidence looks for the onset of a gain error or of an encoder drift
#: (:func:`_gain_statistic`): 2.5 windows, where the window's weight has fallen to 8 %.
GAIN_HORIZON = 0.5
#: The onsets the gain fit tries (:func:`_gain_statistic`): a gain error that started within a factor √2 of such an age
#: explains almost all of what it would from its own onset.
GAIN_ONSET_RATIO = math.sqrt(2.0)
#: The smallest fault-free gain evidence a design takes: a joint its runs never moved sets no smaller one.
GAIN_FLOOR = 0.1
#: The gain scale is this many times the design runs' largest gain evidence: unseen fault-free motion reached
#: 1.4× it on arm6 (three motions), an encoder drift that starts as its joint accelerates 1.2× (arm6) and 4×
#: (arm7 at 1–6 rad/s) when the drift was fitted as a level and a trend; fitted from its own onset
#: (:func:`_gain_statistic`), the 11 encoder drifts of an arm6 fast campaign reached 0.04–0.09, the fault-free level.
GAIN_MARGIN = 4.0
#: The largest share of a window's moving samples that may be position steps for the gain evidence to count: a
#: noisy encoder's increments jump at 94–100 % of its samples, and the few left are the small ones (a biased fit);
#: velocity-gain errors jumped at most 1 % (arm6 and arm7 campaigns).
GAIN_JUMPS = 0.2
#: An increment that stands out from both its neighbours by more than this many single-sample kinematic scales
#: (a one-sample spike: the encoder stepped) marks the joint's encoder as stepped for the rest of the run, and its
#: gain and trend evidence are 0 from then on: an encoder scale error g steps the reading by g·q at its onset and
#: then makes the increments a velocity-gain error makes. A velocity-gain error's increments −T g q̇ are large in
#: fast motion, but smooth: they do not spike.
ENCODER_STEP = 10.0
#: Length [s] of each of the four consecutive windows over which the step row looks for increments that grow
#: steadily away from zero (:func:`_trend_evidence`: a velocity-reading drift).
TREND_WINDOW = 0.25
#: The smallest fault-free trend evidence a design takes.
TREND_FLOOR = 0.1
#: The trend scale is this many times the design runs' largest trend evidence.
TREND_MARGIN = 4.0
#: A velocity reading that changed by at most this [rad/s or m/s] from the previous sample is a repeat (held).
FROZEN_CHANGE = 1e-9
#: Consecutive repeated velocity readings that make the step row 1 (its largest fault-free value, at least).
FROZEN_SAMPLES = 2
#: The smallest move scale a design takes (single-sample scales): one sample's own bound.
MOVE_FLOOR = 1.0
#: The share of the fault-free dynamic residual's energy beyond friction that a carried payload must explain to
#: enter the design (:func:`~robofdi.observers.momentum.identify_friction_and_load`): loads of 0.3, 0.5 and 1 kg on
#: robosuite's Panda explained 0.31–0.66, 0.63–0.83 and 0.90–0.95 of it; on 78 instances of nine arms carrying
#: none the fit found up to ±0.2 kg (the link masses' errors) that explained at most 0.12, and applied there it
#: moved the most marginal fault-free peak of a campaign across its threshold.
PAYLOAD_SHARE = 0.25

#: The rows of the gain evidence's state per joint (:func:`_gain_evidence`): its exponential sums Σw, Σw·e, Σw·x²,
#: Σw·x·e, Σw·e²; the last two velocity readings and the last position reading; the weights of the moving samples
#: that were position steps and of all of them; whether the encoder stepped (:data:`ENCODER_STEP`); the position
#: reading before the last; the samples counted; the statistic of :func:`_gain_statistic` at the last of them; from
#: row ``GAIN_RING`` on, the counted samples' e, then their x.
(SUM_W, SUM_E, SUM_XX, SUM_XE, SUM_EE, V_LAST, V_BEFORE, Q_LAST, JUMPED, MOVING, STEPPED, Q_BEFORE, COUNTED, FITTED,
 GAIN_RING) = range(15)


@dataclass(frozen=True, eq=False)
class ConsistencyDesign:
    """What :class:`ConsistencyResidual` learns once per robot: ``friction`` (identified), ``envelope`` (n, 4)
    bound coefficients of the dynamic rows, ``skew`` (n,) [s] and ``window_scales`` (n, len(windows), 3) of the
    kinematic rows (:func:`~robofdi.observers.kinematic.design_window_scales`), ``step_scale`` (n, 3) of the
    step rows: the tightest bound c₀ + c₁ s + c₂ σ of the fault-free |ν| over the joint's speed s and the spread
    σ(q) that the impulse noise gives ν at the pose (:meth:`step_bound`; c₀ [rad/s], c₁ and c₂ dimensionless), the
    observer ``gain`` K_O [1/s], sample time ``T`` [s], the
    kinematic ``windows`` [s], the operating envelope the kinematic scales were designed on, ``reach``
    (n, len(windows), 2) (:func:`~robofdi.observers.kinematic.window_reach`; None: unbounded), and the drives'
    nominal ripple orders (n, n_orders) [cycles/rad] whose aliasing the kinematic rows cover
    (:func:`~robofdi.observers.kinematic.ripple_orders`) with their identified per-sample errors
    ``ripple_amplitude`` (n, n_orders) [rad] and their torque-dependent parts ``ripple_load`` (n, n_orders)
    [rad/(N·m)] (:func:`~robofdi.observers.kinematic.identify_ripple`; None: none),
    ``impulse_scale`` (n,) [N·m·s], the fault-free spread of the torque impulse (r_k − r_{k−1}) / K_O per
    joint that weighs the velocity innovation (:meth:`ConsistencyResidual.velocity_innovation`; None: equal),
    and ``noise_walk`` (n,) [rad], the long-run standard deviation per sample of the kinematic increments' noise
    that floors the window scales (:func:`~robofdi.observers.kinematic.identify_noise_walk`; None: not identified),
    ``gain_scale`` (n,), the largest fault-free gain evidence per joint (dimensionless, :func:`_gain_evidence`;
    None: no gain evidence), ``trend_scale`` (n,), the same for the trend evidence (:func:`_trend_evidence`;
    None: none), and ``move_scale`` (n,), the largest fault-free change of the kinematic increment from one sample
    to the next, |e_k − e_{k−1}|, in single-sample scales (dimensionless): the noise the step rows' refutation
    allows (:func:`_step_rows`; None: 2, the two samples' bounds added), and ``repeat_scale`` (n,), the longest run
    of unchanged velocity readings on the design runs over :data:`FROZEN_SAMPLES` (dimensionless; 0 for a drive
    whose reading carries noise): where it is 0, a held reading is also the kinematic row's evidence (a frozen
    velocity sensor at rest; :func:`_step_rows`; None: never), and ``payload`` [kg], the mass at the payload point
    the arm carried on the design runs and the nominal model lacks (identified with the friction,
    :func:`~robofdi.observers.momentum.identify_friction_and_load`, where it explains at least
    :data:`PAYLOAD_SHARE` of the residual; its torque is the dynamic rows' model too; 0: none)."""

    friction: JointFriction
    envelope: np.ndarray
    skew: np.ndarray
    window_scales: np.ndarray
    step_scale: np.ndarray
    gain: float
    T: float
    windows: tuple = WINDOWS
    reach: np.ndarray | None = None
    ripple_orders: np.ndarray | None = None
    ripple_amplitude: np.ndarray | None = None
    ripple_load: np.ndarray | None = None
    impulse_scale: np.ndarray | None = None
    noise_walk: np.ndarray | None = None
    gain_scale: np.ndarray | None = None
    trend_scale: np.ndarray | None = None
    move_scale: np.ndarray | None = None
    repeat_scale: np.ndarray | None = None
    payload: float = 0.0

    #: The optional arrays of :meth:`arrays` (absent when None).
    OPTIONAL = ("reach", "ripple_orders", "ripple_amplitude", "ripple_load", "impulse_scale", "noise_walk",
                "gain_scale", "trend_scale", "move_scale", "repeat_scale")

    def step_bound(self, speed: np.ndarray, spread: np.ndarray) -> np.ndarray:
        """(n,) bound [rad/s] of the fault-free |ν| at joint speeds ``speed`` (n,) [rad/s] and the pose's ν spread
        ``spread`` (n,) [rad/s] (:meth:`ConsistencyResidual.velocity_innovation`): c₀ + c₁ |speed| + c₂ spread."""
        return self.step_scale[:, 0] + self.step_scale[:, 1] * np.abs(speed) + self.step_scale[:, 2] * spread

    @property
    def impulse_weight(self) -> np.ndarray:
        """(n,) W [1/(N·m·s)²], the inverse squares of ``impulse_scale`` (all 1 without it): the weights of the
        velocity innovation's fit (:meth:`ConsistencyResidual.velocity_innovation`)."""
        n = self.skew.shape[0]
        scale = np.ones(n) if self.impulse_scale is None else np.asarray(self.impulse_scale, dtype=float)
        return scale ** -2.0

    def spread(self, mass: np.ndarray) -> np.ndarray:
        """(n,) [rad/s] the ν spread at a pose of mass matrix ``mass`` (n, n): (M_jᵀ W M_j)^(−1/2)
        (:meth:`ConsistencyResidual.velocity_innovation`)."""
        return np.einsum("ij,i,ij->j", mass, self.impulse_weight, mass) ** -0.5

    def arrays(self) -> dict[str, np.ndarray]:
        """Flat arrays (for caching in an .npz); :meth:`from_arrays` inverts it."""
        f = self.friction
        out = {"friction": f.coefficients, "friction_shape": np.array([f.stribeck_velocity, f.smoothing]),
               "envelope": self.envelope, "skew": self.skew, "window_scales": self.window_scales,
               "step_scale": self.step_scale, "gain_T": np.array([self.gain, self.T]),
               "windows": np.array(self.windows, dtype=float), "payload": np.array([self.payload])}
        return out | {k: getattr(self, k) for k in self.OPTIONAL if getattr(self, k) is not None}

    @classmethod
    def from_arrays(cls, a: dict) -> ConsistencyDesign:
        shape = a["friction_shape"]
        optional = {k: np.asarray(a[k]) for k in cls.OPTIONAL if k in a}
        return cls(JointFriction.from_coefficients(a["friction"], float(shape[0]), float(shape[1])),
                   np.asarray(a["envelope"]), np.asarray(a["skew"]), np.asarray(a["window_scales"]),
                   np.asarray(a["step_scale"]), float(a["gain_T"][0]), float(a["gain_T"][1]),
                   tuple(float(w) for w in a["windows"]), **optional,
                   payload=float(np.asarray(a["payload"]).reshape(-1)[0]) if "payload" in a else 0.0)


class ConsistencyResidual:
    """Diagnoser (see the module docstring). Residual components ``joint<i>``, ``joint<i>_kin``,
    ``joint<i>_step`` and ``payload`` (dimensionless); estimates: actuator torque ``joint<i>`` [N·m] (level),
    position offset ``joint<i>_pos`` [rad] (increment), velocity bias ``joint<i>_vel`` [rad/s] (level) and the
    added payload ``payload`` [kg] (level)."""

    def __init__(self, model: ManipulatorModel, design: ConsistencyDesign):
        n = model.n
        for field, shape in (("envelope", (n, 4)), ("skew", (n,)), ("step_scale", (n, 3))):
            if np.shape(getattr(design, field)) != shape:
                raise RobofdiError(f"ConsistencyResidual: design field '{field}' has shape "
                                   f"{np.shape(getattr(design, field))}; expected {shape} for the model's {n} joints")
        self.model, self.design, self.n, self.T = model, design, n, design.T
        self._momentum = MomentumObserver(model, design.T, design.gain, design.friction)
        self._kinematic = KinematicConsistency(design.T, design.skew, design.window_scales, design.windows,
                                               design.reach, design.ripple_orders, design.ripple_amplitude,
                                               design.ripple_load)
        self._payload = PayloadRegressor(model, design.T, design.gain)
        if not np.isfinite(design.payload):
            raise RobofdiError(f"ConsistencyResidual: field 'payload' must be a finite mass [kg], got {design.payload!r}")
        self._carried = float(design.payload)
        scale = np.ones(n) if design.impulse_scale is None else np.asarray(design.impulse_scale, dtype=float)
        if scale.shape != (n,) or not np.all(np.isfinite(scale) & (scale > 0)):
            raise RobofdiError(f"ConsistencyResidual: field 'impulse_scale' must be {n} finite values > 0 [N·m·s], "
                               f"got {design.impulse_scale!r}")
        self._impulse_weight = design.impulse_weight
        self._a = design.gain * design.T
        self._hold = max(1, int(round(STEP_HOLD / design.T)))
        self._single = int(np.argmin(design.windows))       # the single-sample kinematic window
        self._gain_scale = (np.zeros(n) if design.gain_scale is None
                            else np.asarray(design.gain_scale, dtype=float))   # 0: no gain evidence
        self._gain_lambda = 1.0 - design.T / GAIN_WINDOW
        self._trend_scale = (np.zeros(n) if design.trend_scale is None
                             else np.asarray(design.trend_scale, dtype=float))  # 0: no trend evidence
        self._trend_samples = max(1, int(round(TREND_WINDOW / design.T)))
        self._move = np.full(n, 2.0) if design.move_scale is None else np.asarray(design.move_scale, dtype=float)
        if self._move.shape != (n,) or not np.all(np.isfinite(self._move) & (self._move > 0)):
            raise RobofdiError(f"ConsistencyResidual: field 'move_scale' must be {n} finite values > 0 "
                               f"(single-sample scales), got {design.move_scale!r}")
        repeat = np.full(n, np.inf) if design.repeat_scale is None else np.asarray(design.repeat_scale, dtype=float)
        if repeat.shape != (n,) or not np.all(repeat >= 0):
            raise RobofdiError(f"ConsistencyResidual: field 'repeat_scale' must be {n} values >= 0, got "
                               f"{design.repeat_scale!r}")
        self._held_kinematic = (repeat == 0).astype(float)      # 1: a held velocity reading is kinematic evidence too
        names = list(model.joint_names)
        self.inputs = names
        self.measurements = [f"{j}_pos" for j in names] + [f"{j}_vel" for j in names]
        self.components = names + [f"{j}_kin" for j in names] + [f"{j}_step" for j in names] + ["payload"]
        self.estimate_components = names + [f"{j}_pos" for j in names] + [f"{j}_vel" for j in names] + ["payload"]
        self.estimate_modes = ["level"] * n + ["increment"] * n + ["level"] * n + ["level"]
        #: The rows that tell hypotheses apart (velocity sensor or encoder; payload or actuator) once another row
        #: has alarmed: their evidence level is their largest fault-free value, not their false-alarm threshold
        #: (ThresholdDecision).
        self.discriminating = [f"{j}_step" for j in names] + ["payload"]
        self.kinematic = [f"{j}_kin" for j in names]       # rows scaled by a noise model, not by a learnt bound
        self.units = {"residual": ["1"] * (3 * n + 1), "estimate": ["N·m"] * n + ["rad"] * n + ["rad/s"] * n + ["kg"]}
        self.reset()

    def reset(self) -> None:
        self._momentum.reset()
        self._kinematic.reset()
        self._payload.reset()
        n = self.n
        self._started = False                   # a residual r_{k−1} is held (ν needs two samples)
        self._features = np.zeros((n, 4))       # LP of the dynamic rows' operating-point features φ
        # per joint: the last residual r_{k−1} [N·m], the last velocity reading [rad/s], the consecutive samples
        # with an unchanged velocity reading, the last sample whose |ν| exceeded its bound
        self._state = np.zeros((4, n))
        self._state[3] = -1e9
        # per joint, this sample's: ν [rad/s], its impulse-noise spread at the pose [rad/s], its fault-free bound
        # [rad/s], what a velocity change within the sample made of e_k [rad] (the onset; 0 elsewhere), and the
        # dynamic rows' operating-point bound [N·m] (:func:`_operating_point`)
        self._point = np.zeros((5, n))
        self._previous = np.zeros((3, self.n))  # the last sample's e [rad] and ν [rad/s], the e before it [rad]
        self._steps = np.zeros((self._hold, self.n))     # ring buffer of |ν| / scale (or agreement) over the hold
        self._jumps = np.zeros((self._hold, self.n))    # ring buffer of position-step ratios
        # the gain evidence's sums, the last readings, encoder stepped, its samples (_gain_evidence)
        self._gain_sums = np.zeros((gain_rows(self.T), self.n))
        self._gain_sums[Q_LAST] = self._gain_sums[Q_BEFORE] = np.nan
        self.gain_evidence = np.zeros(self.n)       # its last value (dimensionless)
        self._trend_ring = np.zeros((4 * self._trend_samples, self.n))  # the increments counted, sample k at k mod 4m
        self._trend_sums = np.zeros((4, self.n))    # their sums over the four windows, newest first
        self.trend_evidence = np.zeros(self.n)      # its last value (dimensionless)
        self._k = 0

    @property
    def innovation(self) -> np.ndarray:
        """(n,) ν of the last sample [rad/s] (:meth:`velocity_innovation`; 0 before the second); a view that the
        next sample overwrites."""
        return self._point[0]

    @property
    def spread(self) -> np.ndarray:
        """(n,) ν's impulse-noise spread at the last sample's pose [rad/s] (:meth:`velocity_innovation`); a view
        that the next sample overwrites."""
        return self._point[1]

    @property
    def outside_envelope(self) -> np.ndarray:
        """(n,) bool: the last sample was outside the operating envelope the kinematic scales were designed on
        (their tolerance was widened there, :class:`~robofdi.observers.kinematic.KinematicConsistency`)."""
        return self._kinematic.outside

    def bound(self) -> np.ndarray:
        """The operating-point bound of the dynamic rows at the last sample [N·m] (0 before the first)."""
        return self._point[4].copy()

    def velocity_innovation(self, mass: np.ndarray, r: np.ndarray) -> np.ndarray:
        """ν_k [rad/s] (module docstring) given M(q_k); 0 at the first sample. Joint j's entry is the velocity
        step on joint j alone that best explains the torque impulse w = (r_k − r_{k−1}) / K_O, which such a step
        makes M_j b (M_j: column j of M): ν_j = M_jᵀ W w / M_jᵀ W M_j, W = diag(impulse_scale)⁻² (the weighted
        least-squares fit of one joint's step; the generalised likelihood ratio's estimate under white impulse
        noise). Solving M ν = w for all joints at once (ν = M⁻¹ w) is exact for a step too, but near a
        singular M (robosuite's iiwa with joint 2 ≈ 0, where joints 1 and 3 are coaxial and their relative
        motion has almost no inertia) it amplifies every impulse along the weak direction: the fault-free
        |ν| of joint 1 reached 0.2 rad/s against 0.02 rad/s for the one-joint fit.

        Sets ``spread`` (n,) [rad/s], the standard deviation that impulse noise of spread impulse_scale gives
        ν_j at this pose, (M_jᵀ W M_j)^(−1/2): a base joint's inertia changes several-fold with the arm's
        reach, and with it the ν its impulse noise makes (sawyer's shoulder: 0.47–3.6 kg·m²)."""
        nu = np.empty(self.n)
        _velocity_innovation(np.asarray(mass, dtype=float), self._impulse_weight, np.asarray(r, dtype=float),
                             self._state[0], not self._started, self.design.gain, nu, self._point[1])
        self._state[0] = r
        self._started = True
        return nu

    def update(self, y: np.ndarray, u: np.ndarray) -> Residual:
        """y = [q; q̇](k), u = ū(k−1)."""
        n = self.n
        y = shared_measurement(y, 2 * n, "y")
        u = shared_measurement(u, n, "u")
        r = self._momentum.update(y, u).r
        q, v = y[:n], y[n:]
        load = self._payload.update(q, v)           # LP(Y) [N·m/kg]: the payload row's direction
        if self._carried:       # the residual of the model with the carried payload: r is linear in the model's mass
            r = r + self._carried * load
        design, point = self.design, self._point
        # ν, the features' low pass and the dynamic rows' bound, the step rows' bound and the onset of a velocity
        # change beyond it, whose increment is not the kinematic windows' to sum (module docstring, "onset")
        beyond = _operating_point(u, v, r, self._momentum.mass, self._impulse_weight, self._state, self._features,
                                  design.envelope, design.step_scale, design.skew, not self._started, self._k,
                                  self._hold, self._a, design.gain, self.T, REST_VELOCITY, LOW_SPEED_VELOCITY,
                                  FROZEN_CHANGE, point)
        self._started = True
        kin, e = self._kinematic.update(q, v, point[3] if beyond else None, u)
        z, estimate = np.empty(3 * n + 1), np.empty(3 * n + 1)
        _step_rows(r, point[0], kin, e, point[4], self._kinematic.scale, self._single, design.skew, self._move,
                   point[2], self._state[2], FROZEN_SAMPLES, self._steps, self._jumps,
                   self._previous, self._k % self._hold, (self._k - 1) % self._hold, self.T, z, estimate,
                   q, v, self._gain_sums, self._gain_lambda, self._gain_scale, self.gain_evidence,
                   self._trend_ring, self._trend_sums, self._k, self._trend_scale, self.trend_evidence,
                   load, self._held_kinematic)
        self._k += 1
        return Residual(z, estimate)

    def signatures(self):
        from robofdi.decision import Signature

        names = list(self.model.joint_names)
        dynamic, steps = frozenset(names), frozenset(f"{j}_step" for j in names)
        sigs = [Signature(j, frozenset([j]), steps) for j in names]
        sigs += [Signature(f"{j}_pos", frozenset([f"{j}_kin"]), dynamic) for j in names]
        sigs += [Signature(f"{j}_vel", frozenset([f"{j}_kin", f"{j}_step"]), dynamic | steps) for j in names]
        sigs.append(Signature("payload", frozenset(["payload"]), dynamic | steps))
        return sigs


@kernel
def _step_rows(r, innovation, kin, e, bound, scale, single, skew, move, step_bound, repeats, frozen_samples, steps, jumps,
               previous, row, previous_row, T, z, estimate, q, v, gain_sums, lam, gain_scale, gain,
               trend_ring, trend_sums, k, trend_scale, trend, regressor, held_kinematic):
    """The rows of :meth:`ConsistencyResidual.update` after its momentum and kinematic parts, joint by joint: the
    residual ``z`` and the ``estimate`` (the payload row and mass last, from the payload regressor ``regressor``
    (n,) [N·m/kg] over ``bound``, :func:`~robofdi.observers.payload.payload_evidence`); the step and jump ring
    buffers ``steps``/``jumps`` held at ``row``; ``previous`` (3, n) the last sample's e and ν and the e before
    it, updated.

    A position step is an increment more than a velocity step of ν can make: a step b in q̇_k adds −(T/2 + τ_s) b
    to e_k (:mod:`~robofdi.observers.kinematic`), so |e_k| > 2 (T/2 + |τ_s|) |ν| + the single-sample scale (a
    factor 2 for ν's own error) is a position step, held as |e_k| / scale. It clears the ν held from before it
    only if the increment also *changed* by more than the velocity steps of this and the last sample can make
    (twice the single-sample scale for the two samples' own errors): a velocity offset b adds −(T/2 + τ_s) b to
    e_k at its onset and −T b to every e after it, each more than its ν ≈ 0 explains, but the increment persists,
    so the onset's ν = b stays held.

    Agreement: a step b of the velocity reading at sample k moves e by −T b over samples k and k+1, −(T/2 + τ_s) b
    of it at k (a reading steps at a sample instant), and makes ν_k = b. One sample later, where e changed over
    the two samples by more than two fault-free samples can (twice the single-sample scale), its share at k is
    that of a reading's step (within the single-sample scale), and ν_k is nearer the step b̂ they imply than 0
    (|ν_k − b̂| < |b̂|/2: the likelihood ratio of a velocity step against an encoder change of the same size,
    under equal noise), the step row holds the change over twice the single-sample scale at sample k. The
    increments measure the step with the encoder's noise, ν with the dynamics' (2.5–4× more on arm6 and arm7),
    so a velocity step below the step row's fault-free bound is still told from an encoder drift, which makes no
    ν and starts anywhere within a sample (its share at k is arbitrary). Not while a position step is held: its
    increment returning looks like a step too. Nor where the encoder's reading stood still at samples k and k+1
    in motion (:func:`_reading_stopped`): a frozen encoder's e = −T q̇ is what a reading's step of q̇ would make,
    and near ν's noise the agreement test then errs; ν held at sample k is cleared there too (``gain_sums``'
    :data:`Q_BEFORE` keeps the reading before the last).

    Refutation: ν_k counts in the step row only where e_k − e_{k−1} is within |m|/2 + ``move`` single-sample
    scales of m = −(T/2 + τ_s) ν_k, what a reading's step of ν_k would have made of it; a real velocity change
    (a torque) leaves the increments near 0 and is the dynamic row's. ``move`` (n,) is the largest fault-free
    |e_k − e_{k−1}| in single-sample scales (``ConsistencyDesign.move_scale``): the noise of the change itself,
    not the two samples' bounds added (which let a torque ringing at the sample rate on sawyer's base count
    as a reading's step: the increments moved 6.6 µrad where a step would have moved them 53).

    Evidence of a velocity-sensor fault that made no step: the gain evidence (:func:`_gain_evidence`) and the
    trend evidence (:func:`_trend_evidence`), over their scales, both 0 once e_{k−1} stood out from e_{k−2} and
    e_k by more than :data:`ENCODER_STEP` single-sample scales on both sides (the encoder stepped; ``gain_sums``'
    :data:`STEPPED`).

    A held velocity reading (``repeats`` over ``frozen_samples``) is the step row's evidence and, where
    ``held_kinematic`` is 1 (a drive whose fault-free reading never repeats: ``ConsistencyDesign.repeat_scale``),
    the kinematic row's too: a velocity sensor frozen while its joint rests leaves the increments as they were,
    and the velocity-sensor hypothesis needs both rows."""
    n, hold = r.shape[0], steps.shape[0]
    for i in range(n):
        single_scale = scale[i, single]
        increment = abs(e[i])
        reach = 2 * (T / 2 + abs(skew[i]))
        position_step = increment > reach * abs(innovation[i]) + single_scale
        moved = e[i] - previous[0, i]       # the increment's change since the last sample
        changed = abs(moved) > reach * (abs(innovation[i]) + abs(previous[1, i])) + 2 * single_scale
        span = e[i] - previous[2, i]        # a velocity-reading step at the last sample: −T b (docstring)
        rise, fall = previous[0, i] - previous[2, i], previous[0, i] - e[i]     # the last increment stood out
        spiked = rise * fall > 0 and min(abs(rise), abs(fall)) > ENCODER_STEP * single_scale   # (ENCODER_STEP)
        # the encoder's reading stood still at the last sample and this one in motion (a frozen encoder, docstring):
        # no velocity step at the last sample, neither agreed nor by its ν
        stopped = _reading_stopped(q[i], gain_sums[Q_LAST, i], gain_sums[Q_BEFORE, i], v[i], gain_sums[V_LAST, i],
                                   gain_sums[V_BEFORE, i],
                                   T, single_scale)
        if stopped:
            steps[previous_row, i] = 0.0
        if abs(span) > 2 * single_scale:
            share = previous[0, i] - previous[2, i] - (T / 2 + skew[i]) / T * span    # its sample's share, ≈ 0
            implied = -span / T
            held_step = 0.0         # a position step held from before this sample (its increments return)
            for h in range(hold):
                if h != row and jumps[h, i] > held_step:
                    held_step = jumps[h, i]
            agreed = abs(span) / (2 * single_scale)
            if held_step == 0 and not stopped and abs(share) < single_scale \
                    and abs(previous[1, i] - implied) < abs(implied) / 2 and agreed > steps[previous_row, i]:
                steps[previous_row, i] = agreed
        previous[2, i] = previous[0, i]
        previous[0, i], previous[1, i] = e[i], innovation[i]
        if position_step and changed:       # no ν held from before the step but the previous sample's (see update)
            keep = steps[previous_row, i]
            for h in range(hold):
                steps[h, i] = 0.0
            steps[previous_row, i] = keep
        jumps[row, i] = increment / single_scale if position_step else 0.0
        jump = jumps[0, i]
        for h in range(1, hold):
            if jumps[h, i] > jump or jumps[h, i] != jumps[h, i]:
                jump = jumps[h, i]
        # refuted: the increment did not move by the −(T/2 + τ_s) ν a reading's step of ν makes (docstring)
        made = -(T / 2 + skew[i]) * innovation[i]
        refuted = abs(moved - made) > abs(made) / 2 + move[i] * single_scale
        steps[row, i] = 0.0 if jump > 0 or refuted else abs(innovation[i]) / step_bound[i]
        step = steps[0, i]
        for h in range(1, hold):
            if steps[h, i] > step or steps[h, i] != steps[h, i]:
                step = steps[h, i]
        # the reading two samples back: e_k holds the noise of v_k and v_{k−1}, which would explain itself
        # not at a position step (an offset's one-sample spike) nor where the encoder repeated its reading (held,
        # e = −T q̇ follows the velocity exactly: a frozen encoder; at rest the reading carries no gain anyway);
        # the share of moving samples that were position steps is kept (JUMPED, MOVING)
        reading_moved = not abs(q[i] - gain_sums[Q_LAST, i]) <= FROZEN_CHANGE       # a held reading's last bits may move
        jumped = position_step and changed
        if reading_moved:
            gain_sums[JUMPED, i] = lam * gain_sums[JUMPED, i] + (1.0 if jumped else 0.0)
            gain_sums[MOVING, i] = lam * gain_sums[MOVING, i] + 1.0
        if spiked:
            gain_sums[STEPPED, i] = 1.0     # the encoder stepped: what follows is no evidence of a velocity gain
        gain[i] = _gain_evidence(gain_sums, i, e[i], T * gain_sums[V_BEFORE, i], reading_moved and not jumped,
                                 lam, single_scale)
        trend[i] = _trend_evidence(trend_ring, trend_sums, k, i, e[i] if reading_moved and not jumped else 0.0,
                                   single_scale)
        if gain_sums[STEPPED, i] > 0:
            gain[i] = 0.0
            trend[i] = 0.0
        gain_sums[V_BEFORE, i], gain_sums[V_LAST, i] = gain_sums[V_LAST, i], v[i]
        gain_sums[Q_BEFORE, i], gain_sums[Q_LAST, i] = gain_sums[Q_LAST, i], q[i]
        if gain_scale[i] > 0 and gain[i] / gain_scale[i] > step:
            step = gain[i] / gain_scale[i]
        if trend_scale[i] > 0 and trend[i] / trend_scale[i] > step:
            step = trend[i] / trend_scale[i]
        held = repeats[i] / frozen_samples
        z[i] = r[i] / bound[i]
        z[n + i] = jump if jump > kin[i] or jump != jump else kin[i]
        if held_kinematic[i] > 0 and held > z[n + i]:
            z[n + i] = held
        z[2 * n + i] = held if held > step or held != held else step
        estimate[i], estimate[n + i], estimate[2 * n + i] = r[i], e[i], -e[i] / T
    evidence, mass = payload_module._payload_evidence(z[:n], regressor / bound)     # by its module: interpreted()
    z[3 * n], estimate[3 * n] = evidence, mass


@kernel
def _reading_stopped(q, q_last, q_before, v, v_last, v_before, T, single_scale):
    """Whether the encoder's readings q_before, q_last, q (samples k−1, k, k+1) stood still while the three velocity
    readings say the joint moved by more than ``single_scale`` (the increments' fault-free single-sample scale,
    which a quantised encoder's count exceeds) in a sample: a frozen encoder. Not a joint at rest, nor a velocity
    step from rest (the reading before it ≈ 0), nor a reading that stands still for one sample as the joint
    reverses (it moves again at k+1)."""
    return abs(q - q_last) <= FROZEN_CHANGE and abs(q_last - q_before) <= FROZEN_CHANGE \
        and T * min(abs(v), abs(v_last), abs(v_before)) > single_scale


@kernel
def _velocity_innovation(mass, weight, r, r_prev, first, gain, innovation, spread):
    """ν (0 at the ``first`` sample) and its spread into ``innovation`` and ``spread`` (n,), joint by joint
    (:meth:`ConsistencyResidual.velocity_innovation`): with w = (r − r_prev) / K_O and W = diag(``weight``),
    ν_j = M_jᵀ W w / M_jᵀ W M_j and spread_j = (M_jᵀ W M_j)^(−1/2)."""
    n = r.shape[0]
    for j in range(n):
        norm, fit = 0.0, 0.0
        for i in range(n):
            weighted = weight[i] * mass[i, j]
            norm += weighted * mass[i, j]
            fit += weighted * (r[i] - r_prev[i])
        spread[j] = norm ** -0.5
        innovation[j] = 0.0 if first else fit / norm / gain


@kernel
def _dynamic_bound(features, envelope, out):
    """The dynamic rows' operating-point bound max(c_iᵀ LP(φ_i), 1e-12) [N·m] into ``out`` (n,)
    (:mod:`robofdi.decision.envelope`)."""
    for i in range(out.shape[0]):
        b = 0.0
        for f in range(features.shape[1]):
            b += features[i, f] * envelope[i, f]
        out[i] = b if b > 1e-12 else 1e-12


@kernel
def _operating_point(u, v, r, mass, weight, state, features, envelope, step_scale, skew, first, k, hold, a, gain, T,
                     rest, low_speed, change, point):
    """The first part of :meth:`ConsistencyResidual.update`, joint by joint; True where some |ν| exceeds its
    bound. ``state`` (4, n): the last residual and velocity reading, the repeated readings, the last sample
    beyond the bound (updated); ``features`` (n, 4): their low pass LP(φ), updated with the torque the motion took
    over (k−1, k] — the smaller of the command ū and ū + r_{k−1} (the command and what else acted) — and the
    last velocity reading (at the ``first`` sample φ(0, q̇_k) as it is); ``point`` (5, n) out: ν, its spread, its
    bound c₀ + c₁ |q̇| + c₂ spread at the mean speed of the two readings (:meth:`ConsistencyDesign.step_bound`),
    the onset's share of e_k, −(T/2 + τ_s) ν at the first sample beyond the bound in ``hold`` samples (0
    elsewhere), and the dynamic rows' bound (:func:`_dynamic_bound`)."""
    r_prev, v_prev, repeats, last = state[0], state[1], state[2], state[3]
    innovation, spread, bound, explained = point[0], point[1], point[2], point[3]
    _velocity_innovation(mass, weight, r, r_prev, first, gain, innovation, spread)
    b = 1.0 - a
    beyond = False
    for i in range(v.shape[0]):
        if first:
            x, y = v[i] / rest, v[i] / low_speed
            features[i, 0], features[i, 1] = 1.0, 0.0
            features[i, 2], features[i, 3] = math.exp(-(x * x)), math.exp(-(y * y))
            speed = abs(v[i])
        else:
            needed = u[i] + r_prev[i]
            torque = needed if abs(needed) < abs(u[i]) else u[i]
            x, y = v_prev[i] / rest, v_prev[i] / low_speed
            features[i, 0] = b * features[i, 0] + a * 1.0
            features[i, 1] = b * features[i, 1] + a * abs(torque)
            features[i, 2] = b * features[i, 2] + a * math.exp(-(x * x))
            features[i, 3] = b * features[i, 3] + a * math.exp(-(y * y))
            repeats[i] = repeats[i] + 1.0 if abs(v[i] - v_prev[i]) <= change else 0.0
            speed = (abs(v[i]) + abs(v_prev[i])) / 2
        bound[i] = step_scale[i, 0] + step_scale[i, 1] * speed + step_scale[i, 2] * spread[i]
        explained[i] = 0.0
        if abs(innovation[i]) > bound[i]:
            beyond = True
            if k - last[i] > hold:
                explained[i] = -(T / 2 + skew[i]) * innovation[i]
            last[i] = k
        r_prev[i], v_prev[i] = r[i], v[i]
    _dynamic_bound(features, envelope, point[4])
    return beyond


def gain_rows(T: float) -> int:
    """Rows of the gain evidence's state per joint at sample time ``T`` [s] (:func:`_gain_evidence`): the
    :data:`GAIN_RING` rows of sums and readings, then the increments and the regressors of the last
    :data:`GAIN_HORIZON` of counted samples."""
    return GAIN_RING + 2 * max(2, int(round(GAIN_HORIZON / T)))


@kernel
def _gain_evidence(sums, i, e, x, add, lam, floor):
    """The gain evidence of joint i (dimensionless): how much more of the kinematic increments e [rad] a
    velocity-gain error explains (e ∝ x = T q̇, the reading two samples back) than an encoder drift, each from its
    own onset, against what neither explains and at least the fault-free single-sample scale ``floor`` [rad]:
    √(max(0, SS_gain − SS_drift) / (Σw e² − max(SS_gain, SS_drift) + Σw floor²)), with SS the explained sums of
    squares of weighted least-squares fits over an exponential window of weight λ per sample
    (:func:`_gain_statistic`) — a likelihood ratio's statistic, so a noisier sensor raises no evidence by its noise
    alone. ``sums`` (:func:`gain_rows`, n): the rows :data:`SUM_W` … :data:`GAIN_RING`, the sums and the last
    :data:`GAIN_HORIZON` of counted samples updated in place when ``add`` (see :func:`_step_rows`; sample c at row
    c mod their number). The statistic changes only with a counted sample: it is computed then and kept
    (:data:`FITTED`), and :func:`_gain_fit` gates it."""
    if not add:
        return _gain_fit(sums, i, lam, floor)
    sums[SUM_W, i] = lam * sums[SUM_W, i] + 1.0
    sums[SUM_E, i] = lam * sums[SUM_E, i] + e
    sums[SUM_XX, i] = lam * sums[SUM_XX, i] + x * x
    sums[SUM_XE, i] = lam * sums[SUM_XE, i] + x * e
    sums[SUM_EE, i] = lam * sums[SUM_EE, i] + e * e
    horizon = (sums.shape[0] - GAIN_RING) // 2
    at = int(sums[COUNTED, i]) % horizon
    sums[GAIN_RING + at, i] = e
    sums[GAIN_RING + horizon + at, i] = x
    sums[COUNTED, i] += 1.0
    sums[FITTED, i] = _gain_statistic(sums, i, lam, floor)
    return _gain_fit(sums, i, lam, floor)


@kernel
def _gain_fit(sums, i, lam, floor):
    """The gain evidence of joint i from its state: the kept statistic (:data:`FITTED`), 0 where more than
    :data:`GAIN_JUMPS` of the window's moving samples were position steps (the encoder, not the velocity, is what
    the increments show: the samples kept are its small increments). ``lam`` and ``floor``: those the statistic
    was computed with (:func:`_gain_evidence`)."""
    if sums[JUMPED, i] > GAIN_JUMPS * sums[MOVING, i]:
        return 0.0
    return sums[FITTED, i]


@kernel
def _gain_statistic(sums, i, lam, floor):
    """:func:`_gain_evidence`'s statistic from its state, 0 until the window holds half its weight. The gain error
    started a samples ago, a on a grid of ratio :data:`GAIN_ONSET_RATIO` (the increments before it ≈ 0), or before
    the window: SS_gain = max over the onsets of (Σ_{<a} w x e)² / Σ_{<a} w x². An encoder drift makes increments of
    one level from its onset on, and a drift that stops (an offset reached) another: SS_drift = max over every split
    a of the window into its newest a samples and the older ones of the two levels' fit, (Σ_{<a} w e)² / Σ_{<a} w +
    (Σ_{≥a} w e)² / Σ_{≥a} w, and the one level over the window. Every split, not a grid: a drift that started
    between two grid ages, on a joint that accelerates, leaves a misfit that the gain partly explains (a large
    encoder drift on arm6's wrist reached 2.3× the gain scale on a grid of ratio √2). The window's samples older
    than :data:`GAIN_HORIZON` stay in the older level. A drift model of a level and a trend instead (an earlier
    form) takes a gain error on a joint accelerating at a steady rate for a drift: its increments make a ramp (on an
    arm6 campaign, the evidence of four gain errors that started at rest came 52–520 ms after the first alarm; it
    comes 28–52 ms after it now)."""
    w, we, wxx, wxe, wee = sums[SUM_W, i], sums[SUM_E, i], sums[SUM_XX, i], sums[SUM_XE, i], sums[SUM_EE, i]
    if w < 0.5 / (1.0 - lam):       # half a window's weight: a fit to fewer samples explains anything
        return 0.0
    explained = wxe * wxe / wxx if wxx > 0 else 0.0
    drift = we * we / w
    horizon = (sums.shape[0] - GAIN_RING) // 2
    counted = int(sums[COUNTED, i])
    newest = (counted - 1) % horizon
    cw, ce, cxe, cxx, weight = 0.0, 0.0, 0.0, 0.0, 1.0
    onset = 2.0
    for a in range(min(counted, horizon)):      # the newest a + 1 samples
        at = (newest - a) % horizon
        ea, xa = sums[GAIN_RING + at, i], sums[GAIN_RING + horizon + at, i]
        cw += weight
        ce += weight * ea
        cxe += weight * xa * ea
        cxx += weight * xa * xa
        weight *= lam
        rest = w - cw
        if rest > 1e-9 * w:
            levels = ce * ce / cw + (we - ce) * (we - ce) / rest
            if levels > drift:
                drift = levels
        if a + 1 >= int(onset + 0.5):
            onset *= GAIN_ONSET_RATIO
            if cxx > 0 and cxe * cxe / cxx > explained:
                explained = cxe * cxe / cxx
    excess = explained - drift
    left = wee - (explained if explained > drift else drift)
    if excess <= 0:
        return 0.0
    return math.sqrt(excess / (left + w * floor * floor))


@kernel
def _trend_evidence(ring, sums, k, i, e, floor):
    """The trend evidence of joint i at sample k (dimensionless): how steadily its kinematic increments e [rad]
    grow away from zero over the last four windows of m = len(ring) / 4 samples. With A, B, C, D the windows'
    means, newest first, it is min(|A − B|, |B − C|, |C − D|) over the noise of a mean, ``floor`` / √m (``floor``:
    the single-sample scale [rad]), where the three differences and A have one sign, else 0. A velocity-reading
    drift d makes e = −T d (t − t₀), a ramp (equal differences, away from zero); an encoder drift or a velocity
    bias a constant (after its onset step has passed through the windows, at most two of the differences move);
    an encoder offset that rises to its value makes |e| fall. ``ring`` (4m, n) holds the increments counted (the
    caller passes 0 where they say nothing of the velocity), ``sums`` (4, n) their sums over the four windows,
    both updated in place. 0 until the windows have filled."""
    m = ring.shape[0] // 4
    at = k % ring.shape[0]
    for w in range(4):          # the sample leaving window w enters window w + 1
        leaving = ring[(at - (w + 1) * m) % ring.shape[0], i]
        sums[w, i] += (e if w == 0 else ring[(at - w * m) % ring.shape[0], i]) - leaving
    ring[at, i] = e
    if k + 1 < ring.shape[0]:
        return 0.0
    a, b, c, d = sums[0, i], sums[1, i], sums[2, i], sums[3, i]
    d1, d2, d3 = a - b, b - c, c - d
    if a > 0:
        if d1 <= 0 or d2 <= 0 or d3 <= 0:
            return 0.0
    elif a < 0:
        if d1 >= 0 or d2 >= 0 or d3 >= 0:
            return 0.0
    else:
        return 0.0
    smallest = min(abs(d1), abs(d2), abs(d3)) / m
    return smallest / (floor / math.sqrt(m))


# The batch forms of the kernels above (robofdi.lockstep): on every run's rows, one call a sample for all runs.
@kernel
def _operating_point_each(Y, U, R, mass, weight, state, features, envelope, step_scale, skew, first, k, hold, a, gain, T,
                          rest, low_speed, point):
    """The operating point per run (``point`` (runs, 5, n); Y (runs, 2n) the states [q; q̇]; the per-run arrays
    (≥ runs, …)): _operating_point."""
    n = R.shape[1]
    for i in range(point.shape[0]):
        _operating_point(U[i], Y[i, n:], R[i], mass[i], weight[i], state[i], features[i], envelope[i], step_scale[i],
                         skew[i], first, k, hold, a, gain, T, rest, low_speed, FROZEN_CHANGE, point[i])


@kernel
def _step_rows_each(R, point, kin, e, scale, single, skew, move, state, steps, jumps, previous, row, previous_row, T, z,
                    estimate, Y, gain_sums, lam, gain_scale, gain, trend_ring, trend_sums, k, trend_scale, trend, load,
                    held_kinematic):
    """The rows per run (``z`` (a, 3n + 1); ``point`` and ``state`` as :func:`_operating_point_each`'s; Y (a, 2n);
    the per-run arrays (≥ a, …)): _step_rows."""
    n = R.shape[1]
    for i in range(z.shape[0]):
        _step_rows(R[i], point[i, 0], kin[i], e[i], point[i, 4], scale[i], single, skew[i], move[i], point[i, 2],
                   state[i, 2], FROZEN_SAMPLES, steps[i], jumps[i], previous[i], row, previous_row, T, z[i], estimate[i],
                   Y[i, :n], Y[i, n:], gain_sums[i], lam, gain_scale[i], gain[i], trend_ring[i], trend_sums[i], k,
                   trend_scale[i], trend[i], load[i], held_kinematic[i])


def design_consistency(model: ManipulatorModel, runs: Sequence[tuple[np.ndarray, np.ndarray]], T: float,
                       gain: float = DEFAULT_GAIN, skip: int = 0, windows: Sequence[float] = WINDOWS,
                       ripple_orders: np.ndarray | None = None) -> ConsistencyDesign:
    """Learn a :class:`ConsistencyDesign` from fault-free runs, each given as the (Y, U) the diagnoser sees
    ((N, 2n) measurements, (N, n) inputs ū(k−1); see :func:`robofdi.loop.diagnoser_inputs`): friction and the
    carried payload, then the operating-point bound of the compensated residual and the step scale, then the
    kinematic skew, window scales and envelope, and, given the drives' ``ripple_orders`` (n, n_orders) [cycles/rad]
    (:func:`~robofdi.observers.kinematic.ripple_orders`), their aliased per-sample errors
    (:func:`~robofdi.observers.kinematic.identify_ripple`; the single-sample scale where the runs never came
    near an alias)."""
    n = model.n
    if not runs:
        raise RobofdiError("design_consistency: expected at least one fault-free run")
    for i, (Y, U) in enumerate(runs):
        if np.shape(Y)[1:] != (2 * n,) or np.shape(U) != (np.shape(Y)[0], n):
            raise RobofdiError(f"design_consistency: run {i}: expected Y (N, {2 * n}) and U (N, {n}), got "
                               f"{np.shape(Y)} and {np.shape(U)}")

    def replay(observer):
        out = []
        for Y, U in runs:
            observer.reset()
            out.append(np.array([observer.update(y, u).r for y, u in zip(Y, U)]))
        return out

    plain = replay(MomentumObserver(model, T, gain))
    regressor, loads = PayloadRegressor(model, T, gain), []
    for Y, _ in runs:
        regressor.reset()
        loads.append(np.array([regressor.update(y[:n], y[n:]) for y in np.asarray(Y)]))
    friction, payload = identify_friction_and_load(plain, [np.asarray(Y)[:, n:] for Y, _ in runs], loads, gain, T, skip,
                                                   min_share=PAYLOAD_SHARE)
    unit = ConsistencyDesign(friction, np.ones((n, 4)), np.zeros(n), np.ones((n, len(windows), 3)),
                             np.column_stack([np.ones(n), np.zeros((n, 2))]), gain, T, tuple(windows), payload=payload)
    features, residuals, speeds, masses = [], [], [], []
    for Y, U in runs:
        d = ConsistencyResidual(model, unit)
        rows, feats, mass = [], [], []
        for y, u in zip(Y, U):
            res = d.update(y, u)
            rows.append(res.estimate[:n])
            feats.append(d._features.copy())
            mass.append(d._momentum.mass.copy())
        residuals.append(np.array(rows))
        features.append(np.array(feats))
        masses.append(np.array(mass))
        v = np.abs(np.asarray(Y)[:, n:])
        speeds.append(np.concatenate([v[:1], (v[1:] + v[:-1]) / 2]))     # the speed step_bound is given
    envelope = design_envelope(features, residuals, skip)
    impulses = [np.diff(r, axis=0, prepend=r[:1]) / gain for r in residuals]     # (r_k − r_{k−1}) / K_O
    impulse_scale = np.maximum(np.concatenate([w[skip + 1:] for w in impulses]).std(axis=0), 1e-12)
    weight = impulse_scale ** -2.0
    norms = [np.einsum("kij,i,kij->kj", M, weight, M) for M in masses]
    innovations = [np.einsum("kij,i,ki->kj", M, weight, w) / norm
                   for M, w, norm in zip(masses, impulses, norms)]          # velocity_innovation over every sample
    step = design_envelope([np.stack([np.ones_like(s), s, norm ** -0.5], axis=-1) for s, norm in zip(speeds, norms)],
                           innovations, skip + 1)
    step[:, 0] = np.maximum(step[:, 0], 1e-9)
    qs = [np.asarray(Y)[:, :n] for Y, _ in runs]
    vs = [np.asarray(Y)[:, n:] for Y, _ in runs]
    skew = identify_skew(qs, vs, T, skip)
    increments = [kinematic_increments(q, v, T, skew) for q, v in zip(qs, vs)]
    walk = identify_noise_walk(increments, skip)
    scales = design_window_scales(increments, vs, T, skip, windows, noise_walk=walk)
    orders = None if ripple_orders is None else np.asarray(ripple_orders, dtype=float)
    if orders is not None and (orders.ndim != 2 or orders.shape[0] != n):
        raise RobofdiError(f"design_consistency: field 'ripple_orders' must be an ({n}, n_orders) array "
                           f"[cycles/rad], got shape {orders.shape}")
    reach = window_reach(vs, T, skip, windows)
    amplitude, load = (None, None) if orders is None else identify_ripple(
        qs, vs, T, skew, orders, skip, fallback=scales[:, int(np.argmin(windows)), 0], us=[np.asarray(U) for _, U in runs])
    design = ConsistencyDesign(friction, envelope, skew, scales, step, gain, T, tuple(windows), reach, orders,
                               amplitude, load if load is not None and load.any() else None, impulse_scale, walk,
                               payload=payload)
    evidence, trend = np.zeros(n), np.zeros(n)      # the gain and trend evidence's largest fault-free values
    move = np.full(n, MOVE_FLOOR)                   # |e_k − e_{k−1}| over the single-sample scale, largest
    held = np.zeros(n)                              # the longest run of unchanged velocity readings, / FROZEN_SAMPLES
    for Y, U in runs:
        d = ConsistencyResidual(model, design)
        for k, (y, u) in enumerate(zip(Y, U)):
            e_prev = d._previous[0].copy()
            d.update(y, u)
            if k >= skip:
                np.maximum(evidence, d.gain_evidence, out=evidence)
                np.maximum(trend, d.trend_evidence, out=trend)
                np.maximum(held, d._state[2] / FROZEN_SAMPLES, out=held)
            if k > skip:
                np.maximum(move, np.abs(d._previous[0] - e_prev) / d._kinematic.scale[:, d._single], out=move)
    return replace(design, gain_scale=GAIN_MARGIN * np.maximum(evidence, GAIN_FLOOR),
                   trend_scale=TREND_MARGIN * np.maximum(trend, TREND_FLOOR), move_scale=move, repeat_scale=held)
