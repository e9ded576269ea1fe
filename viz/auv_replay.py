"""Self-contained Meshcat replay of an AUV run record (robofdi.sims.auv): the vehicle's pose from its quaternion,
one arrow per thruster scaled by its thrust, the reference path, a yellow marker on a thruster from its true fault
onset, and the thruster drawn red from the first diagnosis sample that isolates it.

Tree (below ``auv_scene``, shifted up by the start depth so the orbit camera looks at the vehicle)::

    auv_scene/reference               the reference path (line)
    auv_scene/hull                    transform = the hull's pose (world position, quaternion)
    auv_scene/hull/<thruster>         fixed: the thruster's position, its y-axis along the thrust
    auv_scene/hull/<thruster>/arrow   scale (1, T / T_ref, 1): the thrust arrow
    auv_scene/hull/<thruster>/failed  red, visible from detection;  .../onset  yellow, visible from onset
"""
from __future__ import annotations

from pathlib import Path

import meshcat
import meshcat.geometry as g
import meshcat.transformations as tf
import mujoco
import numpy as np
from meshcat.animation import Animation

from robofdi import RobofdiError

__all__ = ["build_auv_replay", "write_auv_replay_html", "thruster_detection_times"]

ROOT = "auv_scene"
ARROW_PER_NEWTON = 0.5 / 40.0          # [m/N]: 40 N draws a 0.5 m arrow


def _y_to(direction: np.ndarray) -> np.ndarray:
    """Rotation matrix taking +y onto ``direction``."""
    d = direction / np.linalg.norm(direction)
    y = np.array([0.0, 1.0, 0.0])
    v, c = np.cross(y, d), float(y @ d)
    if np.linalg.norm(v) < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    S = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + S + S @ S * (1 - c) / (np.linalg.norm(v) ** 2)


def thruster_detection_times(record, diagnoser: str | None, thrusters) -> dict[str, float]:
    """First time each thruster appears in ``diagnoser``'s isolated set (thrusters never isolated are absent)."""
    if diagnoser is None or diagnoser not in record.diagnosers:
        return {}
    tr = record.diagnosers[diagnoser]
    out: dict[str, float] = {}
    for t, iso in zip(tr.time, tr.isolated):
        for name in str(iso).split("+"):
            name = name.split(":", 1)[0]
            if name in thrusters and name not in out:
                out[name] = float(t)
    return out


def build_auv_replay(vis: meshcat.Visualizer, record, diagnoser: str | None = None, fps: int = 10) -> Animation:
    """Draw the vehicle of ``record`` (its MJCF in ``record.meta["mjcf"]``) and animate it at ``fps``; thrusters
    turn red when ``diagnoser`` (default: the run's health source, else its first diagnoser) isolates them."""
    from robofdi.models.auv import thruster_layout
    from robofdi.mjcf import resolve_asset

    if not isinstance(fps, int) or fps <= 0:
        raise RobofdiError(f"fps: expected a positive integer, got {fps!r}")
    model = mujoco.MjModel.from_xml_path(str(resolve_asset(record.meta.get("mjcf", "auv.xml"))))
    names, P, D = thruster_layout(model)
    cols = record.columns["truth/state"]
    if cols[:7] != ["x", "y", "z", "qw", "qx", "qy", "qz"]:
        raise RobofdiError("AUV replay: the record's truth/state does not start with the hull pose [x y z qw qx qy qz]")
    time = record.time
    frames = np.arange(0.0, time[-1] + 1e-9, 1.0 / fps)
    idx = np.clip(np.searchsorted(time, frames), 0, len(time) - 1)
    pose, thrust = record.truth_state[idx, :7], record.u_applied[idx]
    shift = np.array([0.0, 0.0, -float(record.truth_state[0, 2])])

    vis[ROOT].delete()
    vis[ROOT].set_transform(tf.translation_matrix(shift))
    ref = record.signals["reference"][:, :3].T.astype(np.float32)
    vis[ROOT]["reference"].set_object(g.Line(g.PointsGeometry(ref), g.LineBasicMaterial(color=0x2266cc)))
    hull = vis[ROOT]["hull"]
    radius = float(model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "hull")][0])
    hull["body"].set_object(g.Sphere(radius), g.MeshLambertMaterial(color=0xe6bf1a, opacity=0.85, transparent=True))
    hull["nose"].set_object(g.Box([0.12, 0.04, 0.04]), g.MeshLambertMaterial(color=0x333333))
    hull["nose"].set_transform(tf.translation_matrix([radius, 0, 0]))
    for n, p, d in zip(names, P, D):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = _y_to(d), p
        th = hull[n]
        th.set_transform(T)
        th["housing"].set_object(g.Cylinder(0.08, 0.04), g.MeshLambertMaterial(color=0x555555))
        th["failed"].set_object(g.Cylinder(0.09, 0.05), g.MeshLambertMaterial(color=0xee1111))
        th["onset"].set_object(g.Sphere(0.07), g.MeshLambertMaterial(color=0xffd900, opacity=0.5, transparent=True))
        th["arrow"]["shaft"].set_object(g.Cylinder(1.0, 0.012), g.MeshLambertMaterial(color=0x11aa44))
        th["arrow"]["shaft"].set_transform(tf.translation_matrix([0, 0.5, 0]))

    diagnoser = diagnoser or record.meta.get("health_source") or next(iter(record.diagnosers), None)
    detected = thruster_detection_times(record, diagnoser, names)
    onset = {}
    for f in record.meta.get("faults", []):
        if f["target"] in names:
            onset[f["target"]] = min(onset.get(f["target"], np.inf), f["onset"])
    anim = Animation(default_framerate=fps)
    for k in range(len(frames)):
        with anim.at_frame(vis, k) as frame:
            T = tf.quaternion_matrix(pose[k, 3:7])
            T[:3, 3] = pose[k, :3]
            frame[ROOT]["hull"].set_transform(T)
            for i, n in enumerate(names):
                th = frame[ROOT]["hull"][n]
                length = float(thrust[k, i]) * ARROW_PER_NEWTON
                th["arrow"].set_property("scale", "vector3", [1.0, length if abs(length) > 1e-3 else 1e-3, 1.0])
                if k == 0 or k == len(frames) - 1 or n in detected or n in onset:
                    th["failed"].set_property("visible", "boolean", bool(frames[k] >= detected.get(n, np.inf)))
                    th["onset"].set_property("visible", "boolean", bool(frames[k] >= onset.get(n, np.inf)))
    vis.set_animation(anim, play=True, repetitions=1)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [3.0, 2.0, 3.0])
    return anim


def write_auv_replay_html(record, path: str | Path, diagnoser: str | None = None, fps: int = 10) -> Path:
    """Write the self-contained HTML replay (meshcat's JS inlined, offline) to ``path``; returns the path
    (:func:`robofdi.viz.write_replay_html`, which sends AUV records here)."""
    from robofdi.viz.replay import _as_record, _system_replay, write_replay_html

    record = _as_record(record)
    if _system_replay(record) is not build_auv_replay:
        raise RobofdiError(f"AUV replay: the record is not an AUV run (system {record.system!r}; expected 'auv' or "
                           "meta['replay'] = 'auv')")
    return write_replay_html(record, path, diagnoser, fps)
