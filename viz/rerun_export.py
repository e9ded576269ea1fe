"""A run folder as one rerun recording (``.rrd``, ``pip install 'robofdi[rerun]'``): the 3-D motion of the robot, every
diagnoser's residuals against its thresholds, its alarms, the isolated part highlighted, and the true faults, all
on one timeline ``time`` [s]. Open it with the rerun viewer (``rerun run.rrd``); Meshcat stays the default replay.

Entities:

* ``world/robot/<body>``: each body's pose per frame (``Transform3D``, from the record's joint positions through
  MuJoCo's kinematics of the record's MJCF), its geoms below it as rerun primitives or meshes (``.../geom_<i>``).
  A body whose joint a diagnoser isolates turns red at the isolation time (the lead diagnoser's isolation).
* ``joints/<joint>``: the joint positions [rad or m].
* ``residuals/<diagnoser>/<component>`` and ``thresholds/<diagnoser>/<component>``: scalars in the residual's unit.
* ``alarms/<diagnoser>/<component>``: 1 while the component alarms, else 0.
* ``faults/<name>``: the true fault's label value (0 while inactive), in its unit.
* ``events``: text entries at every true onset/end, every diagnoser's first alarm and every change of isolation.
"""
from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

try:
    import rerun as rr
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("robofdi.viz.rerun_export needs rerun-sdk: pip install 'robofdi[rerun]'") from None

from robofdi.errors import RobofdiError
from robofdi.record import Record, load

from .replay import _choose_diagnoser, _resample, isolated_joints, resolve_mjcf, scene_joints
from .scene import MeshcatScene

__all__ = ["export_rrd", "TIMELINE"]

#: The one timeline of the recording: the run's time [s].
TIMELINE = "time"
HIGHLIGHT = (230, 30, 30, 255)


def _colour(rgba) -> tuple[int, int, int, int]:
    return tuple(int(round(255 * float(np.clip(c, 0, 1)))) for c in rgba)


def _shape(m: mujoco.MjModel, gs, colour):
    """The rerun archetype of one drawn geom, in its own frame (MuJoCo's geom frame; capsules and cylinders on z)."""
    size = np.asarray(gs.size, dtype=float)
    if gs.type == "sphere":
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[colour], fill_mode="solid")
    if gs.type == "ellipsoid":
        return rr.Ellipsoids3D(half_sizes=[size[:3]], colors=[colour], fill_mode="solid")
    if gs.type == "box":
        return rr.Boxes3D(half_sizes=[size[:3]], colors=[colour], fill_mode="solid")
    if gs.type == "capsule":
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]], colors=[colour])
    if gs.type == "cylinder":
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], colors=[colour], fill_mode="solid")
    if gs.type == "plane":
        half = [size[0] or 2.0, size[1] or 2.0, 1e-3]
        return rr.Boxes3D(half_sizes=[half], colors=[colour], fill_mode="solid")
    if gs.type == "mesh" and gs.vertices is not None:
        return rr.Mesh3D(vertex_positions=np.asarray(gs.vertices, dtype=np.float32),
                         triangle_indices=np.asarray(gs.faces, dtype=np.uint32), albedo_factor=colour)
    return None


def _geom_frame(m: mujoco.MjModel, i: int) -> rr.Transform3D:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, m.geom_quat[i])
    return rr.Transform3D(translation=m.geom_pos[i], mat3x3=R.reshape(3, 3))


def _series(rec: rr.RecordingStream, path: str, t: np.ndarray, values: np.ndarray) -> None:
    rec.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(t, dtype=float))],
                     columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float)))


def _robot(rec: rr.RecordingStream, record: Record, folder, fps: int, lead: str | None) -> None:
    scene = MeshcatScene(resolve_mjcf(record, folder))
    m = scene.model
    frames, qpos = _resample(record, scene, fps)
    drawn: dict[str, list] = {}
    rec.set_time(TIMELINE, duration=float(frames[0]))
    for gs in scene.geoms:
        shape = _shape(m, gs, _colour(gs.rgba))
        if shape is None:
            continue
        path = f"world/robot/{gs.body}/geom_{gs.index}"
        rec.log(path, _geom_frame(m, gs.index), static=True)
        rec.log(path, shape)
        drawn.setdefault(gs.body, []).append(gs)
    for t, q in zip(frames, qpos):
        rec.set_time(TIMELINE, duration=float(t))
        for body, T in scene.body_transforms(q).items():
            if body in drawn and body != scene.body_names[0]:      # the world body stays where it is
                rec.log(f"world/robot/{body}", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))
    if lead is None:
        return
    alias = scene_joints(record, scene)
    trace = record.diagnosers[lead]
    lit: set[str] = set()
    for t, iso in zip(trace.time, trace.isolated):
        iso = iso.decode() if isinstance(iso, bytes) else str(iso)
        joints = {alias[j] for j in isolated_joints(iso, list(alias))} if iso else set()
        if joints == lit:
            continue
        rec.set_time(TIMELINE, duration=float(t))
        for joint in lit | joints:
            body = scene.joint(joint)["body"]
            for gs in drawn.get(body, []):
                colour = HIGHLIGHT if joint in joints else _colour(gs.rgba)
                shape = _shape(m, gs, colour)
                rec.log(f"world/robot/{body}/geom_{gs.index}", shape)
        lit = joints


