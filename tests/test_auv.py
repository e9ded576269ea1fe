"""The AUV plant, its nominal model and the thruster control matrix (spec_ch4_auv.md §6; checks from §7)."""
from itertools import combinations

import mujoco
import numpy as np
import pytest

from robofdi.errors import RobofdiError
from robofdi.models.auv import (
    AuvModel, AuvModelMismatch, ODIN_THRUSTER, T_body_from_euler, T_euler_from_body,
)
from robofdi.sims.auv import AuvSensors, AuvSimulator

# the digest's B in FRD (§6.5), mapped to the FLU frame of assets/auv.xml by T = diag(1, -1, -1, 1, -1, -1)
B_FRD = np.array([
    [0.7071, 0.7071, 0.7071, 0.7071, 0, 0, 0, 0],
    [-0.7071, 0.7071, -0.7071, 0.7071, 0, 0, 0, 0],
    [0, 0, 0, 0, 1, 1, 1, 1],
    [0, 0, 0, 0, 0.2475, -0.2475, -0.2475, 0.2475],
    [0, 0, 0, 0, -0.2475, -0.2475, 0.2475, 0.2475],
    [-0.4, 0.4, 0.4, -0.4, 0, 0, 0, 0]])
T6 = np.diag([1, -1, -1, 1, -1, -1])


@pytest.fixture(scope="module")
def model():
    return AuvModel.from_mjcf("auv.xml", AuvModelMismatch.none())


def test_thruster_matrix_is_the_digests_and_has_the_structure_of_eq6(model):
    assert model.thrusters == [f"thruster{i}" for i in range(1, 9)]
    np.testing.assert_allclose(model.B, T6 @ B_FRD, atol=2e-4)
    pattern = np.abs(model.B) > 1e-6
    horizontal, vertical = slice(0, 4), slice(4, 8)
    assert pattern[[0, 1, 5], horizontal].all() and not pattern[[0, 1, 5], vertical].any()
    assert pattern[[2, 3, 4], vertical].all() and not pattern[[2, 3, 4], horizontal].any()


def test_rank_survives_single_losses_and_the_pair_2_6_but_not_same_group_pairs(model):
    B = model.B
    assert np.linalg.matrix_rank(B) == 6
    for i in range(8):
        assert np.linalg.matrix_rank(np.delete(B, i, axis=1)) == 6, f"thruster{i + 1} removed"
    assert np.linalg.matrix_rank(np.delete(B, [1, 5], axis=1)) == 6
    lost = [(i, j) for i, j in combinations(range(8), 2) if np.linalg.matrix_rank(np.delete(B, [i, j], axis=1)) < 6]
    same_group = [(i, j) for i, j in combinations(range(8), 2) if (i < 4) == (j < 4)]
    assert lost == same_group and len(lost) == 12
    np.testing.assert_allclose(np.linalg.svd(np.delete(B, [1, 5], axis=1))[1].min(), 0.2838, atol=2e-3)


def test_euler_rate_maps_are_inverses_away_from_the_singularity():
    g = np.random.default_rng(3)
    for _ in range(20):
        e = g.uniform([-1, -1.4, -3], [1, 1.4, 3])
        np.testing.assert_allclose(T_euler_from_body(e) @ T_body_from_euler(e), np.eye(3), atol=1e-12)


def test_mujoco_plant_matches_the_fossen_model_without_damping(model):
    """MuJoCo's ν̇ (rigid body + point added mass + gravcomp buoyancy) against M⁻¹(τ − Cν − g) — §7 check 3."""
    sim = AuvSimulator(current=(0, 0, 0), sensors=AuvSensors.ideal())
    m, d = sim.model, sim.data
    g = np.random.default_rng(0)
    for _ in range(10):
        sim.reset([0, 0, 5, *g.uniform(-0.5, 0.5, 3)], seed=0)
        d.qvel[:] = g.uniform(-0.5, 0.5, 6)
        d.ctrl[:] = g.uniform(-30, 30, 8)
        mujoco.mj_forward(m, d)
        R = d.xmat[sim._hull].reshape(3, 3)
        nu = np.concatenate([R.T @ d.qvel[:3], d.qvel[3:6]])
        expected = np.linalg.solve(model.M, model.B @ d.ctrl - model.coriolis(nu) - model.restoring(R))
        nu_dot = np.concatenate([R.T @ d.qacc[:3] - np.cross(nu[3:], nu[:3]), d.qacc[3:6]])
        np.testing.assert_allclose(nu_dot, expected, atol=1e-3)


