"""Tests of robofdi.observers.spectral.ripple_initial_parameters: recovering a position-periodic ripple
a + b sin(c x + d) from a synthetic fault-free residual (Caccavale & Villani Sec. 7, eq. (50))."""
import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.observers.diagnostic import RippleModel
from robofdi.observers.spectral import ripple_initial_parameters

N = 6000
# per joint: (start, travel) of the sweep [rad], and the ripple a + b sin(c x + d) in rad/s per sample
JOINTS = [
    dict(start=-1.2, travel=2.0, a=2e-4, b=1.0e-3, c=40.0, d=0.7),
    dict(start=0.30, travel=0.01, a=1e-4, b=5.0e-4, c=30.0, d=2.0),    # barely moves: no estimate
    dict(start=0.40, travel=-1.0, a=-3e-4, b=2.0e-4, c=72.0, d=-2.5),
]


def synthetic(noise=2e-5, seed=0):
    """A there-and-back sweep of every joint with a smooth (non-uniform in x) speed profile."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, N)
    shape = 0.5 * (1 - np.cos(2 * np.pi * s))                           # 0 → 1 → 0
    x = np.stack([j["start"] + j["travel"] * shape for j in JOINTS], axis=1)
    r = np.stack([j["a"] + j["b"] * np.sin(j["c"] * x[:, i] + j["d"]) for i, j in enumerate(JOINTS)], axis=1)
    return x, r + noise * rng.standard_normal(r.shape)


def wrapped(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def test_recovers_frequency_amplitude_and_phase():
    x, r = synthetic()
    theta = ripple_initial_parameters(x, r)
    n = len(JOINTS)
    model = RippleModel(n)
    assert theta.shape == (model.p,)
    pos, (a, b, c, d, e, f, g) = model.split(theta)
    np.testing.assert_array_equal(pos, 0.0)                              # position rows start at 0
    for i in (0, 2):
        j = JOINTS[i]
        assert c[i] == pytest.approx(j["c"], rel=0.01)
        assert b[i] == pytest.approx(j["b"], rel=0.05)
        assert abs(wrapped(d[i] - j["d"])) < 0.05
        assert f[i] == c[i] and e[i] == 0 and g[i] == 0                  # torque term starts off, θ_f = θ_c
    # the model with θ₀ (τ = 0) reproduces the ripple up to the offset θ_a, which starts at 0
    eta, _ = model.evaluate(theta, x[-1], np.zeros(n))
    truth = np.array([j["b"] * np.sin(j["c"] * x[-1, i] + j["d"]) for i, j in enumerate(JOINTS)])
    np.testing.assert_allclose(eta[n:][[0, 2]], truth[[0, 2]], atol=0.1 * 1e-3)


def test_a_joint_that_does_not_travel_stays_at_zero():
    x, r = synthetic()
    _, cols = RippleModel(3).split(ripple_initial_parameters(x, r))
    np.testing.assert_array_equal(cols[:, 1], 0.0)
    x[:, 0] = 0.5                                                         # now joint 1 stands still too
    _, cols = RippleModel(3).split(ripple_initial_parameters(x, r))
    np.testing.assert_array_equal(cols[:, 0], 0.0)
    assert cols[2, 2] == pytest.approx(JOINTS[2]["c"], rel=0.01)


@pytest.mark.parametrize("mutate", [
    lambda x, r: (x[:, :2], r),                 # shapes differ
    lambda x, r: (x[:, 0], r[:, 0]),            # 1-D
    lambda x, r: (x[:10], r[:10]),              # too short
])
def test_bad_shapes_are_rejected(mutate):
    x, r = synthetic()
    with pytest.raises(RobofdiError, match="positions"):
        ripple_initial_parameters(*mutate(x, r))


@pytest.mark.parametrize("which, value", [(0, np.nan), (1, np.inf)])
def test_non_finite_input_is_rejected(which, value):
    data = list(synthetic())
    data[which][100, 1] = value
    with pytest.raises(RobofdiError, match="finite"):
        ripple_initial_parameters(*data)


def test_phase_of_a_sweep_far_from_zero():
    s = np.linspace(0.0, 1.0, N)
    x = (1.5 + 2.0 * 0.5 * (1 - np.cos(2 * np.pi * s)))[:, None]
    r = 1e-3 * np.sin(40.3 * x + 0.7)
    _, (a, b, c, d, *_) = RippleModel(1).split(ripple_initial_parameters(x, r))
    assert c[0] == pytest.approx(40.3, rel=0.01)
    assert abs(wrapped(d[0] - 0.7)) < 0.05
