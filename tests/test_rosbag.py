"""ROS 2 bags (MCAP of sensor_msgs/JointState) as robot logs: a bag written here with the mcap writer from the
shipped arm6 log is diagnosed like the CSV (detected, isolated, quiet on its fault-free part); bad bags are one
line naming the topic."""
from __future__ import annotations

import json
import sys

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("mcap_ros2.writer", reason="ROS 2 bags need the optional extra 'mcap'")

from robofdi import ASSETS, RobofdiError  # noqa: E402
from robofdi.cli import build_parser  # noqa: E402
from robofdi.logs import diagnose_log, parse_columns, parse_topics  # noqa: E402
from robofdi.rosbag import read_joint_states, write_joint_states  # noqa: E402

LOG = ASSETS / "logs" / "arm6_cycles.csv.gz"
TRUTH = json.loads((ASSETS / "logs" / "arm6_cycles.json").read_text())
JOINTS = [f"joint{i}" for i in range(1, 7)]
START, END = 7.0, 11.5         # the bag holds the log from 7 s to 11.5 s: 3.4 s fault-free (one cycle), then the fault


def _arrays(t0=START, t1=None):
    df = pd.read_csv(LOG).rename(columns=TRUTH["columns"])
    df = df[(df["time"] >= t0) & (df["time"] <= (t1 if t1 is not None else np.inf))]
    return (df["time"].to_numpy() - t0, *(df[[f"{j}_{k}" for j in JOINTS]].to_numpy() for k in ("q", "qd", "tau")))


def test_a_bag_is_diagnosed_like_the_csv(tmp_path):
    t, q, qd, tau = _arrays(START, END)
    names = [f"arm_j{i}" for i in range(1, 7)]         # the robot's own joint names, mapped by --columns NAME=joint
    bag = write_joint_states(tmp_path / "arm6.mcap", t, names, q, qd, tau)
    columns = parse_columns(",".join(f"arm_j{i}=joint{i}" for i in range(1, 7)))
    _, summary = diagnose_log(bag, "arm6.xml", (0.0, 3.3), columns=columns, schemes=("momentum",))
    d = summary["diagnosers"]["momentum"]
    onset = TRUTH["fault"]["onset"] - START
    assert d["alarm_samples_in_fault_free_segment"] == 0
    assert onset < d["first_alarm_s"] < onset + 0.3 and d["isolated"] == TRUTH["fault"]["target"]
    assert summary["log"]["tau_source"].startswith("/joint_states effort") and summary["log"]["dropouts"] > 0
    args = build_parser().parse_args(["diagnose", str(bag), "--robot", "arm6.xml", "--fault-free", "0:3",
                                      "--topics", "/joint_states,/joint_commands"])
    assert args.topics == "/joint_states,/joint_commands"


def test_commands_on_their_own_topic_are_held(tmp_path):
    t, q, qd, tau = (a[:40] for a in _arrays(0.0))
    bag = write_joint_states(tmp_path / "cmd.mcap", t, JOINTS, q, qd, None, command=tau)
    table, origin = read_joint_states(bag, "/joint_states", "/joint_commands")
    assert origin["tau_source"] == "/joint_commands effort (commanded)"
    np.testing.assert_allclose(table["time"], t, atol=1e-9)
    np.testing.assert_allclose(table[[f"{j}_tau" for j in JOINTS]].to_numpy(), tau)
    np.testing.assert_allclose(table[[f"{j}_qd" for j in JOINTS]].to_numpy(), qd)
    with pytest.raises(RobofdiError, match=r"no topic '/cmd'; the bag has \['/joint_commands', '/joint_states'\]"):
        read_joint_states(bag, "/joint_states", "/cmd")
    # the state topic has no effort: without a command topic, one line naming the field
    with pytest.raises(RobofdiError, match=r"message 1 has 0 effort values for 6 joints"):
        read_joint_states(bag)


def test_bad_bags_and_topics_are_one_line(tmp_path):
    garbage = tmp_path / "bad.mcap"
    garbage.write_bytes(b"not an mcap file at all")
    with pytest.raises(RobofdiError, match="bad.mcap: not a readable MCAP file"):
        read_joint_states(garbage)
    t, q, qd, tau = (a[:20] for a in _arrays(0.0))
    small = write_joint_states(tmp_path / "small.mcap", t, JOINTS, q, qd, tau)
    from robofdi.logs import read_arm_log
    from robofdi.models import ManipulatorModel

    model = ManipulatorModel("arm6.xml")
    with pytest.raises(RobofdiError, match="not a ROS 2 bag"):
        read_arm_log(LOG, model, TRUTH["columns"], topics="/joint_states")
    with pytest.raises(RobofdiError, match="--topics: expected STATE"):
        parse_topics("joint_states")
    assert parse_topics("/a,/b") == ("/a", "/b") and parse_topics(None) == ("/joint_states", None)
    with pytest.raises(RobofdiError, match="field 'velocity' must have shape"):
        write_joint_states(tmp_path / "x.mcap", t, JOINTS, q, qd[:3], tau)
    assert read_arm_log(small, model, rate=500.0).q.shape[1] == 6


def test_without_mcap_says_what_to_install(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "mcap.reader", None)
    with pytest.raises(RobofdiError, match=r"pip install 'robofdi\[mcap\]'"):
        read_joint_states(tmp_path / "any.mcap")
