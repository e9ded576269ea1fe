"""Batch forms of the arm diagnosers (robofdi.lockstep.observers) and of the nominal-model memo
(robofdi.lockstep.evaluations): on real closed-loop runs of different robot instances and lengths, row i of every
batch output equals run i's own diagnoser stepped alone, bit for bit, compiled and on the pure-Python path."""
import numpy as np
import pytest

from robofdi import RobofdiError, jit
from robofdi.control import ComputedTorque, Quintic
from robofdi.faults import parse_fault_spec
from robofdi.lockstep.evaluations import BatchEvaluations, batch_evaluations
from robofdi.observers import diagnostic
from robofdi.lockstep.observers import batch_form
from robofdi.loop import ClosedLoop, Rates, diagnoser_inputs
from robofdi.models.friction import JointFriction
from robofdi.observers.arm_schemes import BOOK_SCHEMES, arm_schemes
from robofdi.observers.diagnostic import Adaptive, DiagnosticObserver, RippleModel
from robofdi.observers.momentum import MomentumObserver
from robofdi.systems.arm import ArmScenario

Q0 = (np.pi / 2, -2 * np.pi / 3, np.pi / 6, -np.pi / 2, np.pi / 2, 0.0)
DQ = (np.pi / 4, np.pi / 4, -np.pi / 4, 0.0, -np.pi / 2, np.pi / 2)
# (robot instance seed, duration [s], fault): runs of different lengths, longest first (the engine's order)
RUNS = ((1, 0.3, "actuator_additive:joint2:80@0.1"), (2, 0.26, None), (3, 0.2, "sensor_bias:joint3_pos:0.01@0.08"),
        (4, 0.2, None))


@pytest.fixture(scope="module")
def runs():
    """Per run: its nominal model (the robot instance's seeded mismatch) and the (y, ū) its diagnosers receive at
    500 Hz; the scheme settings; one θ̂₀ per run for the adaptive scheme (drawn, non-zero)."""
    out = []
    for seed, duration, fault in RUNS:
        scenario = ArmScenario("lockstep", motion=Quintic(Q0, DQ, 1.0), duration=duration,
                               rates=Rates(1000.0, 500.0), seed=seed)
        sim = scenario.simulator()
        model = scenario.nominal_model(sim)
        loop = ClosedLoop(sim, ComputedTorque(model, torque_limit=sim.torque_limit), scenario.motion,
                          [parse_fault_spec(fault)] if fault else [], {}, scenario.rates)
        y, u = diagnoser_inputs(loop.run(duration, np.asarray(Q0), seed=seed), scenario.rates)
        out.append((model, y, u))
    settings = scenario.scheme_settings(scenario.rates)
    n = out[0][0].n
    rng = np.random.default_rng(7)
    scale = np.concatenate([np.full(n, 1e-5), np.tile([1e-3, 1e-3, 2.0, 1.0, 1e-3, 1.0, 1.0], n)])
    theta0 = [scale * rng.uniform(-1, 1, 8 * n) for _ in out]
    return out, settings, theta0


def _lockstep(runs, settings, theta0, batches=None):
    """Step every book scheme of every run alone and the batch forms together (the same Y and U objects handed to
    every batch form at a sample, as the engine does), asserting row i = run i at every sample. Returns the
    batch forms (reset again by a second call) and the largest |r| per scheme."""
    singles = {name: [arm_schemes(model, settings, th, [name])[name] for (model, _, _), th in zip(runs, theta0)]
               for name in BOOK_SCHEMES}
    if batches is None:
        batches = {name: batch_form(ds) for name, ds in singles.items()}
    else:
        for b in batches.values():
            b.reset()
    assert all(b is not None for b in batches.values())
    largest = dict.fromkeys(BOOK_SCHEMES, 0.0)
    for k in range(len(runs[0][1])):
        active = [(y[k], u[k]) for _, y, u in runs if k < len(y)]
        Y, U = np.array([y for y, _ in active]), np.array([u for _, u in active])
        Y.flags.writeable = U.flags.writeable = False
        for name, batch in batches.items():
            R, E = batch.update(Y, U)
            assert R.shape[0] == E.shape[0] == len(active), (name, k)
            for i, (y, u) in enumerate(active):
                res = singles[name][i].update(y, u)
                assert np.array_equal(R[i], res.r), (name, k, i)
                assert np.array_equal(E[i], res.estimate), (name, k, i)
            largest[name] = max(largest[name], float(np.max(np.abs(R))))
    return batches, largest


