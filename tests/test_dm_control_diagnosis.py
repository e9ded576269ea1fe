"""dm_control cartpole (underactuated: 1 actuator, 2 joints) diagnosed end to end with a momentum residual on every
joint, from a nominal model read from the suite's MJCF with parameter mismatch; the plant is the suite's physics."""
from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

pytest.importorskip("dm_control")
from robofdi import RobofdiError  # noqa: E402
from robofdi.adapters.dm_control_diagnosis import (  # noqa: E402
    CartpoleDiagnoser, ExcitationPolicy, calibrate_cartpole, cartpole_env, run_episode, suite_model,
)
from robofdi.models.manipulator import ModelMismatch  # noqa: E402

STEPS, SKIP = 300, 5          # 3 s episodes at the suite's 10 ms control step; 50 ms start-up blanking


@pytest.fixture(scope="module")
def calibrated():
    model = suite_model("cartpole", ModelMismatch(mass=0.05, damping=0.2, seed=1))
    diagnoser = CartpoleDiagnoser(model, 0.01)
    return diagnoser, calibrate_cartpole(diagnoser, range(30), STEPS, SKIP)


def first_isolation(decision, times, residuals):
    decision.reset()
    alarm_at = None
    for t, r in zip(times, residuals):
        a = decision.update(r)
        if a.alarm.any() and alarm_at is None:
            alarm_at = t
        if a.new:
            return alarm_at, t, a.new
    return alarm_at, None, ()


def test_nominal_model_from_the_mjcf_keeps_the_unactuated_joint():
    model = suite_model("cartpole")
    assert model.joint_names == ["slider", "hinge_1"] and model.actuated == ["slider"]
    np.testing.assert_allclose(model.B, [[10.0], [0.0]])     # gear 10 on the slider, nothing on the pole
    env = cartpole_env()
    env.reset()
    m, d = env.physics.model.ptr, env.physics.data.ptr
    d.qpos[:], d.qvel[:] = [0.3, 2.0], [0.4, -1.5]
    mujoco.mj_forward(m, d)
    M = np.zeros((2, 2))
    mujoco.mj_fullM(m, M, d.qM)
    np.testing.assert_allclose(model.mass_matrix(d.qpos), M, atol=1e-12)
    np.testing.assert_allclose(model.bias(d.qpos, d.qvel), d.qfrc_bias + m.dof_damping * d.qvel, atol=1e-12)


def test_no_false_alarm_on_held_out_fault_free_episodes(calibrated):
    diagnoser, decision = calibrated
    for seed in range(50, 60):
        times, r, _ = run_episode(cartpole_env((), seed), diagnoser, ExcitationPolicy(seed), STEPS)
        assert first_isolation(decision, times, r) == (None, None, ()), seed


@pytest.mark.parametrize("spec", ["actuator_additive:slide:0.1@1.5", "actuator_loss_of_effectiveness:slide:0.5@1.5",
                                  "actuator_additive:slide:0.2@1.5-2.5~intermittent(0.2,0.5)"])
def test_actuator_fault_detected_after_onset_and_isolated_to_the_cart_motor(calibrated, spec):
    diagnoser, decision = calibrated
    for seed in (70, 71):
        times, r, labels = run_episode(cartpole_env([spec], seed), diagnoser, ExcitationPolicy(seed), STEPS)
        alarm, isolated_at, new = first_isolation(decision, times, r)
        assert new == ("slide",), (seed, new)
        # a loss of effectiveness shows only as fast as the command is large: within 0.3 s of the onset
        assert 1.5 <= alarm <= 1.8 and isolated_at <= 1.85, (seed, alarm, isolated_at)
        # the unactuated pole row carries model error only: it stays below its threshold
        assert np.abs(r[SKIP:, 1]).max() < decision.threshold[1]
        assert labels[times < 1.5, 0, 0].max() == 0.0


def test_a_model_with_free_joints_is_refused():
    with pytest.raises(RobofdiError, match="expected hinge and slide joints only"):
        suite_model("humanoid")   # a free-floating root
    with pytest.raises(RobofdiError, match="not a dm_control suite domain"):
        suite_model("nope")


def test_cartpole_campaign_system(tmp_path):
    import pandas as pd

    from robofdi.campaign import load_spec, run_campaign

    spec = load_spec("""
seed = 1
fault_free_runs = 2
faulty_runs = 3
[system]
name = "dm_control-cartpole"
calibration_episodes = 20
[[faults]]
kind = "actuator_additive"
magnitude_fraction = [0.1, 0.2]
onset_fraction = [0.3, 0.6]
""")
    assert spec.diagnosers == ("momentum",) and spec.faults[0].limits == {"slide": (1.0, "1 (action)")}
    run_campaign(spec, tmp_path / "c", workers=1, progress=False)
    rows = pd.read_parquet(tmp_path / "c" / "results.parquet")
    assert rows["error"].isna().all() and (rows["false_alarms"] == 0).all()
    faulty = rows[rows["faulty"]]
    assert len(faulty) == 3 and (faulty["isolated"] == "slide").all() and (faulty["delay"] < 0.3).all(), faulty
