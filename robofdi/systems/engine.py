"""Saif & Xiong's Example 1 (book ch. 1) on a SYNTHETIC intake manifold: MAP estimation with the SMO (96) against the
open-loop model (93), and MAP-sensor fault detection.

The chapter's engine is a GM V8 model whose constants, volumetric-efficiency table, gains and throttle data are not
given (a restricted report); everything numeric here is this module's choice, consistent with the chapter's bounds
a(ω) ≤ 0.0531 ω and b(θ) ≤ 9·10⁶::

    ẋ = −a(ω) x + b(θ) Ψ(x) + d,   y = x (+ sensor fault)             x = MAP [Pa]                     (91)–(92)
    a(ω) = η_v V_d ω / (4π V),   b(θ) = [C_d (c1 + c2 (1 − cos(θ − θ0))) + C_di A_i] √(R T0) P0 / V
    Ψ(x) = √(2k/(k−1) ((x/P0)^{2/k} − (x/P0)^{(k+1)/k}))  above the choke ratio (2/(k+1))^{k/(k−1)}, else
           √(k (2/(k+1))^{(k+1)/(k−1)})                                                                   (85)

[synthetic] P0 = 101325 Pa, T0 = 298 K, R = 287 J/(kg K), k = 1.4, V = 7.5 L, V_d = 5.7 L, η_v = 0.8, C_d = 0.7,
c1 = 1e-5 m², c2 = 2.5e-3 m², θ0 = 0.1 rad, C_di A_i = 1e-5 m²; a drive cycle θ(t), ω(t) of sines; the plant's
mismatch d = 40,000 Pa/s (the chapter's d(t)). Observers: open loop (93) and the SMO (96)
x̂' = −a x̂ + b Ψ(x̂) + K (y − x̂) + K0 sgn(y − x̂), K = 5 s⁻¹, K0 = 60,000 Pa/s > d; residual y − x̂.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.sims.integrate import rk4
from robofdi.loop import ClosedLoop, Diagnosis, Rates
from robofdi.observers.residual import Residual, check_measurement
from robofdi.seeding import stream

__all__ = ["ENGINE", "psi", "a_of", "b_of", "EnginePlant", "EngineObserver", "run_engine", "run_engine_experiment"]

ENGINE = {"P0": 101325.0, "T0": 298.0, "R": 287.0, "k": 1.4, "V": 0.0075, "Vd": 0.0057, "eta_v": 0.8, "Cd": 0.7,
          "c1": 1e-5, "c2": 2.5e-3, "theta0": 0.1, "CdiAi": 1e-5, "d": 40000.0}


def psi(x: float, p=ENGINE) -> float:
    """Ψ of eq. (85) (flow function of the pressure ratio x/P0; choked below the critical ratio)."""
    k = p["k"]
    ratio = min(max(x / p["P0"], 0.0), 1.0)
    crit = (2.0 / (k + 1.0)) ** (k / (k - 1.0))
    if ratio <= crit:
        return math.sqrt(k * (2.0 / (k + 1.0)) ** ((k + 1.0) / (k - 1.0)))
    return math.sqrt(max(2.0 * k / (k - 1.0) * (ratio ** (2.0 / k) - ratio ** ((k + 1.0) / k)), 0.0))


def a_of(omega: float, p=ENGINE) -> float:
    return p["eta_v"] * p["Vd"] * omega / (4.0 * math.pi * p["V"])


def b_of(theta: float, p=ENGINE) -> float:
    area = p["Cd"] * (p["c1"] + p["c2"] * (1.0 - math.cos(theta - p["theta0"]))) + p["CdiAi"]
    return area * math.sqrt(p["R"] * p["T0"]) * p["P0"] / p["V"]


def drive_cycle(t: float) -> np.ndarray:
    """[synthetic] throttle angle θ [rad] and engine speed ω [rad/s] (the chapter's Fig. 4 data are not available)."""
    theta = 0.1 + 0.15 + 0.12 * math.sin(0.4 * t) + 0.06 * math.sin(1.3 * t + 0.4)
    omega = 150.0 + 60.0 * math.sin(0.4 * t - 0.5)
    return np.array([theta, omega])


@dataclass(eq=False)
class EnginePlant:
    """Simulator protocol: the manifold ODE with the mismatch ``d`` [Pa/s]; u = (θ, ω) (measured engine inputs),
    y = MAP [Pa] with Gaussian noise ``noise`` [Pa]; RK4 at 0.1 ms."""

    d: float = ENGINE["d"]
    x0: float = 50000.0
    noise: float = 20.0
    control_dt: float = 0.001
    physics_dt: float = 0.0001
    system = "engine_manifold"
    actuators = ["throttle", "engine_speed"]
    sensor_channels = ["map"]
    components: list = field(default_factory=list)
    component_kinds: dict = field(default_factory=dict)
    state_names = ["map"]
    units = {"state": ["Pa"], "u": ["rad", "rad/s"], "y": ["Pa"]}

    def __post_init__(self):
        self._sub = int(round(self.control_dt / self.physics_dt))
        self.reset()

    def _f(self, x, u):
        return -a_of(u[1]) * x + b_of(u[0]) * psi(x) + self.d

    def reset(self, initial_state=None, seed=None):
        self.x = float(self.x0 if initial_state is None else np.asarray(initial_state, dtype=float).ravel()[0])
        self._rng = np.random.default_rng(stream(seed, "sensor", "map"))
        self.u_applied = np.zeros(2)
        return self._measure()

    def saturate(self, u):
        return np.asarray(u, dtype=float)

    def step(self, u):
        u = np.asarray(u, dtype=float)
        if u.shape != (2,) or not np.all(np.isfinite(u)):
            raise RobofdiError(f"EnginePlant: input 'u' must be (θ, ω), 2 finite values, got {u!r}")
        self.u_applied = u.copy()
        self.x, _ = rk4(lambda t, x: self._f(x, u), self.x, self.physics_dt, self._sub)
        return self._measure()

    def apply_component_fault(self, kind, target, value):
        raise RobofdiError(f"EnginePlant: no component faults (got {kind!r})")

    def nominal_model(self, mismatch=None):
        return dict(ENGINE, d=0.0)

    @property
    def state(self):
        return np.array([self.x])

    @property
    def true_output(self):
        return np.array([self.x])

    def _measure(self):
        return self.true_output + (self.noise * self._rng.standard_normal(1) if self.noise > 0 else 0.0)


class EngineObserver:
    """Diagnoser protocol: the open-loop MAP model (93) (``K`` = ``K0`` = 0) or the SMO (96); residual y − x̂ [Pa];
    explicit Euler at ``substep`` inside each sample, y linearly interpolated, u held."""

    def __init__(self, K: float = 5.0, K0: float = 60000.0, x0: float = 80000.0, sample_time: float = 1e-3,
                 substep: float = 1e-5, name: str = "smo"):
        if not (K >= 0 and K0 >= 0 and 0 < substep <= sample_time):
            raise RobofdiError(f"EngineObserver: need K >= 0, K0 >= 0 and 0 < substep <= sample_time, got {K}, {K0}, {substep}")
        self.K, self.K0, self.x0, self.T = float(K), float(K0), float(x0), float(sample_time)
        self.n = max(1, int(round(sample_time / substep)))
        self.inputs, self.measurements = ["throttle", "engine_speed"], ["map"]
        self.components = [f"{name}_map"]
        self.estimate_components, self.estimate_modes = [], []
        self.units = {"residual": ["Pa"], "estimate": []}
        self.reset()

    def reset(self):
        self.x = self.x0
        self._y = None

    def signatures(self):
        from robofdi.decision import Signature

        return [Signature("map", set(self.components))]

    def update(self, y, u):
        y = check_measurement(y, 1, "y")
        u = check_measurement(u, 2, "u")
        if self._y is not None:
            a, b = a_of(u[1]), b_of(u[0])
            h, x, y0, dy = self.T / self.n, self.x, self._y, (y[0] - self._y) / self.n
            K, K0 = self.K, self.K0
            for j in range(self.n):
                e = y0 + dy * j - x
                x += h * (-a * x + b * psi(x) + K * e + (K0 if e > 0 else -K0 if e < 0 else 0.0))
            self.x = x
        self._y = float(y[0])
        return Residual(np.array([y[0] - self.x]), np.zeros(0))


class _Cycle:
    def __call__(self, t):
        return drive_cycle(t)

    def update(self, y, reference):
        return reference


def run_engine(faults=(), d: float = ENGINE["d"], duration: float = 30.0, seed: int = 0, run_key: str = "run"):
    """Both observers online on the synthetic plant → record (diagnosers "smo" and "open_loop")."""
    plant = EnginePlant(d=d)
    cycle = _Cycle()
    diag = {"smo": Diagnosis(EngineObserver(name="smo")), "open_loop": Diagnosis(EngineObserver(0.0, 0.0, name="open_loop"))}
    loop = ClosedLoop(plant, cycle, cycle, faults=faults, diagnoses=diag, rates=Rates(1000.0, 1000.0, "first"),
                      reference_columns=["throttle", "engine_speed"], reference_units=["rad", "rad/s"])
    return loop.run(duration, seed=seed, run_key=run_key, scenario="ch1-engine")


def run_engine_experiment(name, out, seed, progress):
    from robofdi.evaluate import summarize
    from robofdi.evaluate.figures import save_figure
    from robofdi.evaluate.reproduction import reproduction_check as check
    from robofdi.evaluate.run_folder import prepare_run_dir, write_run_folder
    from robofdi.faults import Fault
    from robofdi.progress import Progress

    run_dir = prepare_run_dir(out, name, seed)
    progress = Progress.of(progress, name)
    k = ENGINE["k"]
    crit = (2.0 / (k + 1.0)) ** (k / (k - 1.0)) * ENGINE["P0"]
    grid = np.linspace(1000.0, ENGINE["P0"] - 1.0, 4000)
    vals = np.array([psi(x) for x in grid])
    jump = abs(psi(crit * (1 + 1e-9)) - psi(crit * (1 - 1e-9)))
    static = [
        check("E1.1 Ψ continuous at the choke ratio (2/(k+1))^(k/(k−1)) and Ψ' ≤ 0 on (0, P0)", 0.0,
              [jump, float(np.diff(vals).max())], 1e-6, jump < 1e-6 and np.diff(vals).max() <= 1e-12),
    ]
    with progress.stage("perfect model (d = 0), 10 s"):
        perfect = run_engine(d=0.0, duration=10.0, seed=seed, run_key="perfect")
    with progress.stage("mismatch d = 40,000 Pa/s and a MAP sensor fault at 20 s, 30 s"):
        fault = Fault("map_bias", "sensor_bias", "map", onset=20.0, magnitude=-8000.0)
        rec = run_engine((fault,), seed=seed, run_key="mismatch")
    tp, rp = perfect.time, perfect.diagnosers["open_loop"].residual[:, 0]
    t, r_smo, r_ol = rec.time, rec.diagnosers["smo"].residual[:, 0], rec.diagnosers["open_loop"].residual[:, 0]
    conv = float(np.abs(rp[tp >= 8.0]).max())
    pre = (t >= 2.0) & (t < 20.0)
    rms_smo, rms_ol = float(np.sqrt(np.mean(r_smo[pre] ** 2))), float(np.sqrt(np.mean(r_ol[pre] ** 2)))
    thr = 3.0 * float(np.abs(r_smo[pre]).max())
    cross = np.flatnonzero((t >= 20.0) & (np.abs(r_smo) > thr))
    delay = float(t[cross[0]] - 20.0) if cross.size else None
    ol_thr = 3.0 * float(np.abs(r_ol[pre]).max())
    ol_cross = bool(np.any((t >= 20.0) & (np.abs(r_ol) > ol_thr)))
    checks = static + [
        check("E1.2 perfect model: the open-loop estimate converges from x̂(0) = 80 kPa (|y − x̂| after 8 s, Pa)", 100.0,
              conv, None, conv < 100.0, note="the band is the sensor noise (20 Pa std) [synthetic]"),
        check("E1.3 with d = 40,000 Pa/s: SMO residual RMS ≤ 10 % of the open-loop residual RMS (2–20 s)", 0.1,
              rms_smo / rms_ol, None, rms_smo <= 0.1 * rms_ol, note=f"SMO {rms_smo:.4g} Pa, open loop {rms_ol:.4g} Pa"),
        check("E1.4 MAP sensor fault (−8 kPa at 20 s): SMO residual crosses 3× its pre-fault max, delay [s]", 0.1,
              delay, None, delay is not None and delay < 0.1,
              note=f"threshold {thr:.4g} Pa; the open-loop residual, whose threshold must absorb the mismatch "
                   f"({ol_thr:.4g} Pa), {'crosses' if ol_cross else 'does not cross'} its own"),
    ]
    summary = summarize(rec, name, [fault.to_dict()])
    summary["reproduction"] = checks
    summary["harness"] = ("SYNTHETIC: the chapter gives no constants, η_v table, gains or throttle data; every number of "
                          "the plant, the drive cycle, K = 5 s⁻¹ and K0 = 60,000 Pa/s is robofdi's choice "
                          "(robofdi.systems.engine); d = 40,000 Pa/s is the chapter's; MAP noise 20 Pa std")
    with progress.stage("run folder: records, figures"):
        (run_dir / "figures").mkdir(parents=True, exist_ok=True)
        write_run_folder(run_dir, rec, summary, {"perfect": perfect}, replay=False)
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        axes[0].plot(t, rec.truth_state[:, 0] / 1e3, "k", lw=1.2, label="actual MAP")
        axes[0].plot(t, (rec.signals["y_meas"][:, 0] - r_ol) / 1e3, "b", lw=0.8, label="open loop (93)")
        axes[0].plot(t, (rec.signals["y_meas"][:, 0] - r_smo) / 1e3, "r--", lw=0.8, label="SMO (96)")
        axes[0].set_ylabel("MAP [kPa]")
        axes[0].legend(fontsize=7)
        axes[1].plot(t, r_ol / 1e3, "b", lw=0.8, label="open-loop residual")
        axes[1].plot(t, r_smo / 1e3, "r", lw=0.8, label="SMO residual")
        from robofdi.evaluate.annotate import event_lines

        for ax in axes:
            event_lines(ax, [fault], label=ax is axes[0], color="0.5")
        axes[1].set_ylabel("y − x̂ [kPa]")
        axes[1].set_xlabel("t [s]")
        axes[1].legend(fontsize=7)
        fig.suptitle("Figs. 5–7 (like, synthetic): MAP estimates and residuals, d = 40,000 Pa/s, sensor fault at 20 s",
                     fontsize=9)
        save_figure(fig, Path(run_dir) / "figures" / "fig5_7_engine.png")
    return summary, run_dir