def test_batch_forms_equal_each_run_alone_compiled_and_interpreted(runs):
    data, settings, theta0 = runs
    batches, largest = _lockstep(data, settings, theta0)
    assert all(v > 0 for v in largest.values()), largest         # every scheme's residual moved
    with jit.interpreted():
        assert not hasattr(diagnostic._observer_step_each, "py_func")      # the batch kernels are swapped too
        _lockstep(data, settings, theta0, batches)                # after reset, on the pure-Python path


def test_state_space_and_observer_variants_equal_each_run_alone(runs):
    """Residuals in the state space, x̂'s model term at the estimate (eq. (23) as printed), other gains."""
    data, settings, _ = runs
    T, n = settings.T, data[0][0].n
    variants = [dict(residual_space="state"), dict(eval_at="estimate", K1=0.3, K2=0.05),
                dict(velocity="backward_difference", residual_space="state", eval_at="estimate")]
    for kw in variants:
        for estimator in (None, lambda m: Adaptive(RippleModel(n, m.torque_limit), np.full(2 * n, 20.0))):
            singles = [DiagnosticObserver(m, T, estimator and estimator(m), **kw) for m, _, _ in data]
            batch = batch_form(singles)
            for k in range(len(data[0][1])):
                active = [(y[k], u[k]) for _, y, u in data if k < len(y)]
                Y, U = np.array([y for y, _ in active]), np.array([u for _, u in active])
                Y.flags.writeable = U.flags.writeable = False
                R, E = batch.update(Y, U)
                for i, (y, u) in enumerate(active):
                    res = singles[i].update(y, u)
                    assert np.array_equal(R[i], res.r) and np.array_equal(E[i], res.estimate), (kw, k, i)


def test_stacked_products_equal_each_runs_product(runs):
    """np.matmul on a stack of mass (and transposed Coriolis) matrices gives each run's M.dot(v) bits (the batch
    forms rely on it); the stacked einsum row sums equal the single form's."""
    data, _, _ = runs
    models = [m for m, _, _ in data]
    n = models[0].n
    ev = BatchEvaluations(models)
    rng = np.random.default_rng(3)
    for k in range(0, 100, 7):
        Y = np.array([y[k] for _, y, _ in data])
        Y.flags.writeable = False
        M, C = ev.mass_matrix_at(Y), ev.coriolis_at(Y)
        V = rng.standard_normal((4, len(models), 2 * n))[2]         # a strided vector rows, as the observers' rows
        P = np.matmul(M, V[:, n:, None])[:, :, 0]
        Ct = np.matmul(C.transpose(0, 2, 1), Y[:, n:, None])[:, :, 0]
        G = rng.standard_normal((len(models), n, 7))
        gg = jit.einsum("kij,kij->ki", G, G)
        for i in range(len(models)):
            assert np.array_equal(P[i], M[i].dot(V[i, n:].copy()))
            assert np.array_equal(Ct[i], C[i].T.dot(Y[i, n:].copy()))
            assert np.array_equal(gg[i], jit.einsum("ij,ij->i", G[i].copy(), G[i].copy()))


