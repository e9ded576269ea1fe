"""Batch forms of the arm diagnosers (robofdi.lockstep.observers) and of the nominal-model memo
(robofdi.lockstep.evaluations): on real closed-loop runs of different robot instances and lengths, row i of every
batch output equals run i's own diagnoser stepped alone, bit for bit, compiled and on the pure-Python path."""
from dataclasses import replace

import numpy as np
import pytest

from robofdi import RobofdiError, jit
from robofdi.campaign import load_spec
from robofdi.campaign.engine import _calibrate
from robofdi.campaign.runs import _draw
from robofdi.control import ComputedTorque, Quintic
from robofdi.faults import parse_fault_spec
from robofdi.lockstep import diagnose_lockstep, diagnoser_view
from robofdi.lockstep.evaluations import BatchEvaluations, batch_evaluations
from robofdi.observers import consistency, diagnostic
from robofdi.lockstep.observers import BatchConsistencyResidual, BatchMomentumObserver, batch_form
from robofdi.loop import ClosedLoop, Rates, diagnoser_inputs
from robofdi.models.friction import JointFriction
from robofdi.observers.arm_schemes import BOOK_SCHEMES, arm_schemes
from robofdi.observers.consistency import ConsistencyResidual
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


# ----------------------------------------------------------------------------------------------------------
# The consistency scheme, with the designs the arm calibration gives two robot instances (one calibration each)
CONSISTENCY_SPEC = """
seed = 11
fault_free_runs = 4
faulty_runs = 0
diagnosers = ["consistency"]

[system]
name = "arm"
speed = "fast"
tail = 0.2
robot_seeds = [0, 1]
"""
# one per run (drawn motions of different lengths): fault-free, an actuator step, an encoder bias and a velocity
# bias, so that the dynamic, kinematic, step and payload rows all move
CONSISTENCY_FAULTS = (None, "actuator_additive:joint2:40@0.3", "sensor_bias:joint3_pos:0.01@0.25",
                      "sensor_bias:joint4_vel:0.05@0.2")


@pytest.fixture(scope="module")
def consistency_runs():
    """Per run, longest first: its built parts (a fresh build each call: nominal model, calibrated design and
    decision), and the (y, ū) its diagnosers receive, simulated without them."""
    spec = load_spec(CONSISTENCY_SPEC)
    system = spec.campaign_system
    calibrations = {key: _calibrate(spec, key)[1] for key in system.calibration_keys(spec.options)}
    out = []
    for index, fault in enumerate(CONSISTENCY_FAULTS):
        key, seed, mission, _, _ = _draw(spec, index)

        def build(key=key, seed=seed, mission=mission, fault=fault):
            return system.build(spec.options, calibrations[key], key, mission, [parse_fault_spec(fault)] if fault else [],
                                seed, spec.diagnosers)

        parts = build()
        record = parts.run(diagnose=False)
        _, y, u = diagnoser_view(record, parts.loop.rates)
        out.append((build, parts.diagnoses["consistency"].diagnoser, record, y, u))
    out.sort(key=lambda run: -len(run[3]))
    assert len({len(run[3]) for run in out}) == len(out)        # the batch shrinks at every run's end
    return out


def _varied(design, i):
    """Run i's design with what other calibrations give: a carried payload (or none), no reach, a ripple that grows
    with the torque, a drive whose velocity reading never repeats, unset optional scales."""
    n = design.skew.shape[0]
    return (design, replace(design, payload=0.4, gain_scale=None),
            replace(design, reach=None, repeat_scale=np.zeros(n), move_scale=None),
            replace(design, payload=-0.2, ripple_load=np.full(design.ripple_amplitude.shape, 2e-8), impulse_scale=None,
                    trend_scale=None))[i % 4]


def _consistency_lockstep(runs, designs, batch=None):
    """Each run's consistency residual alone and the batch form over all, asserting row i = run i at every sample.
    Returns the batch form (reset again by a second call) and the largest |z| per row."""
    models = [run[1].model for run in runs]
    singles = [ConsistencyResidual(m, d) for m, d in zip(models, designs)]
    if batch is None:
        batch = batch_form([ConsistencyResidual(m, d) for m, d in zip(models, designs)])
    else:
        batch.reset()
    assert type(batch) is BatchConsistencyResidual
    largest = 0.0
    for k in range(len(runs[0][3])):
        active = [(y[k], u[k]) for *_, y, u in runs if k < len(y)]
        Y, U = np.array([y for y, _ in active]), np.array([u for _, u in active])
        Y.flags.writeable = U.flags.writeable = False
        R, E = batch.update(Y, U)
        assert R.shape[0] == E.shape[0] == len(active), k
        for i, (y, u) in enumerate(active):
            res = singles[i].update(y, u)
            assert np.array_equal(R[i], res.r), (k, i, np.flatnonzero(R[i] != res.r))
            assert np.array_equal(E[i], res.estimate), (k, i, np.flatnonzero(E[i] != res.estimate))
        largest = np.maximum(largest, np.abs(R).max(axis=0))
    return batch, largest


