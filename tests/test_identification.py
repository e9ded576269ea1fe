"""Tests of robofdi.decision.Identification: fault identification gated by isolation (Caccavale & Villani Sec. 6:
f̂ = 0 before a fault is declared; afterwards the isolated components carry the estimate)."""
import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.decision import Identification

NAMES = ["joint1", "joint2", "joint3"]


def test_zero_before_any_isolation():
    ident = Identification(NAMES, ["level", "increment", "level"])
    for k in range(5):
        out = ident.update(np.array([1.0, 2.0, 3.0]) * (k + 1), [])
        np.testing.assert_array_equal(out, np.zeros(3))


def test_level_entry_passes_the_candidate_through_from_isolation_on():
    ident = Identification(NAMES, ["level", "level", "level"])
    ident.update(np.array([5.0, 6.0, 7.0]), [])
    out = ident.update(np.array([1.5, 2.5, 3.5]), ["joint2"])
    np.testing.assert_array_equal(out, [0.0, 2.5, 0.0])          # the isolation sample itself is passed
    out = ident.update(np.array([-4.0, 8.0, 9.0]), [])            # isolation is kept once declared
    np.testing.assert_array_equal(out, [0.0, 8.0, 0.0])


def test_increment_entry_sums_from_the_isolation_sample_included():
    ident = Identification(NAMES, ["level", "increment", "level"])
    steps = [np.array([0.0, 0.1, 0.0]), np.array([0.0, 0.2, 0.0]), np.array([0.0, 0.3, 0.0]), np.array([0.0, -0.05, 0.0])]
    ident.update(np.array([0.0, 100.0, 0.0]), [])                 # before isolation: not summed
    outs = [ident.update(steps[0], ["joint2"])] + [ident.update(s, []) for s in steps[1:]]
    np.testing.assert_allclose([o[1] for o in outs], [0.1, 0.3, 0.6, 0.55])
    assert all(o[0] == 0 and o[2] == 0 for o in outs)


def test_several_targets_isolated_at_different_times():
    ident = Identification(NAMES, ["increment", "level", "increment"])
    c = np.array([1.0, 10.0, 2.0])
    np.testing.assert_array_equal(ident.update(c, ["joint1"]), [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(ident.update(c, ["joint2", "joint3"]), [2.0, 10.0, 2.0])
    np.testing.assert_array_equal(ident.update(2 * c, []), [4.0, 20.0, 6.0])


def test_unknown_names_are_ignored_and_reset_clears():
    ident = Identification(NAMES, ["level", "increment", "level"])
    np.testing.assert_array_equal(ident.update(np.ones(3), ["joint9", "sensor_x"]), np.zeros(3))
    np.testing.assert_array_equal(ident.update(np.ones(3), ["joint9", "joint2"]), [0.0, 1.0, 0.0])
    ident.reset()
    np.testing.assert_array_equal(ident.update(np.ones(3), []), np.zeros(3))
    np.testing.assert_array_equal(ident.update(np.ones(3), ["joint2"]), [0.0, 1.0, 0.0])   # the sum restarts


@pytest.mark.parametrize("components, modes, field", [
    (NAMES, ["level", "level"], "same length"),
    (NAMES, ["level", "integral", "level"], "modes"),
])
def test_configuration_is_validated(components, modes, field):
    with pytest.raises(RobofdiError, match=field):
        Identification(components, modes)
