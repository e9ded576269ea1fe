"""NLAR on two more models of other shapes, each with a fault detected: a MuJoCo pendulum with Coulomb friction
(model: smoothed friction) and a two-tank system with square-root outflows (truth integrated by scipy)."""
from __future__ import annotations

import mujoco
import numpy as np
import scipy.integrate

from robofdi import ASSETS
from robofdi.decision import calibrate_thresholds
from robofdi.models.affine_examples import TWO_TANK_CATALOGUE, pendulum_model, two_tank_domain, two_tank_model
from robofdi.redundancy import derive_nlar
from robofdi.redundancy.derivatives import SavitzkyGolay
from robofdi.redundancy.residuals import nlar_residual
from robofdi.seeding import rng


def _residuals(diagnoser, y, u):
    diagnoser.reset()
    return np.array([diagnoser.update(y[k], u[k]).r for k in range(len(y))])


def _pendulum_run(seed: int, bias: float = 0.0, onset: float = 4.0, duration: float = 6.0):
    """Open-loop torque on the MuJoCo pendulum; angle encoder with noise. Returns time, y, u (the command)."""
    m = mujoco.MjModel.from_xml_path(str(ASSETS / "pendulum.xml"))
    d = mujoco.MjData(m)
    noise = rng(seed, "pendulum", "encoder")
    t = np.arange(int(duration / m.opt.timestep)) * m.opt.timestep
    u = 0.8 * np.sin(1.3 * t) + 0.5 * np.sin(3.1 * t + 0.4)
    y = np.empty(t.size)
    for k, tk in enumerate(t):
        y[k] = d.qpos[0] + 2e-5 * noise.standard_normal()
        d.ctrl[0] = u[k] + (bias if tk >= onset else 0.0)     # actuator fault: the motor adds a bias
        mujoco.mj_step(m, d)
    return t, y[:, None], u[:, None]


def test_pendulum_torque_bias_detected():
    design = derive_nlar(pendulum_model())
    assert design.count == 1 and design.independent == ["R2"]
    flt = SavitzkyGolay(dt=0.001, window=41, order=3)
    diag = nlar_residual(design, ["angle"], ["torque"], flt)
    # the torque held over the last step is what the diagnoser sees with y(k): shift u by one sample
    _, y0, u0 = _pendulum_run(seed=1)
    threshold = calibrate_thresholds([_residuals(diag, y0, np.r_[[[0.0]], u0[:-1]])], 1.3, skip=flt.window)
    t, y, u = _pendulum_run(seed=2, bias=0.3)
    r = _residuals(diag, y, np.r_[[[0.0]], u[:-1]])
    alarm = np.abs(r[:, 0]) > threshold[0]
    alarm[: flt.window] = False
    assert not alarm[t < 4.0].any()
    first = t[np.flatnonzero(alarm)[0]]
    assert 4.0 <= first <= 4.0 + 0.05


def _tank_run(seed: int, leak: float = 0.0, onset: float = 300.0, duration: float = 500.0, dt: float = 0.1):
    """Truth: the two tanks with orifices 6 % off the catalogue, a pump flow varying slowly, a leak from tank 1."""
    c = TWO_TANK_CATALOGUE
    a12, a2, g = 1.06 * c["a12"], 0.95 * c["a2"], c["g"]

    def q(t):
        return 6e-5 + 1e-5 * np.sin(0.05 * t) + 0.5e-5 * np.sin(0.013 * t)

    def rhs(t, h):
        h1, h2 = max(h[0], 0.0), max(h[1], 0.0)
        q12 = a12 * np.sqrt(2 * g * max(h1 - h2, 0.0))
        q_leak = leak * np.sqrt(2 * g * h1) if t >= onset else 0.0
        return [(q(t) - q12 - q_leak) / c["A1"], (q12 - a2 * np.sqrt(2 * g * h2)) / c["A2"]]

    h2 = (6e-5 / a2) ** 2 / (2 * g)
    h1 = h2 + (6e-5 / a12) ** 2 / (2 * g)
    t = np.arange(0.0, duration, dt)
    sol = scipy.integrate.solve_ivp(rhs, (0.0, duration), [h1, h2], t_eval=t, max_step=0.05, rtol=1e-9, atol=1e-12)
    y = sol.y[1] + 2e-5 * rng(seed, "tank", "level").standard_normal(t.size)
    return t, y[:, None], q(t)[:, None]


def test_two_tank_leak_detected():
    m = two_tank_model()
    design = derive_nlar(m, two_tank_domain(m))
    assert design.count == 1 and design.independent == ["R2"] and design.trivial == ["R1"]
    flt = SavitzkyGolay(dt=0.1, window=101, order=3)
    diag = nlar_residual(design, ["level2"], ["pump_flow"], flt)
    _, y0, u0 = _tank_run(seed=1)
    threshold = calibrate_thresholds([_residuals(diag, y0, u0)], 1.3, skip=flt.window)
    t, y, u = _tank_run(seed=2, leak=2e-5)
    r = _residuals(diag, y, u)
    alarm = np.abs(r[:, 0]) > threshold[0]
    alarm[: flt.window] = False
    assert not alarm[t < 300.0].any()
    assert alarm[t >= 300.0].any()
    first = t[np.flatnonzero(alarm)[0]]
    assert first < 300.0 + 30.0
