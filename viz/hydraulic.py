"""Meshcat replay of a hydraulic-rig record: the motor shaft, coupling, pump and wheel turning (true shaft angle),
the load pressure as the colour of an indicator on the motor housing (blue = 0 → red = the catalogue supply
pressure), a yellow ring while a true fault is active and a red sphere from the primary diagnoser's first alarm."""
from __future__ import annotations

from pathlib import Path

import meshcat.geometry as g
import meshcat.transformations as tf
import numpy as np
from meshcat.animation import Animation

from robofdi.errors import RobofdiError

from .meshcat_local import offline_visualizer
from .replay import _animate_visibility, _as_record, close_visualizer, resolve_mjcf
from .scene import MeshcatScene, rgba_to_material

__all__ = ["build_hydraulic_replay", "write_hydraulic_replay", "PRESSURE_BINS"]

ROOT = "rig"
PRESSURE_BINS = 8
FULL_SCALE = 3000 * 6894.757          # Pa, colour scale


def _pressure_colour(i: int) -> tuple:
    a = i / (PRESSURE_BINS - 1)
    return (a, 0.2, 1.0 - a, 1.0)


def build_hydraulic_replay(vis, record, diagnoser: str | None = None, fps: int = 50) -> dict:
    """Draw the rig and animate it; returns {"frames": n, "markers": [paths]}."""
    if "shaft_angle" not in (record.columns.get("truth/state") or []):
        raise RobofdiError("record: not a hydraulic-rig record (truth/state has no 'shaft_angle' column)")
    scene = MeshcatScene(resolve_mjcf(record))
    cols = record.columns["truth/state"]
    t = np.asarray(record.time)
    ft = np.arange(0.0, t[-1] + 1e-9, 1.0 / fps)
    angle = np.interp(ft, t, record.truth_state[:, cols.index("shaft_angle")])
    pressure = np.interp(ft, t, record.truth_state[:, cols.index("load_pressure")])
    vis[ROOT].delete()
    scene.draw(vis, ROOT)
    anim = Animation(default_framerate=fps)
    for i, a in enumerate(angle):
        with anim.at_frame(vis, i) as frame:
            scene.set_pose(frame, np.array([a, a]), ROOT)
    bins = np.clip((np.abs(pressure) / FULL_SCALE * (PRESSURE_BINS - 1) * 8).round().astype(int), 0, PRESSURE_BINS - 1)
    paths = []
    at = tf.translation_matrix([0.0, 0.0, 0.3])
    for i in range(PRESSURE_BINS):
        path = f"{ROOT}/pressure/bin{i}"
        vis[path].set_object(g.Sphere(0.06), rgba_to_material(_pressure_colour(i)))
        vis[path].set_transform(at)
        shown = [(ft[k], ft[k] + 1.0 / fps) for k in np.flatnonzero(bins == i)]
        _animate_visibility(anim, vis, path, shown, ft)
    faults = (record.meta or {}).get("faults", [])
    if faults:
        path = f"{ROOT}/fault_onset"
        vis[path].set_object(g.Cylinder(0.02, 0.3), rgba_to_material((1.0, 0.85, 0.0, 0.6)))
        vis[path].set_transform(tf.translation_matrix([0.0, 0.0, 0.42]))
        _animate_visibility(anim, vis, path, [(f["onset"], f["end"] if f["end"] is not None else np.inf)
                                              for f in faults], ft)
        paths.append(path)
    diag = diagnoser or (record.meta or {}).get("primary_diagnoser")
    if diag in record.diagnosers:
        tr = record.diagnosers[diag]
        hits = np.flatnonzero(np.asarray(tr.alarm).any(axis=1))
        if hits.size:
            path = f"{ROOT}/fault_detected"
            vis[path].set_object(g.Sphere(0.09), rgba_to_material((1.0, 0.0, 0.0, 0.5)))
            vis[path].set_transform(tf.translation_matrix([0.0, 0.0, 0.55]))
            _animate_visibility(anim, vis, path, [(float(tr.time[hits[0]]), np.inf)], ft)
            paths.append(path)
    vis.set_animation(anim, play=True, repetitions=1)
    return {"frames": ft.size, "markers": paths, "pressure_bins": bins}


def write_hydraulic_replay(record, path: str | Path, diagnoser: str | None = None, fps: int = 25) -> Path:
    """Self-contained HTML replay of a hydraulic-rig record (or the path of a saved one)."""
    record = _as_record(record)
    path = Path(path)
    vis = offline_visualizer()              # no server
    try:
        build_hydraulic_replay(vis, record, diagnoser, fps)
        html = vis.static_html()
    finally:
        close_visualizer(vis)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path
