"""Tests of robofdi.faults: profiles, Fault validation/serialisation, and the injector's effects and labels."""
import json
import math

import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.faults import (
    FAULT_KINDS,
    ExponentialRise,
    Fault,
    FaultInjector,
    Intermittent,
    Ramp,
    Sinusoid,
    Step,
    profile_from_dict,
)

JOINTS = [f"joint{i}" for i in range(1, 7)]
SENSORS = [f"q{i}" for i in range(1, 7)]
U = np.array([1.0, -2.0, 3.0, 0.5, -0.5, 2.0])
Y = np.array([0.1, 0.2, -0.3, 0.4, 0.5, -0.6])
S = [0.0, 0.001, 0.37, 1.0, 2.5]


def injector(*faults, seed=0):
    return FaultInjector(list(faults), JOINTS, SENSORS, seed=seed)


# --- profiles -------------------------------------------------------------------------------


@pytest.mark.parametrize("s", S)
def test_profiles_match_closed_forms(s):
    assert Step()(s) == 1.0
    assert ExponentialRise(0.3)(s) == pytest.approx(1 - math.exp(-s / 0.3))
    assert Ramp(2.0)(s) == pytest.approx(min(s / 2.0, 1.0))
    assert Sinusoid(1.5, 0.2)(s) == pytest.approx(math.sin(2 * math.pi * 1.5 * s + 0.2))
    assert Intermittent(0.4, 0.25)(s) == (1.0 if (s % 0.4) < 0.1 else 0.0)


@pytest.mark.parametrize(
    "make, field",
    [(lambda: ExponentialRise(0), "tau"), (lambda: Ramp(-1), "duration"), (lambda: Sinusoid(float("nan")), "frequency"),
     (lambda: Intermittent(1.0, 1.5), "duty"), (lambda: Intermittent(0, 0.5), "period")],
)
def test_profile_validation_names_field(make, field):
    with pytest.raises(RobofdiError, match=field):
        make()


def test_profile_dict_round_trip():
    for p in (Step(), ExponentialRise(0.002), Ramp(1.0), Sinusoid(2.0, 0.5), Intermittent(0.5, 0.3)):
        assert profile_from_dict(json.loads(json.dumps(p.to_dict()))) == p


# --- Fault ------------------------------------------------------------------------------------


def test_book_fault_tau3():
    f = Fault("tau3", "actuator_additive", "joint3", onset=1.0, magnitude=60, profile=ExponentialRise(0.002))
    inj = injector(f)
    out = inj.actuate(1.004, U)
    expected = 60 * (1 - math.exp(-(1.004 - 1) / 0.002))
    assert out[2] == pytest.approx(U[2] + expected)
    assert inj.labels["tau3"] == (True, pytest.approx(expected))
    assert f.family == "actuator"


def test_fault_dict_round_trip_and_json():
    d = {"name": "tau3", "kind": "actuator_additive", "target": "joint3", "onset": 1.0, "magnitude": 60,
         "profile": {"type": "exponential_rise", "tau": 0.002}}
    f = Fault.from_dict(d)
    assert f.profile == ExponentialRise(0.002) and f.magnitude == 60.0
    g = Fault("h", "actuator_hard_over", "joint1", onset=0.5, end=2.0, params={"limit": 5, "rate": 2}, seed=3)
    for x in (f, g):
        assert Fault.from_dict(json.loads(json.dumps(x.to_dict()))) == x
    assert hash(g) == hash(Fault.from_dict(g.to_dict()))


def test_fault_active_window():
    f = Fault("a", "sensor_bias", "q1", onset=1.0, end=2.0)
    assert [f.active(t) for t in (0.99, 1.0, 1.5, 2.0, 3.0)] == [False, True, True, False, False]
    assert Fault("b", "sensor_bias", "q1", onset=1.0).active(1e9)


def test_params_are_copied():
    p = {"limit": 1.0}
    f = Fault("h", "actuator_hard_over", "joint1", onset=0, params=p)
    p["limit"] = 99.0
    assert f.params["limit"] == 1.0


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(onset=-1.0), "onset"),
        (dict(onset=float("inf")), "onset"),
        (dict(onset=2.0, end=1.0), "end"),
        (dict(onset=1.0, end=1.0), "end"),
        (dict(magnitude=float("nan")), "magnitude"),
        (dict(magnitude=float("inf")), "magnitude"),
        (dict(kind="actuator_explode"), "kind"),
        (dict(kind="actuator_loss_of_effectiveness", magnitude=1.5), "magnitude"),
        (dict(kind="sensor_noise", target="q1", magnitude=-0.1), "magnitude"),
        (dict(name=""), "name"),
        (dict(params={"limit": 1.0}), "params"),
        (dict(kind="actuator_hard_over"), "limit"),
        (dict(kind="actuator_hard_over", params={"limit": float("nan")}), "limit"),
        (dict(kind="actuator_hard_over", params={"limit": 1.0, "rate": 0.0}), "rate"),
        (dict(kind="sensor_outliers", target="q1", params={"probability": 0.0}), "probability"),
        (dict(kind="sensor_delay", target="q1"), "delay"),
        (dict(seed=-1), "seed"),
    ],
)
def test_fault_validation_names_field(kwargs, field):
    base = dict(name="f", kind="actuator_additive", target="joint1", onset=0.0)
    base.update(kwargs)
    with pytest.raises(RobofdiError, match=field):
        Fault(**base)


