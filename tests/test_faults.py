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
    g = Fault("h", "actuator_hard_over", "joint1", onset=0.5, end=2.0, profile=Ramp(0.5), params={"limit": 5}, seed=3)
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
        (dict(kind="actuator_hard_over", params={"limit": 1.0, "rate": 2.0}), "rate"),
        (dict(kind="actuator_drift", profile=ExponentialRise(1.0)), "profile"),
        (dict(kind="actuator_lock_in_place", profile=Sinusoid(1.0)), "profile"),
        (dict(kind="sensor_delay", target="q1", params={"delay": 0.1}, profile=Sinusoid(2.0)), "profile"),
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
    inj = injector(Fault("a", "actuator_float", "joint1", onset=0.0), Fault("b", "sensor_bias", "q1", onset=0.0))
    with pytest.raises(RobofdiError, match=field):
        inj.actuate(0.0, u)
    with pytest.raises(RobofdiError, match="'y'"):
        inj.sense(0.0, np.array([np.inf, 0, 0, 0, 0, 0]))
    with pytest.raises(RobofdiError, match="'t'"):
        inj.actuate(float("nan"), U)


def test_a_family_without_faults_passes_its_vector_through_untouched():
    inj = injector(Fault("a", "sensor_bias", "q1", onset=0.0, magnitude=1.0))
    assert inj.actuate(0.5, U) is U and inj.emulate(0.5, U) is U
    assert inj.sense(0.5, Y)[0] == Y[0] + 1.0


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
        ("actuator_scale", "joint2", 0.25, Ramp(2.0), lambda x, s: x * (1 + 0.25 * min(s / 2.0, 1.0))),
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


def test_hard_over_slews_along_a_ramp_to_limit():
    f = Fault("h", "actuator_hard_over", "joint1", onset=1.0, profile=Ramp(2.0), params={"limit": 5.0})
    inj = injector(f)
    times = np.arange(0.0, 4.0001, 0.01)
    out = np.array([inj.actuate(t, U)[0] for t in times])  # U[0] = 1
    assert np.all(out[times < 1.0] == 1.0)
    slewing = (times >= 1.0) & (times <= 2.99)
    np.testing.assert_allclose(out[slewing], 1.0 + 2.0 * (times[slewing] - 1.0), atol=1e-9)
    assert np.all(out[times >= 3.0 - 1e-9] == 5.0)
    assert inj.labels["h"] == (True, 4.0)
    # with a step: jumps to the limit at once; works downwards too
    g = Fault("g", "actuator_hard_over", "joint1", onset=1.0, params={"limit": -3.0})
    inj = injector(g)
    assert inj.actuate(0.9, U)[0] == 1.0 and inj.actuate(1.0, U)[0] == -3.0


def test_hard_over_recovers_after_end():
    f = Fault("h", "actuator_hard_over", "joint1", onset=ONSET, end=END, profile=Ramp(4.0), params={"limit": 5.0})
    outs, labels, noms = run(f)
    check_window(outs, labels, noms)
    assert outs[2] == pytest.approx(1.5)


def test_intermittent_is_a_profile():
    f = Fault("i", "actuator_additive", "joint1", onset=1.0, magnitude=2.0, profile=Intermittent(0.4, 0.25))
    inj = injector(f)
    for t in (0.5, 1.0, 1.05, 1.15, 1.3, 1.41, 1.55):
        out = inj.actuate(t, U)[0]
        on = t >= 1.0 and ((t - 1.0) % 0.4) < 0.1
        assert out == pytest.approx(U[0] + (2.0 if on else 0.0)), t
        assert inj.labels["i"][1] == pytest.approx(2.0 if on else 0.0)
    with pytest.raises(RobofdiError, match="unknown kind 'actuator_intermittent'"):
        Fault("d", "actuator_intermittent", "joint1", onset=0.0, magnitude=1.0)


def _series(fault, seed=0, n=400, dt=0.01):
    inj = injector(fault, seed=seed)
    act = fault.family == "actuator"
    ch = (JOINTS if act else SENSORS).index(fault.target)
    return np.array([(inj.actuate(k * dt, U) if act else inj.sense(k * dt, Y))[ch] for k in range(n)]), inj


