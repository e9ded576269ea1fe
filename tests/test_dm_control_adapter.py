"""The dm_control adapter on the real cartpole suite task (MuJoCo, headless): spec conformance with faults active,
labels, reproducibility, the physics really changes, and bad input."""
from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np
import pytest

pytest.importorskip("dm_control")
from absl.testing import absltest  # noqa: E402  (comes with dm_control)
from dm_control import suite  # noqa: E402
from dm_env import test_utils  # noqa: E402

from robofdi import RobofdiError  # noqa: E402
from robofdi.adapters.dm_control import LABELS_KEY, FaultyEnvironment, strip_labels  # noqa: E402

FAULTS = ["actuator_loss_of_effectiveness:slide:0.6@0.05",
          "sensor_bias:velocity[1]:0.5@0.02-0.2~intermittent(0.04,0.5)",
          "sensor_noise:position[0]:0.01@0"]


def cartpole(faults=(), seed=0, random=0):
    return FaultyEnvironment(suite.load("cartpole", "swingup", task_kwargs={"random": random}),
                             faults if isinstance(faults, str) else list(faults), seed=seed)


class FaultyCartpoleConformance(test_utils.EnvironmentTestMixin, absltest.TestCase):
    """dm_env's own environment tests (spec-conforming timesteps, episode ends, reset) with three faults active."""

    def make_object_under_test(self):
        env = suite.load("cartpole", "swingup", task_kwargs={"random": 0, "time_limit": 0.3})
        return FaultyEnvironment(env, FAULTS, seed=1)


def rollout(env, steps, policy=lambda k: np.array([np.sin(0.1 * k)])):
    ts = env.reset()
    obs, labels, qpos = [ts.observation], [ts.observation[LABELS_KEY]], [env.physics.data.qpos.copy()]
    for k in range(steps):
        ts = env.step(policy(k))
        obs.append(ts.observation)
        labels.append(ts.observation[LABELS_KEY])
        qpos.append(env.physics.data.qpos.copy())
    return obs, np.array(labels), np.array(qpos)


def test_actuator_label_is_active_exactly_from_onset_and_holds_the_applied_change():
    # 0.4 additive on the cart from t = 0.3 s, gone at 0.6 s; cartpole's control step is 0.01 s
    env = cartpole(["actuator_additive:slide:0.4@0.3-0.6"])
    _, labels, _ = rollout(env, 80, policy=lambda k: np.array([0.2]))
    # timestep k+1 is the result of the action applied at t = 0.01 k
    t_applied = 0.01 * np.arange(80)
    active = labels[1:, 0, 0] == 1.0
    np.testing.assert_array_equal(active, (t_applied >= 0.3 - 1e-9) & (t_applied < 0.6 - 1e-9))
    np.testing.assert_allclose(labels[1:, 0, 1][active], 0.4)
    assert labels[0, 0].tolist() == [0.0, 0.0] and np.all(labels[1:, 0, 1][~active] == 0.0)


def test_actuator_label_reports_saturation():
    env = cartpole(["actuator_additive:slide:0.5@0"])
    _, labels, _ = rollout(env, 3, policy=lambda k: np.array([0.9]))
    np.testing.assert_allclose(labels[1:, 0, 1], 0.1)        # 0.9 + 0.5 saturates at the ctrlrange 1.0


def test_sensor_fault_changes_the_observation_by_its_label_and_not_the_physics():
    clean, faulty = cartpole(), cartpole(["sensor_bias:velocity[1]:0.5@0.1-0.2"])
    obs0, _, q0 = rollout(clean, 30)
    obs1, labels, q1 = rollout(faulty, 30)
    np.testing.assert_array_equal(q0, q1)                    # a sensor fault does not touch the plant
    diff = np.array([o1["velocity"][1] - o0["velocity"][1] for o0, o1 in zip(obs0, obs1)])
    t = 0.01 * np.arange(31)
    on = (t >= 0.1 - 1e-9) & (t < 0.2 - 1e-9)
    np.testing.assert_allclose(diff[on], 0.5)
    np.testing.assert_array_equal(diff[~on], 0.0)
    np.testing.assert_array_equal(labels[:, 0, 0] == 1.0, on)
    assert set(strip_labels(obs1[-1])) == {"position", "velocity"}


def test_same_seed_same_trajectories_other_seed_other_noise():
    a = rollout(cartpole(FAULTS, seed=3), 40)
    b = rollout(cartpole(FAULTS, seed=3), 40)
    c = rollout(cartpole(FAULTS, seed=4), 40)
    for oa, ob in zip(a[0], b[0]):
        for k in oa:
            np.testing.assert_array_equal(oa[k], ob[k])
    np.testing.assert_array_equal(a[2], b[2])
    assert not np.array_equal([o["position"][0] for o in a[0]], [o["position"][0] for o in c[0]])


def test_actuator_fault_really_changes_the_cart_motion():
    _, _, q0 = rollout(cartpole(), 100, policy=lambda k: np.array([0.5]))
    _, _, q1 = rollout(cartpole(["actuator_loss_of_effectiveness:slide:0.8@0.5"]), 100, policy=lambda k: np.array([0.5]))
    np.testing.assert_array_equal(q0[:51], q1[:51])          # identical before the onset
    assert abs(q1[-1, 0] - q0[-1, 0]) > 0.05                  # the cart lags behind by more than 5 cm after 0.5 s


@pytest.mark.parametrize("faults, message", [
    (["actuator_additive:elbow:1@0"], "unknown target 'elbow'; expected one of slide"),
    (["sensor_bias:velocity[2]:1@0"], "unknown target 'velocity[2]'"),
    (["sensor_bias:position:1@0"], "unknown target 'position'"),
    (["actuator_loss_of_effectiveness:slide:1.5@0"], "must be in [0, 1]"),
    (["component_mass:pole_1:1@0"], "component fault"),
    (["actuator_additive:slide@0"], "expected KIND:TARGET:MAGNITUDE@ONSET"),
    ("actuator_additive:slide:1@0", "must be a list"),
])
def test_bad_faults_get_a_one_line_error(faults, message):
    with pytest.raises(RobofdiError) as info:
        cartpole(faults)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_bad_env_and_seed_get_a_clear_error():
    with pytest.raises(RobofdiError, match="must be a dm_env.Environment"):
        FaultyEnvironment(object(), [])
    with pytest.raises(RobofdiError, match="'seed' must be an integer >= 0"):
        cartpole([], seed=-1)
    with pytest.raises(RobofdiError, match="wrapped twice"):
        FaultyEnvironment(cartpole(), [])