def test_from_dict_rejects_unknown_key_and_profile_type():
    d = {"name": "tau3", "kind": "actuator_additive", "target": "joint3", "onset": 1.0}
    with pytest.raises(RobofdiError, match="'magnitud'"):
        Fault.from_dict({**d, "magnitud": 3})
    with pytest.raises(RobofdiError, match="unknown type 'spike'"):
        Fault.from_dict({**d, "profile": {"type": "spike"}})
    with pytest.raises(RobofdiError, match="'tau3'.*profile.*'tua'"):
        Fault.from_dict({**d, "profile": {"type": "exponential_rise", "tua": 1}})
    with pytest.raises(RobofdiError, match="'target'"):
        Fault.from_dict({k: v for k, v in d.items() if k != "target"})


# --- injector validation -------------------------------------------------------------------------


def test_unknown_target_lists_allowed_names():
    f = Fault("tau3", "actuator_additive", "joint7", onset=0.0)
    with pytest.raises(RobofdiError, match=r"'joint7'.*joint1, joint2, joint3, joint4, joint5, joint6"):
        injector(f)
    # actuator faults may not target a sensor name and vice versa
    with pytest.raises(RobofdiError, match="target 'q1'"):
        injector(Fault("x", "actuator_float", "q1", onset=0.0))
    with pytest.raises(RobofdiError, match="target 'joint1'"):
        injector(Fault("x", "sensor_dropout", "joint1", onset=0.0))


def test_duplicate_fault_names():
    f = Fault("a", "actuator_float", "joint1", onset=0.0)
    with pytest.raises(RobofdiError, match="duplicate fault name 'a'"):
        injector(f, Fault("a", "sensor_dropout", "q1", onset=0.0))


@pytest.mark.parametrize(
    "u, field",
    [(np.array([1, 2, np.nan, 4, 5, 6.0]), "'u'"), (np.ones(5), "'u'"), (np.ones((6, 1)), "'u'"), ("abc", "'u'")],
)
def test_bad_input_vector(u, field):
    inj = injector(Fault("a", "actuator_float", "joint1", onset=0.0))
    with pytest.raises(RobofdiError, match=field):
        inj.actuate(0.0, u)
    with pytest.raises(RobofdiError, match="'y'"):
        inj.sense(0.0, np.array([np.inf, 0, 0, 0, 0, 0]))
    with pytest.raises(RobofdiError, match="'t'"):
        inj.actuate(float("nan"), U)


# --- effects and labels ---------------------------------------------------------------------------

ONSET, END = 1.0, 2.0
TIMES = [0.5, ONSET, 1.5, END, 2.5]  # before, at, after onset, at end, after end


def run(fault, times=TIMES, nominal=None):
    """Apply one fault at each time; returns (outputs on the target channel, labels, nominal target values)."""
    inj = injector(fault)
    act = fault.family == "actuator"
    names = JOINTS if act else SENSORS
    ch = names.index(fault.target)
    outs, labels, noms = [], [], []
    for _k, t in enumerate(times):
        x = (U if act else Y).copy() if nominal is None else nominal(t)
        before = x.copy()
        out = inj.actuate(t, x) if act else inj.sense(t, x)
        np.testing.assert_array_equal(x, before)  # input never mutated
        others = [i for i in range(len(names)) if i != ch]
        np.testing.assert_array_equal(out[others], x[others])  # only the target channel changes
        outs.append(out[ch])
        labels.append(inj.labels[fault.name])
        noms.append(x[ch])
    return np.array(outs), labels, np.array(noms)


def check_window(outs, labels, noms):
    """Nominal and inactive label before onset and from end on; label value = faulty - nominal."""
    for k, t in enumerate(TIMES):
        active = ONSET <= t < END
        assert labels[k][0] == active
        assert labels[k][1] == pytest.approx(outs[k] - noms[k])
        if not active:
            assert outs[k] == noms[k] and labels[k][1] == 0.0


