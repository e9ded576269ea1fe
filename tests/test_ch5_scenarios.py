"""Bošković & Mehra, chapter 5, on the flight surrogate: the closed-loop outcomes of the digest's C.1(b) (the
experiments ch5-* record them all; these are the few that pin the behaviour, ~20 s together)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from robofdi.experiments.ch5_boskovic import sim2_faults, sim4_faults, tracking
from robofdi.faults import Fault, Step
from robofdi.models.flight import flight_surrogate
from robofdi.systems.flight_surrogate import FlightScenario, build_loop

S = flight_surrogate()
DELTA = 3e-6          # ≈ 2 × the calibrated threshold of the default mission (calibrate_delta: 1.55e-6)


def test_hybrid_fdi_arc_switches_nominal_rudder_lef_and_nothing_without_failure():
    sc = FlightScenario(sim4_faults(), 0, 12.0, "hybrid", delta=DELTA)
    loop = build_loop(sc)
    rec = loop.run(12.0, seed=0)
    bank = loop.diagnoses["hybrid_mm"].diagnoser
    assert [m for _, m in bank.sequence] == ["nominal", "rud_left", "lef_right"]
    assert 1.5 < bank.sequence[1][0] <= 1.75
    limit = sim4_faults()[0].params["limit"]
    assert abs(bank.frozen[S.effectors.index("rud_left")] - limit) < 0.05 * limit
    lock = rec.signals["u"][350, S.effectors.index("lef_right")]
    assert abs(bank.frozen[S.effectors.index("lef_right")] - lock) < 0.05 * abs(lock)
    assert tracking(rec).max() < 0.1            # baseline: ≈ 1 (V), 0.14 (r)
    loop = build_loop(replace(sc, faults=()))
    loop.run(12.0, seed=0, run_key="failure_free")
    assert [m for _, m in loop.diagnoses["hybrid_mm"].diagnoser.sequence] == ["nominal"]


def test_damage_estimate_converges_and_stays_zero_without_damage():
    f = (Fault("wing", "component_wing_damage", "left_wing", onset=1.5, magnitude=0.6),)
    rec = build_loop(FlightScenario(f, 0, 11.5, "damage")).run(11.5, seed=0)
    rho = rec.diagnosers["damage"].residual[:, 0]
    assert abs(rho[-1] - 0.6) <= 0.1
    assert np.all(rho[rec.diagnosers["damage"].time < 1.5] == 0.0)


def test_constant_sensor_bias_is_estimated_and_the_static_estimate_tracks():
    rec = build_loop(FlightScenario(sim2_faults(Step()), 0, 15.0, "sensor", noise=False)).run(15.0, seed=0)
    d = rec.diagnosers["sensor_bias"].residual[-1]
    for c, m in (("alpha", 0.0175), ("q", 0.045), ("theta", -0.0525)):
        assert abs(d[S.state_names.index(c)] - m) < 1e-3
    err = tracking(rec, 12.0, 15.0)
    assert np.delete(err, S.state_names.index("V")).max() < 5e-3
