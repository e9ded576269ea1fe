"""Mission supervision (book ch. 4, §3 and §3.4): the Theseus phase manager and the HW/SW watchdog on scripted
event streams, and the safe manoeuvre on a short AUV run (the longer runs are `reproduction` entries of ch4-auv)."""
from __future__ import annotations

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.control.supervision import MissionPhase, PhaseFaultManager, SupervisedController, Watchdog
from robofdi.experiments.ch4_auv import _supervised_run
from robofdi.systems.auv import AuvScenario, _controller


def test_a_phase_that_does_not_complete_in_time_switches_to_its_safe_behaviour():
    manager = PhaseFaultManager([MissionPhase("descend", 2.0), MissionPhase("homing", 3.0, "stop_and_wait"),
                                 MissionPhase("surface", 5.0)])
    dt, out = 0.1, []
    for k in range(100):
        t = k * dt
        done = manager.behaviour == "descend" and t >= 1.0          # descend completes at 1 s; homing never does
        out.append(manager.update(t, done))
    assert manager.log[0] == (0.0, "descend") and manager.log[1] == (1.0, "homing")
    assert manager.failed.name == "homing" and manager.failed_at == pytest.approx(4.1)   # first tick past 1 + 3 s
    assert out[-1] == "stop_and_wait" and "surface" not in out
    complete = PhaseFaultManager([MissionPhase("a", 1.0)])
    assert complete.update(0.0, False) == "a" and complete.update(0.5, True) == "mission_complete"
    with pytest.raises(RobofdiError, match="timeout"):
        MissionPhase("x", 0.0)
    with pytest.raises(RobofdiError, match="unique"):
        PhaseFaultManager([MissionPhase("a", 1.0), MissionPhase("a", 2.0)])


def test_watchdog_flags_a_held_output_after_its_timeout_and_not_a_changing_one():
    gen = np.random.default_rng(0)
    dog = Watchdog(0.05)
    alarms = []
    held = None
    for k in range(300):
        t = k * 0.01
        u = gen.normal(size=3) if t < 2.0 else held
        held = u if t < 2.0 else held
        alarms.append((t, dog.update(t, u)))
    first = next(t for t, a in alarms if a)
    assert not any(a for t, a in alarms if t < 2.0)
    assert first == pytest.approx(2.0 - 0.01 + 0.06, abs=1e-9)     # last change at 1.99 s, > 0.05 s later
    with pytest.raises(RobofdiError, match="timeout"):
        Watchdog(-1.0)


def test_supervised_controller_flies_the_safe_manoeuvres_on_the_auv():
    # a real AUV run: the controller task crashes at 0.5 s (outputs held), the watchdog alarms one timeout later and
    # the backup task surfaces (depth falls)
    sc = AuvScenario(duration=3.0)
    model = sc.nominal_model(sc.simulator())
    rec, ctl = _supervised_run(sc, 3.0, "watchdog", crash=0.5, backup=_controller(model, sc.allocation),
                               watchdog=Watchdog(0.05), on_watchdog="surface", ascent_speed=0.25)
    assert ctl.log[0][0] == pytest.approx(0.48 + 0.06) and ctl.mode == "surface"   # last change at the 0.48 s tick
    depth = -rec.truth_state[:, 2]
    k1, k3 = np.argmin(np.abs(rec.time - 1.0)), len(rec.time) - 1
    assert depth[k1] - depth[k3] > 0.2                                        # rising: ≈ 0.25 m/s after the lag
    with pytest.raises(RobofdiError, match="backup"):
        SupervisedController(_controller(model), 0.02, watchdog=Watchdog(0.05))