@pytest.mark.parametrize(
    "kind, target, magnitude, profile, expected",
    [
        ("actuator_additive", "joint2", 3.0, Ramp(1.0), lambda x, s: x + 3.0 * min(s, 1.0)),
        ("actuator_drift", "joint2", 0.5, Step(), lambda x, s: x + 0.5 * s),
        ("actuator_loss_of_effectiveness", "joint2", 0.4, Step(), lambda x, s: x * 0.6),
        ("actuator_float", "joint2", 0.0, Step(), lambda x, s: 0.0),
        ("sensor_bias", "q3", 0.2, ExponentialRise(0.1), lambda x, s: x + 0.2 * (1 - math.exp(-s / 0.1))),
        ("sensor_drift", "q3", -0.1, Step(), lambda x, s: x - 0.1 * s),
        ("sensor_dropout", "q3", 0.0, Step(), lambda x, s: 0.0),
        ("sensor_scale", "q3", 0.5, Step(), lambda x, s: x * 1.5),
    ],
)
def test_deterministic_kinds(kind, target, magnitude, profile, expected):
    f = Fault("f", kind, target, onset=ONSET, end=END, magnitude=magnitude, profile=profile)
    outs, labels, noms = run(f)
    check_window(outs, labels, noms)
    for k, t in enumerate(TIMES):
        if ONSET <= t < END:
            assert outs[k] == pytest.approx(expected(noms[k], t - ONSET))


@pytest.mark.parametrize("kind, target", [("actuator_lock_in_place", "joint4"), ("sensor_freeze", "q4")])
def test_lock_and_freeze_hold_onset_value(kind, target):
    ramp = lambda t: np.full(6, 10.0 * t)  # noqa: E731 - nominal changes every step
    f = Fault("f", kind, target, onset=ONSET, end=END)
    outs, labels, noms = run(f, nominal=ramp)
    check_window(outs, labels, noms)
    assert outs[1] == pytest.approx(10.0 * ONSET) and outs[2] == pytest.approx(10.0 * ONSET)
    assert labels[2][1] == pytest.approx(10.0 * ONSET - 15.0)


def test_hard_over_slews_at_rate_to_limit():
    f = Fault("h", "actuator_hard_over", "joint1", onset=1.0, params={"limit": 5.0, "rate": 2.0})
    inj = injector(f)
    times = np.arange(0.0, 4.0001, 0.01)
    out = np.array([inj.actuate(t, U)[0] for t in times])  # U[0] = 1
    assert np.all(out[times < 1.0] == 1.0)
    slewing = (times >= 1.0) & (times <= 2.99)
    np.testing.assert_allclose(out[slewing], 1.0 + 2.0 * (times[slewing] - 1.0), atol=1e-9)
    assert np.all(out[times >= 3.0 - 1e-9] == 5.0)
    assert inj.labels["h"] == (True, 4.0)
    # without rate: jumps to the limit at once; works downwards too
    g = Fault("g", "actuator_hard_over", "joint1", onset=1.0, params={"limit": -3.0})
    inj = injector(g)
    assert inj.actuate(0.9, U)[0] == 1.0 and inj.actuate(1.0, U)[0] == -3.0


def test_hard_over_recovers_after_end():
    f = Fault("h", "actuator_hard_over", "joint1", onset=ONSET, end=END, params={"limit": 5.0, "rate": 1.0})
    outs, labels, noms = run(f)
    check_window(outs, labels, noms)
    assert outs[2] == pytest.approx(1.5)


def test_intermittent_periodic_pattern():
    f = Fault("i", "actuator_intermittent", "joint1", onset=1.0, magnitude=2.0, params={"period": 0.4, "duty": 0.25})
    inj = injector(f)
    for t in (0.5, 1.0, 1.05, 1.15, 1.3, 1.41, 1.55):
        out = inj.actuate(t, U)[0]
        on = t >= 1.0 and ((t - 1.0) % 0.4) < 0.1
        assert out == pytest.approx(U[0] + (2.0 if on else 0.0)), t
        assert inj.labels["i"][1] == pytest.approx(2.0 if on else 0.0)
    default = Fault("d", "actuator_intermittent", "joint1", onset=0.0, magnitude=1.0)
    inj = injector(default)  # period 0.5, duty 0.5
    assert [inj.actuate(t, U)[0] - U[0] for t in (0.0, 0.2, 0.3, 0.5, 0.8)] == pytest.approx([1, 1, 0, 1, 0])


def _series(fault, seed=0, n=400, dt=0.01):
    inj = injector(fault, seed=seed)
    act = fault.family == "actuator"
    ch = (JOINTS if act else SENSORS).index(fault.target)
    return np.array([(inj.actuate(k * dt, U) if act else inj.sense(k * dt, Y))[ch] for k in range(n)]), inj