@pytest.mark.parametrize("designs", ["calibrated", "varied"])
def test_consistency_batch_form_equals_each_run_alone_compiled_and_interpreted(consistency_runs, designs):
    runs = consistency_runs
    chosen = [run[1].design if designs == "calibrated" else _varied(run[1].design, i) for i, run in enumerate(runs)]
    assert len({id(d.friction) for d in chosen}) == 2                   # two robot instances
    batch, largest = _consistency_lockstep(runs, chosen)
    n = runs[0][1].n
    # the faults moved every row set: dynamic (actuator), kinematic (encoder and velocity), step (velocity), payload
    assert largest[:n].max() > 1 and largest[n:2 * n].max() > 1 and largest[2 * n:3 * n].max() > 1 and largest[3 * n] > 0
    with jit.interpreted():
        assert not hasattr(consistency._step_rows_each, "py_func")          # the batch kernels are swapped too
        _consistency_lockstep(runs, chosen, batch)


def test_consistency_scheme_in_lockstep_gives_each_runs_online_trace(consistency_runs):
    """The engine with the consistency batch form: each run's trace (residual, decision, isolation) is the one its
    own loop records."""
    runs = consistency_runs
    traces = diagnose_lockstep([run[2] for run in runs], [run[0]().diagnoses for run in runs],
                               runs[0][0]().loop.rates)
    for run, trace in zip(runs, traces):
        alone = run[0]().run().diagnosers["consistency"]
        for field in ("time", "residual", "threshold", "alarm", "estimate"):
            assert np.array_equal(getattr(alone, field), getattr(trace["consistency"], field)), field
        assert list(alone.isolated) == list(trace["consistency"].isolated)
    assert any(trace["consistency"].alarm.any() for trace in traces)


def test_the_friction_of_a_block_of_runs_is_each_runs_torque(runs):
    """NumPy's SIMD tanh and exp on one (a, n) block give each row's bits (thousands of random rows of the shapes the
    batch forms use), so the batch friction τ̂_f is each run's JointFriction.torque."""
    model = runs[0][0][0]
    n, rng = model.n, np.random.default_rng(5)
    frictions = [JointFriction(*rng.uniform(-5, 5, (4, n)), rng.uniform(0.01, 0.2), rng.uniform(0.001, 0.05))
                 for _ in range(16)]
    batch = BatchMomentumObserver([MomentumObserver(model, 0.002, 100.0, f) for f in frictions])
    for trial in range(300):
        a = int(rng.integers(1, 17))
        V = rng.standard_normal((a, 2 * n)) * 10.0 ** rng.uniform(-6, 1, (a, 2 * n))
        V[rng.random((a, 2 * n)) < 0.1] = 0.0
        V = V[:, n:]                                          # rows of the previous Y, as the batch forms take them
        tau = batch._friction(V)
        for i in range(a):
            assert tau[i].tobytes() == frictions[i].torque(V[i].copy()).tobytes(), (trial, i)
        for width in (6, 7):             # the raw functions on other arms' joint counts, at τ̂_f's arguments
            x = rng.standard_normal((a, width)) * 10.0 ** rng.uniform(-3, 3, (a, width))
            for f, block in ((np.tanh, x), (np.exp, -(x * x))):
                assert all(f(block)[i].tobytes() == f(block[i].copy()).tobytes() for i in range(a)), (trial, f)


def test_consistency_batch_form_is_none_unless_the_runs_share_its_settings(consistency_runs):
    (_, d0, *_), (_, d1, *_) = consistency_runs[:2]
    m0, m1, e0, e1 = d0.model, d1.model, d0.design, d1.design

    class Tuned(ConsistencyResidual):
        pass

    assert type(batch_form([ConsistencyResidual(m0, e0), ConsistencyResidual(m1, e1)])) is BatchConsistencyResidual
    no_ripple = dict(ripple_orders=None, ripple_amplitude=None, ripple_load=None)
    shorter = dict(windows=e1.windows[:-1], window_scales=e1.window_scales[:, :-1], reach=e1.reach[:, :-1])
    for i, other in enumerate([replace(e1, gain=e1.gain / 2), replace(e1, T=2 * e1.T), replace(e1, **shorter),
                               replace(e1, **no_ripple)]):
        assert batch_form([ConsistencyResidual(m0, e0), ConsistencyResidual(m1, other)]) is None, i
    assert batch_form([ConsistencyResidual(m, replace(e, friction=None)) for m, e in ((m0, e0), (m1, e1))]) is None
    assert batch_form([ConsistencyResidual(m0, e0), Tuned(m1, e1)]) is None
    assert batch_form([ConsistencyResidual(m0, e0), MomentumObserver(m1, e1.T)]) is None


def test_consistency_batch_form_raises_on_non_finite_inputs(consistency_runs):
    batch = batch_form([ConsistencyResidual(run[1].model, run[1].design) for run in consistency_runs])
    Y = np.array([run[3][0] for run in consistency_runs])
    U = np.zeros((len(consistency_runs), Y.shape[1] // 2))
    batch.update(Y, U)
    Y[2, 1] = np.inf
    with pytest.raises(RobofdiError, match="non-finite"):
        batch.update(Y, U)