def test_batch_evaluations_give_each_models_values_and_share_by_identity(runs):
    data, _, _ = runs
    models = [m for m, _, _ in data]
    n = models[0].n
    ev = batch_evaluations(models)
    assert batch_evaluations(list(models)) is ev and batch_evaluations(models[:2]) is not ev
    X = np.array([y[40] for _, y, _ in data])
    U = np.array([u[40] for _, _, u in data])
    X.flags.writeable = U.flags.writeable = False
    results = (ev.mass_matrix_at(X), ev.gravity_at(X), ev.coriolis_at(X), ev.acceleration_at(X, U))
    for i, (model, x, u) in enumerate(zip(models, X, U)):
        q, v = x[:n].copy(), x[n:].copy()
        wanted = (model.mass_matrix(q), model.gravity(q), model.coriolis(q, v), model.acceleration(q, v, u))
        for got, want in zip(results, wanted):
            assert got[i].tobytes() == want.tobytes() and not got.flags.writeable
    assert models[0].mass_matrix(X[0, :n]).tobytes() != models[1].mass_matrix(X[0, :n]).tobytes()   # instances differ
    assert ev.mass_matrix_at(X) is results[0] and ev.acceleration_at(X, U) is results[3]
    U2 = U + 1.0                                                       # the same states, other torques
    U2.flags.writeable = False
    assert ev.acceleration_at(X, U2)[1].tobytes() == models[1].acceleration(X[1, :n], X[1, n:], U2[1]).tobytes()
    assert ev.mass_matrix_at(X[:2]).shape == (2, n, n)                 # a prefix of the runs: evaluated afresh
    writeable = np.array(X)
    first = ev.gravity_at(writeable)
    writeable[0, 0] += 0.5                                             # a writeable argument is never a hit
    assert ev.gravity_at(writeable) is not first
    assert ev.gravity_at(writeable)[0].tobytes() == models[0].gravity(writeable[0, :n]).tobytes()
    for i in range(len(models)):                                       # only the last few memos are kept
        batch_evaluations(models[i:i + 1])
    assert batch_evaluations(models) is not ev


def test_batch_form_is_none_unless_one_supported_type_with_the_same_settings(runs):
    data, settings, theta0 = runs
    (m0, _, _), (m1, _, _) = data[:2]
    T, n = settings.T, m0.n

    class Tuned(DiagnosticObserver):
        pass

    def adaptive(m, **kw):
        return Adaptive(RippleModel(n, m.torque_limit), **({"Q": np.full(2 * n, 20.0)} | kw))

    assert batch_form([DiagnosticObserver(m0, T), DiagnosticObserver(m1, T)]) is not None
    unsupported = [
        [DiagnosticObserver(m0, T), DiagnosticObserver(m1, T, K1=0.2)],                     # gains differ
        [DiagnosticObserver(m0, T), DiagnosticObserver(m1, 2 * T)],                         # sample times differ
        [DiagnosticObserver(m0, T), DiagnosticObserver(m1, T, residual_space="state")],
        [DiagnosticObserver(m0, T), DiagnosticObserver(m1, T, velocity="backward_difference")],
        list(arm_schemes(m0, settings, theta0[0], ["simple", "recursive"]).values()),        # estimators differ
        [DiagnosticObserver(m0, T), MomentumObserver(m1, T)],
        [DiagnosticObserver(m0, T), Tuned(m1, T)],                                          # a subclass
        [DiagnosticObserver(m, T, freeze_threshold=np.ones(2 * n)) for m in (m0, m1)],
        [DiagnosticObserver(m, T, adaptive(m, Q=np.full((2 * n, 2 * n), 1.0) + 20 * np.eye(2 * n))) for m in (m0, m1)],
        [DiagnosticObserver(m0, T, adaptive(m0)), DiagnosticObserver(m1, T, adaptive(m1, step=1.0))],
        [MomentumObserver(m0, T), MomentumObserver(m1, T, gain=20.0)],
        [MomentumObserver(m, T, friction=JointFriction.from_coefficients(np.full((n, 4), 0.1))) for m in (m0, m1)],
        arm_schemes(m0, settings, None, ["sliding_mode"])["sliding_mode"],                  # not one of the kinds
        [],
    ]
    for i, ds in enumerate(unsupported):
        assert batch_form(ds if isinstance(ds, list) else [ds]) is None, i


def test_bad_inputs_raise(runs):
    data, settings, theta0 = runs
    for name in ("adaptive", "momentum", "position_only"):
        batch = batch_form([arm_schemes(m, settings, th, [name])[name] for (m, _, _), th in zip(data, theta0)])
        Y = np.array([y[0] for _, y, _ in data])
        U = np.zeros((len(data), data[0][0].n))
        batch.update(Y, U)
        Y[1, 3] = np.nan
        with pytest.raises(RobofdiError, match="non-finite"):
            batch.update(Y, U)
        Y[1, 3] = 0.0
        with pytest.raises(RobofdiError):
            batch.update(Y[:, :-1], U[:, :-1])                       # misshapen
        batch.update(Y[:2], U[:2])
        with pytest.raises(RobofdiError):
            batch.update(Y, U)                                       # more runs than at the last sample