STOCHASTIC = [
    dict(name="n", kind="sensor_noise", target="q2", onset=1.0, magnitude=0.05),
    dict(name="o", kind="sensor_outliers", target="q2", onset=1.0, magnitude=1.0, params={"probability": 0.2}),
    dict(name="i", kind="actuator_intermittent", target="joint2", onset=1.0, magnitude=1.0,
         params={"period": 0.3, "duty": 0.4}),
]


@pytest.mark.parametrize("spec", STOCHASTIC, ids=lambda s: s["kind"])
def test_seeded_faults_reproducible(spec):
    a, inj = _series(Fault(**spec, seed=7))
    b, _ = _series(Fault(**spec, seed=7))
    c, _ = _series(Fault(**spec, seed=8))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    nominal = U[1] if spec["kind"].startswith("actuator") else Y[1]
    assert np.all(a[:100] == nominal)  # nothing before onset
    inj.reset()  # reset replays the same randomness
    np.testing.assert_array_equal(np.array([inj.actuate(k * 0.01, U)[1] if spec["kind"].startswith("actuator")
                                            else inj.sense(k * 0.01, Y)[1] for k in range(400)]), a)


@pytest.mark.parametrize("spec", STOCHASTIC[:2], ids=lambda s: s["kind"])
def test_unseeded_faults_follow_injector_seed(spec):
    a, _ = _series(Fault(**spec), seed=1)
    b, _ = _series(Fault(**spec), seed=1)
    c, _ = _series(Fault(**spec), seed=2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_noise_and_outlier_statistics():
    n, _ = _series(Fault("n", "sensor_noise", "q2", onset=0.0, magnitude=0.05, seed=1), n=4000)
    assert np.std(n - Y[1]) == pytest.approx(0.05, rel=0.1)
    o, _ = _series(Fault("o", "sensor_outliers", "q2", onset=0.0, magnitude=1.0, params={"probability": 0.2}, seed=1),
                   n=4000)
    d = o - Y[1]
    assert set(np.round(np.unique(d), 12)) <= {-1.0, 0.0, 1.0}
    assert np.mean(d != 0) == pytest.approx(0.2, abs=0.03)
    assert np.any(d > 0) and np.any(d < 0)
    i, _ = _series(Fault("i", "actuator_intermittent", "joint2", onset=0.0, magnitude=1.0,
                         params={"period": 0.2, "duty": 0.3}, seed=1), n=20000)
    assert np.mean(i - U[1]) == pytest.approx(0.3, abs=0.06)


def test_sensor_delay_returns_delayed_value():
    f = Fault("d", "sensor_delay", "q1", onset=1.0, end=3.0, params={"delay": 0.05})
    inj = injector(f)
    dt = 0.01
    for k in range(400):
        t = k * dt
        out = inj.sense(t, np.full(6, 2.0 * t))[0]
        if 1.0 <= t < 3.0:
            assert out == pytest.approx(2.0 * (t - 0.05)), t
            assert inj.labels["d"] == (True, pytest.approx(-0.1))
        else:
            assert out == pytest.approx(2.0 * t) and inj.labels["d"] == (False, 0.0)
    # not enough history: the oldest sample is used
    g = Fault("g", "sensor_delay", "q1", onset=0.0, params={"delay": 1.0})
    inj = injector(g)
    assert [inj.sense(t, np.full(6, t))[0] for t in (0.0, 0.1, 0.2)] == [0.0, 0.0, 0.0]


def test_faults_on_same_channel_compose_in_order():
    a = Fault("a", "actuator_additive", "joint1", onset=0.0, magnitude=1.0)
    b = Fault("b", "actuator_loss_of_effectiveness", "joint1", onset=0.0, magnitude=0.5)
    inj = injector(a, b)
    out = inj.actuate(0.1, U)
    assert out[0] == pytest.approx((U[0] + 1.0) * 0.5)
    assert inj.labels == {"a": (True, 1.0), "b": (True, pytest.approx(-1.0))}
    assert inj.label_names == ["a", "b"]


def test_reset_clears_held_values_and_labels():
    f = Fault("l", "actuator_lock_in_place", "joint1", onset=0.0)
    inj = injector(f)
    assert inj.actuate(0.0, np.full(6, 3.0))[0] == 3.0
    assert inj.actuate(0.1, np.full(6, 4.0))[0] == 3.0
    inj.reset()
    assert inj.labels == {"l": (False, 0.0)}
    assert inj.actuate(0.0, np.full(6, 4.0))[0] == 4.0


def test_every_kind_is_covered():
    covered = {"actuator_additive", "actuator_drift", "actuator_loss_of_effectiveness", "actuator_lock_in_place",
               "actuator_float", "actuator_hard_over", "actuator_intermittent", "sensor_bias", "sensor_drift",
               "sensor_freeze", "sensor_dropout", "sensor_scale", "sensor_noise", "sensor_delay", "sensor_outliers"}
    assert set(FAULT_KINDS) == covered
