"""Campaign fault kinds: kinds without a size need none and get no minimum detectable fault, a hard-over drawn
from each target's own limit, signed scale faults; and the motion generator's self-collision check on a shipped
arm made solid. Spec parsing and draws only (no run): each test well under a second."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from robofdi import RobofdiError
from robofdi.campaign import load_spec, run_seed
from robofdi.campaign.metrics import analyse
from robofdi.campaign.runs import draw_fault

LINEAR = """
seed = 5
fault_free_runs = 0
faulty_runs = 50

[system]
name = "linear"
duration = 3.0
calibration_runs = 2

[[faults]]
{entry}
"""


def test_a_lock_needs_no_magnitude_and_is_the_same_entry_as_magnitude_zero():
    bare = load_spec(LINEAR.format(entry='kind = "actuator_lock_in_place"'))
    zero = load_spec(LINEAR.format(entry='kind = "actuator_lock_in_place"\nmagnitude = [0.0, 0.0]'))
    assert bare.faults == zero.faults and bare.fingerprint() == zero.fingerprint()
    fault, _ = draw_fault(bare, run_seed(5, 0), 3.0)
    assert fault.kind == "actuator_lock_in_place" and fault.magnitude == 0.0
    with pytest.raises(RobofdiError, match="exactly one of 'magnitude'"):
        load_spec(LINEAR.format(entry='kind = "actuator_additive"'))     # a sized kind still needs one


def test_no_minimum_detectable_fault_for_kinds_without_a_size():
    rows = [{"diagnoser": "d", "faulty": True, "error": None, "kind": k, "target": "u1", "profile": "step",
             "size": s, "limit": 1.0, "unit": "1", "detected": True, "isolated": "u1", "correct": True, "delay": 0.01,
             "false_alarms": 0, "isolable": True} for k, s in [("actuator_float", 0.0)] * 3 + [("actuator_scale", 0.3)] * 3]
    out = analyse(pd.DataFrame(rows), 0.9)["d"]
    assert set(out["detectability"]) == {"actuator_scale"}
    assert out["by_kind"]["actuator_float"]["detection"]["count"] == 3


def test_a_hard_over_is_drawn_within_each_joints_own_torque_limit():
    text = LINEAR.format(entry='kind = "actuator_hard_over"\nlimit_fraction = [0.5, 1.0]').replace(
        'name = "linear"\nduration = 3.0\ncalibration_runs = 2', 'name = "arm"\nrobot = "arm6.xml"')
    spec = load_spec(text)
    limits = {t: lim for t, (lim, _) in spec.faults[0].limits.items()}
    assert len(set(limits.values())) > 1                 # the arm's joints have different motor limits
    signs = set()
    for i in range(60):
        fault, info = draw_fault(spec, run_seed(5, i), 3.0)
        drawn = fault.params["limit"]
        assert 0.5 * limits[fault.target] - 1e-9 <= abs(drawn) <= limits[fault.target] + 1e-9
        assert info["limit"] == limits[fault.target] and fault.magnitude == 0.0
        signs.add(np.sign(drawn))
    assert signs == {-1.0, 1.0}
    with pytest.raises(RobofdiError, match="limit_fraction: only for actuator_hard_over without params.limit"):
        load_spec(text.replace("limit_fraction = [0.5, 1.0]", "limit_fraction = [0.5, 1.0]\nparams = {limit = 1.0}"))


def test_signed_scale_faults_draw_gains_below_and_above_one():
    spec = load_spec(LINEAR.format(entry='kind = "actuator_scale"\nmagnitude = [-0.5, 0.5]'))
    gains = [1 + draw_fault(spec, run_seed(5, i), 3.0)[0].magnitude for i in range(50)]
    assert min(gains) < 0.9 and max(gains) > 1.1 and min(gains) >= 0.5
    mirrored = load_spec(LINEAR.format(entry='kind = "sensor_scale"\nmagnitude = [0.1, 0.5]\nrandom_sign = true'))
    m = [draw_fault(mirrored, run_seed(5, i), 3.0)[0].magnitude for i in range(50)]
    assert min(m) <= -0.1 and max(m) >= 0.1 and all(0.1 <= abs(v) <= 0.5 for v in m)
    with pytest.raises(RobofdiError, match="gain 1 \\+ m must stay positive"):
        load_spec(LINEAR.format(entry='kind = "actuator_scale"\nmagnitude = [-1.0, 0.5]'))


@pytest.fixture(scope="module")
def solid_arm6(tmp_path_factory):
    """The shipped arm6 with every geom made solid (its file has contype = conaffinity = 0 and contacts off)."""
    from robofdi.mjcf import resolve_asset

    text = resolve_asset("arm6.xml").read_text().replace('contype="0" conaffinity="0"', 'contype="1" conaffinity="1"')
    text = text.replace('<flag contact="disable"/>', "")
    path = tmp_path_factory.mktemp("solid") / "arm6_solid.xml"
    path.write_text(text)
    return path


def test_a_segment_through_the_arm_itself_is_refused_and_redrawn(solid_arm6):
    import mujoco

    from robofdi.control import motions

    m = mujoco.MjModel.from_xml_path(str(solid_arm6))
    names = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt))
    check = motions._SelfCollision(solid_arm6, names)
    assert check.active and not check.contacts(0.5 * (m.jnt_range[:, 0] + m.jnt_range[:, 1]))
    poses = np.random.default_rng(0).uniform(m.jnt_range[:, 0], m.jnt_range[:, 1], size=(200, len(names)))
    hits = [q for q in poses if check.contacts(q)]
    free = [q for q in poses if not check.contacts(q)]
    assert hits and free
    g1, g2, dist = check.contacts(hits[0])[0]
    assert dist < motions.SELF_CLEARANCE and not check.rigid[g1, g2]
    # the straight segment from a clear pose into a too-close one is refused (the generator redraws it) ...
    segment = free[0] + np.linspace(0.0, 1.0, 41)[:, None] * (hits[0] - free[0])
    assert not check.free(segment) and check.free(np.array([free[0], free[0]]))
    model = type("Belief", (), {"path": solid_arm6, "joint_names": names})()
    assert not motions._collision_free(model, free[0], hits[0]) and motions._collision_free(model, free[0], free[0])
    # and the floor the base stands on (a pair no joint moves apart) never counts
    assert any(check.rigid[0, g] for g in range(1, m.ngeom) if m.geom_bodyid[g] == 0)
