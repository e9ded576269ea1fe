"""The Gymnasium adapter: faults and labels in any environment, check_env, vector environments, and a MuJoCo
environment (Reacher) diagnosed end to end from a nominal model of its own MJCF."""
from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
pytest.importorskip("imageio", reason="Gymnasium's MuJoCo environments need gymnasium[mujoco] (extra 'gymnasium')")

from gymnasium.utils.env_checker import check_env  # noqa: E402

from robofdi.adapters.gymnasium import DIAGNOSIS_KEY, LABELS_KEY, FaultyEnv, make_vector  # noqa: E402
from robofdi.errors import RobofdiError  # noqa: E402

REACHER = "Reacher-v5"


def _check(env):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # check_env's advice on wrapped envs and unbounded Boxes
        check_env(env, skip_render_check=True)


def test_check_env_passes_with_faults_active():
    _check(FaultyEnv(gymnasium.make(REACHER), ["actuator_additive:actuator1:0.2@0.0", "sensor_bias:obs[6]:0.3@0.0",
                                               "sensor_noise:obs[7]:0.1@0.0"], seed=0))
    # not MuJoCo, a Discrete action: sensor faults only, the clock counts steps
    cartpole = FaultyEnv(gymnasium.make("CartPole-v1"), ["sensor_bias:obs[2]:0.05@0.0"], seed=0)
    _check(cartpole)
    assert cartpole.dt == 1.0 and cartpole.actuators == []


def test_labels_actions_and_seeds():
    env = FaultyEnv(gymnasium.make(REACHER), ["actuator_additive:actuator1:0.5@0.1", "sensor_bias:obs[6]:0.3@0.04",
                                              "sensor_noise:obs[7]:0.1@0.0"], seed=3)
    assert env.actuators == ["actuator0", "actuator1"] and env.dt == pytest.approx(0.02)
    obs0, info = env.reset(seed=1)
    assert info[LABELS_KEY].shape == (3, 2) and info[LABELS_KEY][0].tolist() == [0.0, 0.0]
    rows = []
    for _ in range(8):
        obs, _, _, _, info = env.step(np.array([0.1, 0.8], dtype=np.float32))
        rows.append((info[LABELS_KEY].copy(), env.unwrapped.data.ctrl.copy(), obs))
    # step k applies its action at k·dt: the actuator fault from step 5 (t = 0.1 s) on, clipped to the ctrlrange
    assert [r[0][0, 0] for r in rows] == [0.0] * 5 + [1.0] * 3
    assert rows[6][0][0, 1] == pytest.approx(0.2) and rows[6][1][1] == pytest.approx(1.0)
    assert rows[2][1][1] == pytest.approx(0.8)
    # the sensor bias from the observation at t = 0.04 s (after step 2) on
    assert [r[0][1, 0] for r in rows[:3]] == [0.0, 1.0, 1.0] and rows[2][0][1, 1] == pytest.approx(0.3)
    # the same reset seed replays the episode exactly; an unseeded reset draws new fault noise
    env.reset(seed=1)
    again = [env.step(np.array([0.1, 0.8], dtype=np.float32))[0] for _ in range(8)]
    assert all(np.array_equal(a, r[2]) for a, r in zip(again, rows))
    env.reset()
    noise = [env.step(np.array([0.1, 0.8], dtype=np.float32))[4][LABELS_KEY][2, 1] for _ in range(3)]
    assert noise != [r[0][2, 1] for r in rows[:3]]
    rec = env.record()
    assert rec.signals["u"].shape == (4, 2) and rec.columns["truth/state"][:2] == ["joint0", "joint1"]


def test_vector_env_stacks_labels_and_seeds_each_copy():
    env = make_vector(REACHER, 2, ["sensor_noise:obs[7]:0.1@0.0"], seed=1)
    try:
        env.reset()
        _, _, _, _, info = env.step(env.action_space.sample())
        labels = info[LABELS_KEY]
        assert labels.shape == (2, 1, 2) and labels[:, 0, 0].tolist() == [1.0, 1.0]
        assert labels[0, 0, 1] != labels[1, 0, 1]          # each copy its own fault stream
    finally:
        env.close()


