"""ROS 2 bags (MCAP) of ``sensor_msgs/msg/JointState`` as robot logs, through the maintained ``mcap`` /
``mcap-ros2-support`` readers (``pip install 'robofdi[mcap]'``).

:func:`read_joint_states` turns a bag into the table :func:`robofdi.logs.read_arm_log` checks: ``time`` [s] from the
messages' header stamps (the recorder's log time where a stamp is unset), and per joint of the messages' ``name``
field ``<joint>_q`` (``position``), ``<joint>_qd`` (``velocity``) and ``<joint>_tau``. The diagnosers need the torque
the controller *commanded*: name the topic that carries it (``command_topic``, a JointState whose ``effort`` is the
command, held from its last message at each state stamp as a drive holds it); without one, the state topic's own
``effort`` is taken, which on a real robot is often the *measured* torque (the summary says which). The units are
ROS's (REP 103): rad, rad/s, N·m (m, m/s, N for prismatic joints), checked as for any log.

:func:`write_joint_states` writes such a bag (e.g. a CSV log converted, or the tests' bag).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["read_joint_states", "write_joint_states", "JOINT_STATE", "JOINT_STATE_MSGDEF"]

#: The ROS 2 type name of the messages read.
JOINT_STATE = "sensor_msgs/msg/JointState"
#: Its ROS 2 message definition with its dependencies (the schema an MCAP bag stores).
JOINT_STATE_MSGDEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


def _mcap():
    try:
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
    except ImportError:
        raise RobofdiError("ROS 2 bags (.mcap) need the optional extra: pip install 'robofdi[mcap]'") from None
    return make_reader, DecoderFactory


def _messages(path: Path, topic: str, make_reader, DecoderFactory):
    """(stamp [ns], names, position, velocity, effort) of every JointState message on ``topic``."""
    name = path.name
    with open(path, "rb") as f:
        try:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            channels = {c.topic: c for c in summary.channels.values()} if summary is not None else {}
        except Exception as exc:
            raise RobofdiError(f"log {name}: not a readable MCAP file ({' '.join(str(exc).split())})") from None
        if topic not in channels:
            raise RobofdiError(f"log {name}: no topic {topic!r}; the bag has {sorted(channels)} (choose with --topics)")
        schema = summary.schemas.get(channels[topic].schema_id)
        if schema is None or schema.name not in (JOINT_STATE, "sensor_msgs/JointState"):
            raise RobofdiError(f"log {name}: topic {topic!r} carries {getattr(schema, 'name', '?')}; expected {JOINT_STATE}")
        rows = []
        try:
            for _, _, message, msg in reader.iter_decoded_messages(topics=[topic], log_time_order=True):
                s = msg.header.stamp
                stamp = int(s.sec) * 1_000_000_000 + int(s.nanosec)
                rows.append((stamp or int(message.log_time), list(msg.name), msg.position, msg.velocity, msg.effort))
        except RobofdiError:
            raise
        except Exception as exc:
            raise RobofdiError(f"log {name}: topic {topic!r} cannot be decoded ({' '.join(str(exc).split())})") from None
    if not rows:
        raise RobofdiError(f"log {name}: topic {topic!r} has no messages")
    return rows


def _columns(name: str, topic: str, rows, fields: Sequence[str]):
    """The joints (first message's order) and, per field, an (N, n) array, each message reordered by its names."""
    joints = rows[0][1]
    if not joints:
        raise RobofdiError(f"log {name}: topic {topic!r}: the first message names no joints; expected JointState.name")
    out = {f: np.empty((len(rows), len(joints))) for f in fields}
    index = {"position": 2, "velocity": 3, "effort": 4}
    for k, row in enumerate(rows):
        names = row[1]
        if names != joints:
            if sorted(names) != sorted(joints):
                raise RobofdiError(f"log {name}: topic {topic!r}: message {k + 1} names joints {names}; expected the "
                                   f"first message's {joints}")
            order = [names.index(j) for j in joints]
        else:
            order = None
        for f in fields:
            value = np.asarray(row[index[f]], dtype=float)
            if value.size != len(names):
                raise RobofdiError(f"log {name}: topic {topic!r}: message {k + 1} has {value.size} {f} values for "
                                   f"{len(names)} joints; expected JointState.{f} for every joint")
            out[f][k] = value if order is None else value[order]
    return joints, out


def read_joint_states(path: str | Path, state_topic: str = "/joint_states", command_topic: str | None = None):
    """The bag at ``path`` as a table (a pandas DataFrame, module docstring) and where its torques came from:
    (table, {"state_topic", "command_topic", "tau_source"})."""
    import pandas as pd

    make_reader, DecoderFactory = _mcap()
    path = Path(path)
    state = _messages(path, state_topic, make_reader, DecoderFactory)
    joints, values = _columns(path.name, state_topic, state, ("position", "velocity") if command_topic else
                              ("position", "velocity", "effort"))
    stamps = np.array([r[0] for r in state], dtype=np.int64)
    table = {"time": (stamps - stamps[0]) / 1e9}
    if command_topic:
        command = _messages(path, command_topic, make_reader, DecoderFactory)
        cjoints, cvalues = _columns(path.name, command_topic, command, ("effort",))
        missing = [j for j in joints if j not in cjoints]
        if missing:
            raise RobofdiError(f"log {path.name}: topic {command_topic!r} commands no joint {missing[0]!r}; expected "
                               f"every joint of {state_topic!r}")
        cstamps = np.array([r[0] for r in command], dtype=np.int64)
        held = np.searchsorted(cstamps, stamps, side="right") - 1
        if held[0] < 0:
            first = float((cstamps[0] - stamps[0]) / 1e9)
            raise RobofdiError(f"log {path.name}: topic {command_topic!r} starts {first:.6g} s after {state_topic!r}; "
                               "expected a command at or before the first state (trim the bag)")
        effort = cvalues["effort"][held][:, [cjoints.index(j) for j in joints]]
        source = f"{command_topic} effort (commanded)"
    else:
        effort = values["effort"]
        source = f"{state_topic} effort (no command topic: the state's own effort)"
    for i, j in enumerate(joints):
        table[f"{j}_q"], table[f"{j}_qd"], table[f"{j}_tau"] = values["position"][:, i], values["velocity"][:, i], effort[:, i]
    return pd.DataFrame(table), {"state_topic": state_topic, "command_topic": command_topic, "tau_source": source}


def write_joint_states(path: str | Path, time: np.ndarray, joints: Sequence[str], position: np.ndarray,
                       velocity: np.ndarray, effort: np.ndarray | None = None, topic: str = "/joint_states",
                       command: np.ndarray | None = None, command_topic: str = "/joint_commands",
                       start_ns: int = 1_700_000_000_000_000_000) -> Path:
    """Write a ROS 2 bag (MCAP, zstd chunks) of JointState messages: ``position`` / ``velocity`` / ``effort``
    (N, n) at ``time`` (N,) [s after ``start_ns``, the POSIX time of the first stamp] on ``topic`` and, with
    ``command`` (N, n), the commanded torques as JointState efforts on ``command_topic``. Returns the path."""
    _mcap()
    from mcap_ros2.writer import Writer

    t = np.asarray(time, dtype=float)
    joints = [str(j) for j in joints]
    arrays = {"position": position, "velocity": velocity, "effort": effort, "command": command}
    for key, value in arrays.items():
        if value is not None and np.shape(value) != (t.size, len(joints)):
            raise RobofdiError(f"write_joint_states: field {key!r} must have shape ({t.size}, {len(joints)}), got "
                               f"{np.shape(value)}")
    stamps = start_ns + np.rint(t * 1e9).astype(np.int64)
    path = Path(path)
    with open(path, "wb") as f:
        writer = Writer(f)
        schema = writer.register_msgdef(JOINT_STATE, JOINT_STATE_MSGDEF)
        for k, ns in enumerate(stamps):
            ns = int(ns)
            header = {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": ""}
            msg = {"header": header, "name": joints, "position": [float(v) for v in position[k]],
                   "velocity": [float(v) for v in velocity[k]],
                   "effort": [] if effort is None else [float(v) for v in effort[k]]}
            writer.write_message(topic=topic, schema=schema, message=msg, log_time=ns, publish_time=ns)
            if command is not None:
                cmd = {"header": header, "name": joints, "position": [], "velocity": [],
                       "effort": [float(v) for v in command[k]]}
                writer.write_message(topic=command_topic, schema=schema, message=cmd, log_time=ns, publish_time=ns)
        writer.finish()
    return path
