"""Thruster allocation (robofdi.ftc.allocation) against the digest's tables (spec_ch4_auv.md §6.6, §7 check 2)."""
import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.ftc.allocation import (
    ThrustReallocation, capability, column_deletion_allocation, constrained_allocation, pseudo_inverse_allocation,
)
from robofdi.protocols import HEALTHY, Health

s = 0.5 ** 0.5
B = np.array([                       # the digest's B (FRD), exact entries
    [s, s, s, s, 0, 0, 0, 0],
    [-s, s, -s, s, 0, 0, 0, 0],
    [0, 0, 0, 0, 1, 1, 1, 1],
    [0, 0, 0, 0, 0.2475, -0.2475, -0.2475, 0.2475],
    [0, 0, 0, 0, -0.2475, -0.2475, 0.2475, 0.2475],
    [-0.4, 0.4, 0.4, -0.4, 0, 0, 0, 0]])
TAU = np.array([30.0, 15.0, 20.0, 2.0, 2.0, 5.0])
TABLE = {(): [2.178, 19.035, 8.428, 12.785, 5.0, 0.959, 5.0, 9.041],
         (1,): [-16.857, 0, 27.463, 31.820, 5.0, 0.959, 5.0, 9.041],
         (1, 5): [-16.857, 0, 27.463, 31.820, 5.959, 0, 5.959, 8.081]}


@pytest.mark.parametrize("failed", list(TABLE))
def test_allocations_reproduce_the_table_and_zero_weight_equals_column_deletion(failed):
    e = np.ones(8)
    e[list(failed)] = 0.0
    deleted = column_deletion_allocation(B, TAU, failed)
    weighted = pseudo_inverse_allocation(B, TAU, e)
    constrained = constrained_allocation(B, TAU, -40, 40, e)
    np.testing.assert_allclose(deleted.u, TABLE[failed], atol=1e-3)
    np.testing.assert_allclose(weighted.u, deleted.u, atol=1e-12)
    np.testing.assert_allclose(constrained.u, deleted.u, atol=1e-9)
    for r in (deleted, weighted, constrained):
        assert r.feasible and np.linalg.norm(r.unattained) < 1e-9


def test_capability_reproduces_the_lp_table():
    np.testing.assert_allclose(capability(B, -40, 40)[:, 1], [113.14, 113.14, 160, 39.60, 39.60, 64], atol=1e-2)
    e = np.ones(8)
    e[[1, 5]] = 0
    np.testing.assert_allclose(capability(B, -40, 40, e)[:, 1], [56.57, 56.57, 80, 19.80, 19.80, 32], atol=1e-2)
    np.testing.assert_allclose(capability(B, -40, 40, e)[:, 0], -capability(B, -40, 40, e)[:, 1], atol=1e-6)


def test_constrained_allocation_always_respects_saturation_and_reports_what_is_lost():
    g = np.random.default_rng(11)
    for k in range(200):
        tau = g.normal(0, 60, 6)
        e = np.ones(8)
        e[g.choice(8, g.integers(0, 3), replace=False)] = 0.0
        limit = g.uniform(5, 40)
        r = constrained_allocation(B, tau, -limit, limit, e)
        assert np.all(np.abs(r.u) <= limit + 1e-9), k
        np.testing.assert_allclose(r.attained + r.unattained, tau, atol=1e-9)
        # nothing the limits allow is left out: the unattained part cannot be reduced along the attainable directions
        pinv = pseudo_inverse_allocation(B, tau, e)
        if np.all(np.abs(pinv.u) <= limit):
            assert r.feasible
    big = constrained_allocation(B, np.array([200.0, 0, 0, 0, 0, 0]), -40, 40)
    assert not big.feasible and big.attained[0] == pytest.approx(113.137, abs=0.01)
    assert big.unattained[0] == pytest.approx(200 - 113.137, abs=0.01)


def test_reallocation_takes_out_the_isolated_thrusters():
    acc = ThrustReallocation(B, [f"thruster{i}" for i in range(1, 9)], 40.0)
    u_cmd = np.linalg.pinv(B) @ TAU
    np.testing.assert_allclose(acc.update(u_cmd, HEALTHY), TABLE[()], atol=1e-3)
    u = acc.update(u_cmd, Health(1.0, ("thruster2", "thruster6"), {}, "voltage_residual"))
    np.testing.assert_allclose(u, TABLE[(1, 5)], atol=1e-3)
    assert acc.failed == ("thruster2", "thruster6")
    np.testing.assert_allclose(acc.remaining_capability()[:, 1], [56.57, 56.57, 80, 19.80, 19.80, 32], atol=1e-2)


def test_bad_allocation_inputs_are_clear_errors():
    with pytest.raises(RobofdiError, match="6 × p thruster control matrix"):
        pseudo_inverse_allocation(B[:5], TAU)
    with pytest.raises(RobofdiError, match="'tau' must be 6 finite"):
        pseudo_inverse_allocation(B, [1.0, np.nan, 0, 0, 0, 0])
    with pytest.raises(RobofdiError, match="saturation limits"):
        constrained_allocation(B, TAU, 10.0, 40.0)
    with pytest.raises(RobofdiError, match="saturation limits"):
        constrained_allocation(B, TAU, -40.0, -5.0)
    with pytest.raises(RobofdiError, match="effectiveness"):
        pseudo_inverse_allocation(B, TAU, np.ones(7))
    with pytest.raises(RobofdiError, match="'failed'"):
        column_deletion_allocation(B, TAU, [8])
    with pytest.raises(RobofdiError, match=r"'B' must be \(6, 8\)"):
        ThrustReallocation(B.T, [f"thruster{i}" for i in range(1, 9)], 40.0)
    with pytest.raises(RobofdiError, match="method"):
        ThrustReallocation(B, [f"thruster{i}" for i in range(1, 9)], 40.0, method="magic")