def test_rest_acceleration_is_the_net_buoyancy_and_mujoco_fluid_gives_none():
    sim = AuvSimulator(current=(0, 0, 0), sensors=AuvSensors.ideal())
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.data.qacc[2] == pytest.approx(5.0 / (125 + 57.962), rel=1e-6)
    raw = mujoco.MjModel.from_xml_path(str(sim.path))          # §7 check 4: the built-in fluid model adds no buoyancy
    raw.opt.density, raw.body_gravcomp[:] = 1025.0, 0.0
    d = mujoco.MjData(raw)
    mujoco.mj_forward(raw, d)
    assert d.qacc[2] == pytest.approx(-9.81, rel=1e-6)


def test_trimmed_vehicle_holds_depth_within_5_cm_over_60_s_in_a_current():
    from robofdi.models.auv import ODIN_LIKE
    from dataclasses import replace

    trimmed = replace(ODIN_LIKE, buoyancy=ODIN_LIKE.weight)
    sim = AuvSimulator(hydro=trimmed, current=(0.2, 0.1, 0.0))
    sim.reset([0, 0, 5, 0, 0, 0], seed=0)
    depth = []
    for _ in range(3000):
        sim.step(np.zeros(8))
        depth.append(-sim.data.qpos[2])
    assert np.max(np.abs(np.array(depth) - 5.0)) < 0.05
    # and the current does carry it away horizontally (the drag is applied on the relative velocity)
    assert np.hypot(*sim.data.qpos[:2]) > 5.0
    buoyant = AuvSimulator(current=(0, 0, 0))
    buoyant.reset([0, 0, 5, 0, 0, 0], seed=0)
    for _ in range(500):
        buoyant.step(np.zeros(8))
    assert -buoyant.data.qpos[2] < 4.5                          # +5 N of buoyancy untrimmed: it rises


def test_thruster_steady_thrust_and_voltage_zeroing_decay():
    th = ODIN_THRUSTER
    assert th.max_thrust() == pytest.approx(40.0, rel=0.01)
    for T in (2.0, 15.0, 38.0):
        w = th.steady_speed(th.voltage_for_thrust(T))
        assert th.thrust(w) == pytest.approx(T, rel=1e-9)
    # with the drive at 0 V the motor brakes through its back-EMF: faster than the propeller-only decay Ω0/(1 + aΩ0t)
    w, dt, a = 250.0, 1e-5, th.torque_coefficient / th.inertia
    for _ in range(int(0.2 / dt)):
        w += dt * th.speed_rate(w, 0.0)
    assert 0 < w < 250.0 / (1 + a * 250.0 * 0.2)


def test_sensor_noise_is_seeded_and_channels_are_named():
    sim = AuvSimulator()
    y1 = [sim.reset(None, seed=5)] + [sim.step(np.full(8, 5.0)) for _ in range(20)]
    y2 = [sim.reset(None, seed=5)] + [sim.step(np.full(8, 5.0)) for _ in range(20)]
    np.testing.assert_array_equal(np.array(y1), np.array(y2))
    assert len(sim.sensor_channels) == 13 + 24 == len(sim.units["y"])
    assert sim.sensor_channels[2] == "depth" and "thruster2_voltage" in sim.sensor_channels
    y3 = sim.reset(None, seed=6)
    assert not np.array_equal(y1[0], y3)


def test_bad_inputs_are_clear_errors():
    sim = AuvSimulator()
    with pytest.raises(RobofdiError, match="initial_state"):
        sim.reset([0, 0, 5], seed=0)
    with pytest.raises(RobofdiError, match="'u' must hold 8 finite"):
        sim.step(np.array([np.nan] * 8))
    with pytest.raises(RobofdiError, match="unknown thruster 'thruster9'"):
        sim.apply_component_fault("component_thruster_blocking", "thruster9", 1.0)
    with pytest.raises(RobofdiError, match="thrust_limit"):
        AuvSimulator(thrust_limit=80.0)
    with pytest.raises(RobofdiError, match="control_dt"):
        AuvSimulator(control_dt=0.013)
