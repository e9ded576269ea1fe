"""Your own diagnoser (docs/howto/own-diagnoser.md): run from the folder where `robofdi demo` wrote runs/."""
import numpy as np
import robofdi as fdi
from robofdi.decision import Signature, ThresholdDecision, calibrate_thresholds
from robofdi.loop import Diagnosis, diagnose_record
from robofdi.observers import Residual
from robofdi.observers.residual import check_measurement


class InverseDynamicsResidual:
    """Torque residual r = ū − τ̂(q, v, a) [N·m], averaged over ``window`` samples: the input the arm was told,
    minus what the nominal model (the belief) says the measured motion needed; a = velocity difference / T."""

    def __init__(self, model, dt, window=10):
        joints = model.joint_names
        self.model, self.dt, self.window = model, dt, window
        self.inputs = list(joints)                                   # the simulator's actuators
        self.measurements = [f"{j}_pos" for j in joints] + [f"{j}_vel" for j in joints]
        self.components = list(joints)                               # one residual per joint
        self.estimate_components = list(joints)                      # the residual is the torque-fault estimate
        self.estimate_modes = ["level"] * len(joints)
        self.units = {"residual": ["N*m"] * len(joints), "estimate": ["N*m"] * len(joints)}
        self.reset()

    def reset(self):
        self._last, self._recent = None, []

    def update(self, y, u):
        n = len(self.components)
        y, u = check_measurement(y, 2 * n, "y"), check_measurement(u, n, "u")      # NaN/inf: a clear error
        q, v = y[:n], y[n:]
        r = np.zeros(n)
        if self._last is not None:                                   # u is ū(k−1), held since the last sample
            q0, v0 = self._last
            self._recent = [*self._recent[-(self.window - 1):], u - self.model.inverse_dynamics(q0, v0, (v - v0) / self.dt)]
            r = np.mean(self._recent, axis=0)
        self._last = q, v
        return Residual(r=r, estimate=r)

    def signatures(self):
        return [Signature(j, frozenset({j})) for j in self.components]


runs = fdi.load("runs/ch3-actuator-seed0/record.h5"), fdi.load("runs/ch3-actuator-seed0/fault_free.h5")
diagnoser = InverseDynamicsResidual(fdi.ManipulatorModel(fdi.ASSETS / "arm6.xml"), dt=1 / runs[0].rates["diagnosis_hz"])
free = diagnose_record(runs[1], Diagnosis(diagnoser))                       # fault-free: design the thresholds
decision = ThresholdDecision(diagnoser.components, calibrate_thresholds([free.residual], margin=1.2),
                             diagnoser.signatures())
trace = diagnose_record(runs[0], Diagnosis(diagnoser, decision))            # the faulty run, offline
for fault in ("joint3", "joint5"):
    hit = [k for k, isolated in enumerate(trace.isolated) if fault in isolated.split("+")]
    print(fault, f"isolated at {trace.time[hit[0]]:.3f} s" if hit else "not isolated")
print("alarm samples before the first onset (1 s):", int(trace.alarm[trace.time < 1.0].any(axis=1).sum()))