def _events(record: Record) -> list[tuple[float, str, str]]:
    out = []
    for f in (record.meta or {}).get("faults") or []:
        if isinstance(f, dict) and f.get("onset") is not None:
            out.append((float(f["onset"]), f"true fault {f.get('name')} ({f.get('kind')} on {f.get('target')}) starts",
                        "WARN"))
            if f.get("end") is not None:
                out.append((float(f["end"]), f"true fault {f.get('name')} ends", "INFO"))
    for name, tr in record.diagnosers.items():
        alarm = np.asarray(tr.alarm, dtype=bool).reshape(len(tr.time), -1).any(axis=1)
        if alarm.any():
            k = int(np.argmax(alarm))
            out.append((float(tr.time[k]), f"{name}: first alarm", "WARN"))
        previous = ""
        for t, iso in zip(tr.time, tr.isolated):
            iso = iso.decode() if isinstance(iso, bytes) else str(iso)
            if iso != previous:
                out.append((float(t), f"{name}: isolated {iso or 'nothing'}", "ERROR" if iso else "INFO"))
                previous = iso
    return sorted(out)


def export_rrd(run, path: str | Path | None = None, fps: int = 25, diagnoser: str | None = None,
               robot: bool = True) -> Path:
    """Write ``run`` — a run folder (its ``record.h5``), a record file, or a :class:`~robofdi.record.Record` — as a
    rerun recording at ``path`` (default: ``run.rrd`` in the run folder). ``fps``: frames of the 3-D motion per
    second; ``diagnoser``: whose isolation lights the robot (default: the run's lead); ``robot=False`` leaves the
    3-D motion out (a record without an MJCF). Returns the path."""
    folder = None
    if isinstance(run, Record):
        record = run
    else:
        p = Path(run)
        file = p / "record.h5" if p.is_dir() else p
        if not file.is_file():
            raise RobofdiError(f"run: {str(p)!r} is neither a run folder with record.h5 nor a record file")
        folder, record = file.parent, load(file)
    if isinstance(fps, bool) or not isinstance(fps, int) or fps < 1:
        raise RobofdiError(f"fps: expected an integer >= 1 frames per second, got {fps!r}")
    if path is None:
        if folder is None:
            raise RobofdiError("path: expected the .rrd file to write (a Record has no run folder)")
        path = folder / "run.rrd"
    path = Path(path)
    lead = _choose_diagnoser(record, diagnoser) if record.diagnosers else None
    rec = rr.RecordingStream("robofdi", recording_id=f"{record.system}-{record.scenario}-{record.seed}")
    rec.save(str(path))
    try:
        events = _events(record)
        if robot:
            _robot(rec, record, folder, fps, lead)
        t = np.asarray(record.time, dtype=float)
        x = np.asarray(record.truth_state, dtype=float).reshape(t.size, -1)
        names = list((record.meta or {}).get("joint_names") or (record.columns or {}).get("truth/state") or [])
        names = names[:x.shape[1] // 2] if len(names) >= x.shape[1] else names
        for k, name in enumerate(names or [f"q{i}" for i in range(x.shape[1] // 2)]):
            _series(rec, f"joints/{name}", t, x[:, k])       # the positions: the state's first columns
        for name, tr in record.diagnosers.items():
            td = np.asarray(tr.time, dtype=float)
            r = np.asarray(tr.residual, dtype=float).reshape(td.size, -1)
            alarm = np.asarray(tr.alarm, dtype=float).reshape(td.size, -1)
            thr = np.broadcast_to(np.asarray(tr.threshold, dtype=float).reshape(-1), (r.shape[1],))
            for j, comp in enumerate(tr.components):
                _series(rec, f"residuals/{name}/{comp}", td, r[:, j])
                if np.isfinite(thr[j]):
                    _series(rec, f"thresholds/{name}/{comp}", td, np.full(td.size, thr[j]))
                _series(rec, f"alarms/{name}/{comp}", td, alarm[:, j])
        for name, labels_ in (record.faults or {}).items():
            _series(rec, f"faults/{name}", t, np.where(np.asarray(labels_.active, bool), labels_.value, 0.0))
        for when, text, level in events:
            rec.set_time(TIMELINE, duration=when)
            rec.log("events", rr.TextLog(text, level=level))
    finally:
        rec.flush()
        rec.disconnect()
    return path
