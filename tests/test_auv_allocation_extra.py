"""The survey's remaining allocation pieces (Antonelli, Sec. 5 and eq. (7)): the Phantom S3 thruster matrix,
null-space redistribution and direction-preserving scaling under thrust limits."""
import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.ftc.allocation import (
    ThrustReallocation, capability, direction_preserving_allocation, null_space_allocation, pseudo_inverse_allocation,
)
from robofdi.models.auv import phantom_thruster_matrix
from robofdi.protocols import Health

s = 0.5 ** 0.5
B = np.array([                       # the ODIN-like B (FRD) of the digest
    [s, s, s, s, 0, 0, 0, 0],
    [-s, s, -s, s, 0, 0, 0, 0],
    [0, 0, 0, 0, 1, 1, 1, 1],
    [0, 0, 0, 0, 0.2475, -0.2475, -0.2475, 0.2475],
    [0, 0, 0, 0, -0.2475, -0.2475, 0.2475, 0.2475],
    [-0.4, 0.4, 0.4, -0.4, 0, 0, 0, 0]])


def test_phantom_thruster_matrix_has_the_pattern_of_eq7_and_rank_4():
    P = phantom_thruster_matrix()
    pattern = np.abs(P) > 1e-12
    expected = np.array([[1, 1, 0, 0], [0, 0, 1, 1], [0, 0, 1, 1], [0, 0, 1, 1], [1, 1, 0, 0], [1, 1, 0, 0]], bool)
    assert P.shape == (6, 4) and (pattern == expected).all()
    assert np.linalg.matrix_rank(P) == 4                       # not all directions independently actuated
    with pytest.raises(RobofdiError, match="pattern of eq. \\(7\\)"):
        phantom_thruster_matrix(aft_z=0.0)


def test_null_space_redistribution_keeps_the_wrench_and_respects_the_limits():
    tau = np.array([30.0, 15.0, 20.0, 2.0, 2.0, 5.0])
    e = np.ones(8)
    e[[1, 5]] = 0.0                                             # thrusters 2 and 6 off: B_f is square, no freedom
    free = pseudo_inverse_allocation(B, tau)
    limit = 16.5       # the minimum-norm solution saturates (19.0 N); 15.9 N is the least max |u| here
    r = null_space_allocation(B, tau, -limit, limit)
    assert r.feasible and np.abs(r.u).max() <= limit + 1e-9
    assert np.abs(B @ r.u - tau).max() < 1e-7
    np.testing.assert_allclose(null_space_allocation(B, tau, -40, 40).u, free.u, atol=1e-12)   # nothing to move
    square = null_space_allocation(B, tau, -20, 20, e)           # rank 6 with 6 columns: the saturation stays
    assert not square.feasible and np.abs(square.u).max() <= 20 + 1e-12


def test_direction_preserving_scaling_cuts_the_size_not_the_direction():
    tau = np.array([200.0, 50.0, 0.0, 0.0, 0.0, 10.0])          # beyond the horizontal capability
    r = direction_preserving_allocation(B, tau, -40, 40)
    alpha = r.attained @ tau / (tau @ tau)
    np.testing.assert_allclose(r.attained, alpha * tau, atol=1e-7)
    assert 0 < alpha < 1 and np.abs(r.u).max() <= 40 + 1e-9
    np.testing.assert_allclose(r.unattained, (1 - alpha) * tau, atol=1e-7)
    surge = direction_preserving_allocation(B, np.array([200.0, 0, 0, 0, 0, 0]), -40, 40)
    assert surge.attained[0] == pytest.approx(capability(B, -40, 40)[0, 1], rel=1e-6)        # = the LP capacity
    small = np.array([30.0, 15.0, 20.0, 2.0, 2.0, 5.0])
    np.testing.assert_allclose(direction_preserving_allocation(B, small, -40, 40).u,
                               pseudo_inverse_allocation(B, small).u, atol=1e-12)


def test_reallocation_offers_both_methods_and_refuses_bad_input():
    u_cmd = np.full(8, 30.0)
    for method in ("null_space", "direction_preserving"):
        acc = ThrustReallocation(B, [f"thruster{i}" for i in range(1, 9)], 40.0, method)
        u = acc.update(u_cmd, Health(isolated=("thruster2",)))
        assert u[1] == 0.0 and np.abs(u).max() <= 40 + 1e-9
    with pytest.raises(RobofdiError, match="'iterations'"):
        null_space_allocation(B, np.zeros(6), -1, 1, iterations=0)
    with pytest.raises(RobofdiError, match="finite saturation limits"):
        direction_preserving_allocation(B, np.zeros(6), -np.inf, np.inf)
