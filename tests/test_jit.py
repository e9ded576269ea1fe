"""The compiled kernels (robofdi.jit) and their pure-Python path give the same diagnosis, bit for bit, on a real arm
run: every arm scheme's residual, alarms, isolation and identified estimate, through a fault that alarms."""
import numpy as np
import pytest

from robofdi import jit
from robofdi.control import ComputedTorque, Quintic
from robofdi.decision import ThresholdDecision
from robofdi.faults import parse_fault_spec
from robofdi.loop import ClosedLoop, Diagnosis, Rates, diagnose_record
from robofdi.models.friction import JointFriction
from robofdi.observers.arm_schemes import SCHEMES, arm_schemes
from robofdi.observers.consistency import ConsistencyDesign
from robofdi.observers.kinematic import WINDOWS
from robofdi.systems.arm import ArmScenario

Q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0)
DQ = (np.pi / 4, np.pi / 4, -np.pi / 4, 0.0, -np.pi / 2, np.pi / 2)


@pytest.fixture(scope="module")
def run():
    """0.2 s of the shipped arm (honest harness: ripple, Stribeck friction, quantised and noisy sensors) with a
    torque step on joint 2 at 0.06 s; the nominal model and the scheme settings of the scenario."""
    scenario = ArmScenario("jit", motion=Quintic(Q0, DQ, 1.0), duration=0.2, rates=Rates(1000.0, 500.0))
    sim = scenario.simulator()
    model = scenario.nominal_model(sim)
    loop = ClosedLoop(sim, ComputedTorque(model, torque_limit=sim.torque_limit), scenario.motion,
                      [parse_fault_spec("actuator_additive:joint2:80@0.06")], {}, scenario.rates)
    return loop.run(0.2, np.asarray(Q0), seed=3), model, scenario.scheme_settings(scenario.rates)


def _diagnose(record, model, settings) -> dict:
    n = model.n
    design = ConsistencyDesign(JointFriction.from_coefficients(np.full((n, 4), 0.1)), np.full((n, 4), 0.5),
                               np.full(n, 2e-4), np.full((n, len(WINDOWS), 3), 1e-4),
                               np.column_stack([np.full(n, 0.05), np.zeros(n), np.full(n, 0.5)]),
                               settings.consistency_gain, settings.T, WINDOWS, np.full((n, len(WINDOWS), 2), 0.2))
    out = {}
    for name, d in arm_schemes(model, settings, None, SCHEMES, consistency=design).items():
        # thresholds at the fault-free start's scale: the fault at 0.06 s alarms, isolates and identifies
        decision = ThresholdDecision(d.components, np.full(len(d.components), 1.0 if name == "consistency" else 2.0),
                                     d.signatures(), blanking=5)
        trace = diagnose_record(record, Diagnosis(d, decision))
        out[name] = trace
    return out


def test_compiled_and_pure_python_kernels_give_the_same_diagnosis(run):
    record, model, settings = run
    compiled = _diagnose(record, model, settings)
    with jit.interpreted():
        python = _diagnose(record, model, settings)
    assert any(t.alarm.any() for t in compiled.values())          # the fault alarms: the alarm path is exercised
    assert any(np.any(t.estimate != 0) for t in compiled.values())  # and something is isolated and identified
    for name in SCHEMES:
        a, b = compiled[name], python[name]
        assert np.array_equal(a.residual, b.residual), name
        assert np.array_equal(a.estimate, b.estimate), name
        assert np.array_equal(a.alarm, b.alarm), name
        assert list(a.isolated) == list(b.isolated), name


def test_interpreted_swaps_every_kernel_and_restores_it():
    from robofdi.observers import kinematic

    before = kinematic._kinematic_step
    with jit.interpreted():
        inside = kinematic._kinematic_step
    assert kinematic._kinematic_step is before
    assert inside is not before or not jit.COMPILED
    assert not hasattr(inside, "py_func")


def test_one_sample_fast_paths_equal_the_array_form(run):
    """Friction torque, envelope features and the symmetric mass matrix of one sample (compiled arithmetic, NumPy's
    tanh/exp) give the bits of their array form (the (N, n) path, NumPy throughout)."""
    from robofdi.decision.envelope import envelope_features

    record, model, _ = run
    n = model.n
    friction = JointFriction.from_coefficients(np.arange(4 * n, dtype=float).reshape(n, 4) / 7.0 - 1.0)
    for y, u in zip(record.signals["y_meas"][::17], record.signals["u"][::17]):
        v = y[n:]
        assert friction.torque(v).tobytes() == friction.torque(v[None])[0].tobytes()
        assert envelope_features(u, v).tobytes() == envelope_features(u[None], v[None])[0].tobytes()
        M = model.mass_matrix(y[:n])
        assert np.array_equal(M, M.T)
        with jit.interpreted():
            assert model.mass_matrix(y[:n]).tobytes() == M.tobytes()
            assert friction.torque(v).tobytes() == friction.torque(v[None])[0].tobytes()


def test_computed_torque_kernels_equal_the_array_form(run):
    """The controller's feedback and clip kernels give the bits of the NumPy expressions, compiled and not; a
    reference given as lists takes the array form."""
    record, model, _ = run
    n = model.n
    limit = np.full(n, 30.0)
    ctrl = ComputedTorque(model, torque_limit=limit)
    motion = Quintic(Q0, DQ, 1.0)
    for t, y in zip(record.time[::13], record.truth_state[::13]):
        qd, vd, ad = (np.asarray(x, dtype=float) for x in motion(t))
        q, v = y[:n], y[n:]
        a = ad + ctrl.kd * (vd - v) + ctrl.kp * (qd - q)
        expected = np.minimum(np.maximum(model.inverse_dynamics(q, v, a), -limit), limit)
        assert ctrl.update(y, (qd, vd, ad)).tobytes() == expected.tobytes()
        assert ctrl.update(y, (list(qd), list(vd), list(ad))).tobytes() == expected.tobytes()
        with jit.interpreted():
            assert ctrl.update(y, (qd, vd, ad)).tobytes() == expected.tobytes()