STOCHASTIC = [
    dict(name="n", kind="sensor_noise", target="q2", onset=1.0, magnitude=0.05),
    dict(name="o", kind="sensor_outliers", target="q2", onset=1.0, magnitude=1.0, params={"probability": 0.2}),
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
    covered = {"actuator_additive", "actuator_drift", "actuator_loss_of_effectiveness", "actuator_scale",
               "actuator_lock_in_place",
               "actuator_float", "actuator_hard_over", "sensor_bias", "sensor_drift",
               "sensor_freeze", "sensor_dropout", "sensor_scale", "sensor_noise", "sensor_delay", "sensor_outliers",
               "component_friction", "component_mass", "component_thruster_blocking", "component_thruster_flooding",
               # hydraulic rig (Table 1 of book ch. 6), covered in tests/test_hydraulic.py
               "component_open_winding", "component_valve_sticking", "component_leak",
               "component_wing_damage"}   # flight surrogate (book ch. 5): tests/test_ch5_errors.py, test_ch5_scenarios.py
    assert set(FAULT_KINDS) == covered


# --- profiles honoured by every kind, offline emulation, saturation, components ----------------------------

@pytest.mark.parametrize(
    "kind, target, expected",
    [
        ("actuator_lock_in_place", "joint2", lambda x, x0, p: x + p * (x0 - x)),
        ("actuator_float", "joint2", lambda x, x0, p: (1 - p) * x),
        ("sensor_freeze", "q3", lambda x, x0, p: x + p * (x0 - x)),
        ("sensor_dropout", "q3", lambda x, x0, p: (1 - p) * x),
        ("actuator_loss_of_effectiveness", "joint2", lambda x, x0, p: x * (1 - 0.8 * p)),
    ],
)
def test_blending_kinds_follow_their_profile(kind, target, expected):
    """A seizing joint or a fading sensor: the nominal value blends into the faulty one along p(t − onset)."""
    tau = 0.2
    f = Fault("f", kind, target, onset=1.0, magnitude=0.8 if "effectiveness" in kind else 0.0, profile=ExponentialRise(tau))
    ramp = lambda t: np.full(6, 3.0 + 2.0 * t)  # noqa: E731 - nominal changes every step
    times = [0.5, 1.0, 1.1, 1.3, 2.0]
    outs, _, noms = run(f, times=times, nominal=ramp)
    x0 = 3.0 + 2.0 * 1.0
    for k, t in enumerate(times):
        p = 1 - math.exp(-(t - 1.0) / tau) if t >= 1.0 else None
        assert outs[k] == pytest.approx(noms[k] if p is None else expected(noms[k], x0, p)), t


def test_delay_grows_with_its_profile_and_outliers_scale():
    f = Fault("d", "sensor_delay", "q1", onset=1.0, profile=Ramp(1.0), params={"delay": 0.2})
    inj = injector(f)
    for k in range(300):
        t = k * 0.01
        out = inj.sense(t, np.full(6, 2.0 * t))[0]
    # at t = 2.99 the delay is 0.2 (ramp complete); at 1.5 it was 0.1
    assert out == pytest.approx(2.0 * (2.99 - 0.2))
    g = Fault("o", "sensor_outliers", "q1", onset=0.0, magnitude=1.0, profile=Ramp(10.0), params={"probability": 1.0}, seed=2)
    inj = injector(g)
    d = [abs(inj.sense(t, Y)[0] - Y[0]) for t in (1.0, 5.0)]
    assert d == pytest.approx([0.1, 0.5])


@pytest.mark.parametrize("kind, magnitude, profile", [
    ("actuator_additive", 7.0, ExponentialRise(0.05)),
    ("actuator_drift", -3.0, Step()),
    ("actuator_loss_of_effectiveness", 0.6, Ramp(0.5)),
])
def test_offline_emulation_is_exact_for_invertible_kinds(kind, magnitude, profile):
    """Told ū, a plant with the fault would receive faulty(ū) = u, the command the fault-free plant really got."""
    f = Fault("f", kind, "joint3", onset=1.0, magnitude=magnitude, profile=profile)
    emulator, online = injector(f), injector(f)
    for t in np.arange(0.0, 3.0, 0.01):
        u = U * (1 + t)
        u_diag = emulator.emulate(t, u)
        np.testing.assert_allclose(online.actuate(t, u_diag), u, rtol=1e-12, atol=1e-12)
        assert emulator.labels["f"][1] == pytest.approx(u[2] - u_diag[2])
        assert emulator.labels["f"][0] == (t >= 1.0)


@pytest.mark.parametrize("kind", ["actuator_lock_in_place", "actuator_float", "actuator_hard_over", "component_mass"])
def test_offline_refuses_what_it_cannot_emulate(kind):
    params = {"limit": 1.0} if kind == "actuator_hard_over" else {}
    target = "link3" if kind.startswith("component") else "joint3"
    f = Fault("f", kind, target, onset=1.0, params=params)
    inj = FaultInjector([f], JOINTS, SENSORS, component_kinds={"component_mass": ["link3"]})
    with pytest.raises(RobofdiError, match=f"'f'.*{kind}.*offline.*online"):
        inj.check_offline()


def test_actuator_labels_measure_what_the_saturated_plant_received():
    limit = np.full(6, 4.0)
    f = Fault("f", "actuator_additive", "joint3", onset=0.0, magnitude=10.0)
    inj = FaultInjector([f], JOINTS, SENSORS, saturate=lambda u: np.clip(u, -limit, limit))
    out = inj.actuate(0.1, U)              # U[2] = 3: 3 + 10 clips to 4, so the plant got only +1
    assert out[2] == 13.0                   # the faulty command itself is not clipped by the injector
    assert inj.labels["f"] == (True, pytest.approx(1.0))
    g = Fault("g", "actuator_additive", "joint3", onset=0.0, magnitude=-2.0)
    inj = FaultInjector([g], JOINTS, SENSORS, saturate=lambda u: np.clip(u, -limit, limit))
    inj.actuate(0.1, U)
    assert inj.labels["g"] == (True, pytest.approx(-2.0))


def test_component_faults_give_their_change_and_labels():
    kinds = {"component_friction": ["joint2", "joint3"], "component_mass": ["link6", "payload"]}
    f = Fault("fr", "component_friction", "joint3", onset=1.0, end=2.0, magnitude=1.5, profile=Ramp(0.5))
    m = Fault("m", "component_mass", "payload", onset=0.5, magnitude=2.0)
    inj = FaultInjector([f, m], JOINTS, SENSORS, component_kinds=kinds)
    assert inj.components(0.2) == [("component_friction", "joint3", 0.0), ("component_mass", "payload", 0.0)]
    assert inj.components(1.25) == [("component_friction", "joint3", pytest.approx(0.75)),
                                    ("component_mass", "payload", 2.0)]
    assert inj.labels == {"fr": (True, pytest.approx(0.75)), "m": (True, 2.0)}
    assert inj.components(2.5)[0] == ("component_friction", "joint3", 0.0) and inj.labels["fr"] == (False, 0.0)
    with pytest.raises(RobofdiError, match="'link9'.*link6, payload"):
        FaultInjector([Fault("x", "component_mass", "link9", onset=0.0)], JOINTS, SENSORS, component_kinds=kinds)


def test_check_faults_refuses_what_a_run_cannot_carry_in_one_line():
    """One check for every scenario and the command line: the onset inside the run, targets the plant has,
    kinds offline injection can emulate."""
    from robofdi.faults import check_faults
    from robofdi.systems.linear import wheel_speed_plant

    plant = wheel_speed_plant()
    ok = Fault("bias", "sensor_bias", plant.sensor_channels[0], onset=1.0, magnitude=0.1)
    check_faults([ok], plant, duration=2.0)
    with pytest.raises(RobofdiError, match=r"--fault 'bias': onset 3 s is not inside the run \(duration 2 s\)"):
        check_faults([Fault("bias", "sensor_bias", plant.sensor_channels[0], onset=3.0, magnitude=0.1)],
                     duration=2.0, label="--fault")
    with pytest.raises(RobofdiError, match="nowhere"):
        check_faults([Fault("x", "actuator_additive", "nowhere", onset=1.0, magnitude=1.0)], plant)
    with pytest.raises(RobofdiError, match="cannot be emulated offline"):
        check_faults([Fault("f", "actuator_float", plant.actuators[0], onset=1.0)], plant, injection="offline")
    with pytest.raises(RobofdiError, match="expected Fault objects"):
        check_faults(["sensor_bias:encL:0.1@1"])
