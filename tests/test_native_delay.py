"""robofdi's ``sensor_delay`` against MuJoCo's native sensor delay (``<sensor ... delay= nsample= interp=>``,
MuJoCo >= 3.5; the core's range 3.8.1–4.x has it): sample for sample the same y(t − d) where the native history
is long enough, and the reason robofdi keeps its own buffer — the native history is sized at compile time, and a
delay set beyond it at run time silently reads the oldest sample (docs: concepts.md, "Delays and MuJoCo's native
delay")."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from robofdi.faults import Fault
from robofdi.faults.effects import make_effect

DT, D = 0.001, 0.02                     # s: physics step, delay


def _pendulum(nsample: int):
    xml = f"""<mujoco><option timestep="{DT}"/><worldbody><body><joint name="j" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass="1"/></body></worldbody>
      <actuator><motor joint="j"/></actuator>
      <sensor><jointpos joint="j"/><jointpos joint="j" nsample="{nsample}" delay="{D}" interp="linear"/></sensor></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    if not hasattr(model, "sensor_delay"):
        pytest.skip(f"mujoco {mujoco.__version__} has no native sensor delay")
    return model, mujoco.MjData(model)


def _step(model, data):
    data.ctrl[0] = np.sin(20.0 * data.time)          # N·m: a torque that keeps the pendulum moving
    mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)                    # the sensors at the new time
    return data.time, data.sensordata[0], data.sensordata[1]


def test_sensor_delay_equals_mujocos_native_delay_within_its_history():
    model, data = _pendulum(nsample=int(D / DT) + 2)
    lag = make_effect(Fault("lag", "sensor_delay", "q", onset=0.0, params={"delay": D}), np.random.SeedSequence(0))
    worst, moved = 0.0, []
    for _ in range(300):
        t, q, q_native = _step(model, data)
        lag.observe(t, q)
        y = lag.apply(t, q)
        moved.append(q)
        if t > D + 2 * DT:                            # once both histories hold the delay
            worst = max(worst, abs(y - q_native))
    assert np.ptp(moved) > 0.5                        # rad: the signal moves, so a wrong delay would show
    assert worst < 1e-12


def test_a_native_delay_longer_than_its_compiled_history_reads_the_oldest_sample():
    model, data = _pendulum(nsample=int(D / DT) + 2)   # history for 22 ms
    values = [_step(model, data) for _ in range(300)]
    model.sensor_delay[1] = 0.1                       # s: a fault's delay switched on at run time, past the history
    t, q, q_native = _step(model, data)
    times, qs = np.array([v[0] for v in values]), np.array([v[1] for v in values])
    assert abs(q_native - np.interp(t - 0.1, times, qs)) > 0.05      # not y(t - 0.1 s)
    assert abs(q_native - np.interp(t - (int(D / DT) + 1) * DT, times, qs)) < 0.02   # about the history's oldest
