"""Bošković & Mehra, chapter 5: bad input gets a one-line error naming the condition."""
from __future__ import annotations

import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.faults import ExponentialGrowth, Fault
from robofdi.ftc.idcl import (
    IDCLController, ReferenceModel, allocate, allocation_matrix, check_isolable, check_weights,
    redistributed_allocation,
)
from robofdi.models.flight import flight_surrogate
from robofdi.observers.effector_bank import HybridEffectorFDI
from robofdi.observers.sensor_adaptive import SensorBiasEstimator
from robofdi.sims.flight import FlightPlant
from robofdi.systems.flight_surrogate import FlightScenario, design

S = flight_surrogate()


def test_collinear_effector_columns_are_refused_by_the_bank():
    B = S.B2().copy()
    B[:, 1] = -2.0 * B[:, 0]                      # right LEF a multiple of the left one
    with pytest.raises(RobofdiError, match="'lef_left' and 'lef_right' are collinear"):
        HybridEffectorFDI(S.A2(), B, S.effectors, S.state_names, range(5, 8), 0.01, S.u_min, S.u_max)
    B[:, 1] = 0.0
    with pytest.raises(RobofdiError, match="zero column"):
        check_isolable(B, S.effectors)


def test_a_reference_model_that_is_not_hurwitz_is_refused():
    Lam, ref = design()
    with pytest.raises(RobofdiError, match="must be Hurwitz"):
        ReferenceModel(ref.Abar, -ref.Am, ref.Bm)
    with pytest.raises(RobofdiError, match="Hurwitz"):
        IDCLController(S.A2, S.B2, S.weights(), -Lam, ref)


def test_w_must_be_positive_definite_and_diagonal():
    w = S.weights().copy()
    w[3] = 0.0
    with pytest.raises(RobofdiError, match="positive definite"):
        allocate(S.B2(), w, np.zeros(3))
    with pytest.raises(RobofdiError, match="positive definite"):
        check_weights(-np.eye(8), 8)
    W = np.eye(8)
    W[0, 1] = 0.1
    with pytest.raises(RobofdiError, match="diagonal"):
        check_weights(W, 8)


def test_an_infeasible_allocation_names_the_condition():
    with pytest.raises(RobofdiError, match="infeasible allocation.*singular"):
        allocation_matrix(S.B2(), S.weights(), range(6), S.effectors)        # two rudders cannot span 3 axes
    with pytest.raises(RobofdiError, match="infeasible allocation"):
        redistributed_allocation(S.B2(), S.weights(), np.array([50.0, 0.0, 0.0]), S.u_min, S.u_max)
    # a feasible demand within the limits stays within them
    u = redistributed_allocation(S.B2(), S.weights(), np.array([0.3, 0.5, -0.2]), S.u_min, S.u_max)
    assert np.allclose(S.B2() @ u, [0.3, 0.5, -0.2]) and np.all(u >= S.u_min) and np.all(u <= S.u_max)


def test_bad_fields_are_named():
    with pytest.raises(RobofdiError, match="'rate' must be a finite number > 0"):
        ExponentialGrowth(0.0)
    with pytest.raises(RobofdiError, match="'magnitude' must be in \\[0, 1\\] for component_wing_damage"):
        Fault("w", "component_wing_damage", "left_wing", onset=1.0, magnitude=1.5)
    with pytest.raises(RobofdiError, match="'lam' must be a Hurwitz"):
        SensorBiasEstimator(S.A(), S.B(), S.state_names, S.effectors, list(S.units), 0.01, lam=1.0)
    with pytest.raises(RobofdiError, match="'scheme' must be one of"):
        FlightScenario(scheme="magic")
    with pytest.raises(RobofdiError, match="wing damage must be a fraction"):
        FlightPlant().apply_component_fault("component_wing_damage", "left_wing", 2.0)
    with pytest.raises(RobofdiError, match="damage 'rho' must be in \\[0, 1\\]"):
        S.A(1.2)
    with pytest.raises(RobofdiError, match="input 'u' must be finite"):
        FlightPlant().step(np.full(8, np.nan))
    bank = HybridEffectorFDI(S.A2(), S.B2(), S.effectors, S.state_names, range(5, 8), 0.01, S.u_min, S.u_max)
    with pytest.raises(RobofdiError, match="'y'"):
        bank.update(np.full(8, np.inf), np.zeros(8))