def test_errors_name_the_field():
    with pytest.raises(RobofdiError, match="component fault"):
        FaultyEnv(gymnasium.make(REACHER), ["component_friction:joint1:0.5@1.0"])
    with pytest.raises(RobofdiError, match="unknown target 'joint9'.*actuator0, actuator1"):
        FaultyEnv(gymnasium.make(REACHER), ["actuator_additive:joint9:0.1@1.0"])
    with pytest.raises(RobofdiError, match="1-D Box action space"):
        FaultyEnv(gymnasium.make("CartPole-v1"), ["actuator_additive:action[0]:0.1@1.0"])
    from robofdi.adapters.gymnasium_diagnosis import momentum_diagnoser

    d = momentum_diagnoser(REACHER)
    from robofdi.loop import Diagnosis, DiagnosisBank, Rates

    with pytest.raises(RobofdiError, match="field 'measure'"):
        FaultyEnv(gymnasium.make(REACHER), diagnosis=DiagnosisBank({"m": Diagnosis(d)}, Rates(50, 50)))
    with pytest.raises(RobofdiError, match="call reset"):
        FaultyEnv(gymnasium.make(REACHER)).step(np.zeros(2))


@pytest.mark.parametrize("env_id", ["Reacher-v5", "Pusher-v5", "InvertedPendulum-v5"])
def test_readouts_read_the_joints(env_id):
    from robofdi.adapters.gymnasium_diagnosis import env_model, readout_for

    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=0)
    readout = readout_for(env)
    m, d = env.unwrapped.model, env.unwrapped.data
    ids = [m.joint(j).id for j in readout.joints]
    truth = np.r_[d.qpos[m.jnt_qposadr[ids]], d.qvel[m.jnt_dofadr[ids]]]
    np.testing.assert_allclose(readout(obs), truth, atol=1e-12)
    model = env_model(env, readout)
    assert model.joint_names == list(readout.joints) and model.actuated
    env.close()


def test_reacher_diagnosed_end_to_end():
    """Calibrated on 3 fault-free episodes (3 s each); a fault-free episode of another seed gives no alarm; a
    10 N·m actuator bias (0.05 of the action) on actuator1 at 1.5 s is detected and isolated as actuator1."""
    from robofdi.adapters import gymnasium_diagnosis as gd

    d = gd.momentum_diagnoser(REACHER)
    decision = gd.calibrate(REACHER, d, seeds=range(3), steps=150)
    free = gd.diagnose_episode(REACHER, [], seed=7, diagnoser=d, decision=decision, steps=150).diagnosers["momentum"]
    assert not free.alarm.any() and set(free.isolated) == {""}
    rec = gd.diagnose_episode(REACHER, ["actuator_additive:actuator1:0.05@1.5"], seed=7, diagnoser=d, decision=decision,
                              steps=150)
    trace = rec.diagnosers["momentum"]
    alarmed = trace.time[trace.alarm.any(axis=1)]
    assert alarmed.size and alarmed[0] >= 1.5 and alarmed[0] - 1.5 < 0.1
    assert set(trace.isolated) == {"", "actuator1"} and trace.isolated[-1] == "actuator1"
    assert rec.faults["actuator1_additive"].active.sum() > 0 and rec.units["signals/u"] == ["1", "1"]
    # the same diagnosis is in every step's info, online
    bank = gd.DiagnosisBank({"momentum": gd.Diagnosis(d, decision)}, gd.Rates(50, 50, "first"))
    env = gd.make_env(REACHER, 150, ["actuator_additive:actuator1:0.05@1.5"], 7, bank)
    policy = gd.ExcitationPolicy(d.model, env.measure, 7)
    obs, info = env.reset(seed=7)
    for k in range(150):
        obs, _, _, _, info = env.step(policy(k * env.dt, obs).astype(np.float32))
    assert info[DIAGNOSIS_KEY]["momentum"]["isolated"] == "actuator1"
    env.close()


def test_without_gymnasium_says_what_to_install():
    code = ("import sys, importlib; sys.modules['gymnasium'] = None\n"
            "for m in ('robofdi.adapters.gymnasium', 'robofdi.adapters.gymnasium_diagnosis'):\n"
            "    try:\n        importlib.import_module(m)\n    except ImportError as e:\n        print(e)\n"
            "from robofdi.adapters import adapter\n"
            "try:\n    adapter('robofdi.adapters.gymnasium', 'gymnasium')\nexcept Exception as e:\n    print(type(e).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    lines = out.stdout.strip().splitlines()
    assert out.returncode == 0 and len(lines) == 3, out.stderr
    assert all("pip install 'robofdi[gymnasium]'" in line for line in lines[:2]) and lines[2] == "RobofdiError"
