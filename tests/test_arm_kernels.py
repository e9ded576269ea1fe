"""The arm simulator's compiled hot path (robofdi.sims.kernels) against its pure-Python path and against the
NumPy formulation of the plant effects (ArmSimulator.disturbance, SensorModel), on real MuJoCo."""
import mujoco
import numpy as np
import pytest

from robofdi import ASSETS, RobofdiError
from robofdi.jit import interpreted
from robofdi.sims import ArmSimulator, SensorModel, capi, kernels

ARM6 = ASSETS / "arm6.xml"
KERNELS = ("apply_torque", "physics_forces", "control_tick", "measure")
SENSORS = SensorModel(position_noise=2e-5)          # quantisation, position and velocity noise all on


def _drive(sim, steps, fault_at=None):
    """Reset (seeded noise), then ``steps`` control ticks of seeded random torques; a friction fault from ``fault_at``."""
    y0 = sim.reset(None, seed=7)
    rng = np.random.default_rng(3)
    ys = [y0]
    for j in range(steps):
        if j == fault_at:
            sim.apply_component_fault("component_friction", "joint3", 2.0)
        ys.append(sim.step(rng.uniform(-0.4, 0.4, sim.n) * sim.torque_limit))
    return np.array(ys), sim.state, sim.u_applied.copy()


def test_compiled_and_pure_python_paths_agree_bit_for_bit():
    compiled = _drive(ArmSimulator(ARM6, sensors=SENSORS), 80, fault_at=30)
    with interpreted():              # the pure-Python path: each kernel's own Python function (NUMBA_DISABLE_JIT=1)
        assert all(not hasattr(getattr(kernels, name), "py_func") for name in KERNELS)
        python = _drive(ArmSimulator(ARM6, sensors=SENSORS), 80, fault_at=30)
    for a, b in zip(compiled, python):
        assert np.array_equal(a, b)
    assert np.ptp(compiled[0][:, :6], axis=0).min() > 5e-4       # the arm moved: the comparison is not vacuous


def test_the_c_step_equals_the_bindings_step_bit_for_bit():
    """The control period through MuJoCo's C API (robofdi.sims.capi) and through ``mujoco.mj_step`` (the path a
    mujoco whose library cannot be found takes) give the same state and measurements, bit for bit."""
    assert capi.MJ_STEP != 0                                        # the shipped wheels' library is found
    via_c = _drive(ArmSimulator(ARM6, sensors=SENSORS), 80, fault_at=30)
    bindings = ArmSimulator(ARM6, sensors=SENSORS)
    bindings._mj_step = 0
    via_bindings = _drive(bindings, 80, fault_at=30)
    for a, b in zip(via_c, via_bindings):
        assert np.array_equal(a, b)


def test_step_equals_the_numpy_formulation_of_the_plant_effects():
    """Independent stepping: qfrc_applied = −δ of ArmSimulator.disturbance (NumPy: the ripple's fused sines and
    BLAS product, NumPy's tanh, Stribeck) every physics step, then the sensor model of SensorModel's docstring.
    To rounding: the kernels sum in their own order and take the C library's tanh (NumPy's SIMD tanh differs
    in the last bit for about a quarter of its arguments)."""
    sim = ArmSimulator(ARM6, sensors=SENSORS)
    ref = ArmSimulator(ARM6, sensors=SENSORS)
    sim.reset(None, seed=5)
    ref.reset(None, seed=5)
    m, d, dofs, qadr = ref.model, ref.data, ref._dofs, ref._qadr
    res = SENSORS.position_resolution
    rng = np.random.default_rng(1)
    for _ in range(100):
        u = rng.uniform(-0.3, 0.3, sim.n) * sim.torque_limit
        y = sim.step(u)
        tau = np.clip(u, ref.torque_range[:, 0], ref.torque_range[:, 1])
        d.ctrl[ref._act] = tau / ref._gain
        for _ in range(ref.substeps):
            d.qfrc_applied[dofs] = -ref.disturbance(d.qpos[qadr], d.qvel[dofs], tau)
            mujoco.mj_step(m, d)
        q_meas = np.round(d.qpos[qadr] / res) * res + SENSORS.position_noise * ref._pos_draws.draw()
        v_meas = d.qvel[dofs] + SENSORS.velocity_noise * ref._vel_draws.draw()
        np.testing.assert_allclose(sim.state, ref.state, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(y, np.concatenate([q_meas, v_meas]), rtol=0, atol=1.01 * res)   # a tie: one count
    assert np.any(sim.data.qfrc_applied != 0)


def test_step_refuses_non_finite_torques_before_touching_the_plant():
    sim = ArmSimulator(ARM6)
    sim.reset()
    x = sim.state
    with pytest.raises(RobofdiError, match="u must be 6 finite joint torques"):
        sim.step(np.array([0, 0, np.nan, 0, 0, 0.0]))
    with pytest.raises(RobofdiError, match="got shape \\(5,\\)"):
        sim.step(np.zeros(5))
    assert np.array_equal(sim.state, x) and sim.time == 0.0


def test_a_simulator_refuses_to_be_copied_or_pickled():
    """Its compiled control period steps its own MjData by address: a copy would step the original's."""
    import copy
    import pickle

    sim = ArmSimulator(ARM6)
    for make in (copy.copy, copy.deepcopy, pickle.dumps):
        with pytest.raises(RobofdiError, match="cannot be copied or pickled"):
            make(sim)
