"""Replay a run record of a MuJoCo robot in meshcat, with the faults and their diagnosis overlaid.

For every joint that is a fault target (``record.meta["faults"][k]["target"]``, sensor channels such as
``joint5_pos`` map to ``joint5``) and every joint the chosen diagnoser isolates, two markers ride on the
joint's body:

* ``robot/<body>/fault_onset_<joint>``: a yellow translucent ring around the joint axis, visible while a
  true fault on that joint is active (from its ``onset`` to its ``end``, ``end`` None = to the end of the run);
* ``robot/<body>/fault_detected_<joint>``: a red translucent, slightly inflated copy of the link's geoms plus
  a red sphere at the joint, visible from the first diagnosis sample whose ``isolated`` contains that joint.

The visibility is animated (``visible`` boolean tracks) together with the body transforms, so the markers
move with the link in the browser.
"""
from __future__ import annotations

import contextlib
import math
import signal
import threading
import time as _time
import webbrowser
from dataclasses import dataclass, field
from pathlib import Path

import meshcat
import meshcat.geometry as g
import numpy as np
from meshcat.animation import Animation

import robofdi
from robofdi import RobofdiError

from .meshcat_local import local_visualizer, offline_visualizer
from .scene import MeshcatScene, rgba_to_material

__all__ = ["Replay", "Marker", "resolve_mjcf", "scene_joints", "fault_joint", "isolated_joints", "build_replay",
           "write_replay_html", "view", "close_visualizer", "REPLAYS", "register_replay"]

ROOT = "robot"
ONSET_RGBA = (1.0, 0.85, 0.0, 0.55)
DETECTED_RGBA = (0.95, 0.05, 0.05, 0.45)
_ONSET_NAME = "fault_onset_{}"
_DETECTED_NAME = "fault_detected_{}"


@dataclass
class Marker:
    """One overlay marker: its meshcat path (below the visualizer root) and when it is shown."""

    joint: str
    kind: str                         # "onset" or "detected"
    path: str                         # e.g. "robot/link3/fault_onset_joint3"
    intervals: list[tuple[float, float]] = field(default_factory=list)   # record-time [start, end) shown

    @property
    def first_visible(self) -> float | None:
        return min((a for a, _ in self.intervals), default=None)


@dataclass
class Replay:
    """What :func:`build_replay` put into the visualizer."""

    scene: MeshcatScene
    animation: Animation
    fps: int
    frame_times: np.ndarray           # record time of every animation frame
    diagnoser: str | None
    markers: list[Marker]

    def marker(self, joint: str, kind: str) -> Marker | None:
        return next((m for m in self.markers if m.joint == joint and m.kind == kind), None)


# ---------------------------------------------------------------------------- record helpers
def resolve_mjcf(record, folder: str | Path | None = None) -> Path:
    """The model file of ``record``: ``record.meta["mjcf"]`` (an MJCF XML or a compiled ``.mjb``); a relative name
    is the file of that name in ``folder`` (the record's run folder, where e.g. the robosuite experiment writes the
    environment's MJCF) if there is one, else in ``robofdi.ASSETS``."""
    name = (record.meta or {}).get("mjcf")
    if not name or not isinstance(name, str):
        raise RobofdiError("record.meta['mjcf']: missing; expected the MJCF file name of the simulated robot")
    p = Path(name)
    if not p.is_absolute():
        local = Path(folder) / p if folder is not None else None
        p = local if local is not None and local.is_file() else Path(robofdi.ASSETS) / p
    return p


def scene_joints(record, scene: MeshcatScene) -> dict[str, str]:
    """Record joint name → the scene's joint name: the same, or with ``record.meta["mjcf_joint_prefix"]`` added
    (robosuite names the Panda's ``joint2`` ``robot0_joint2`` in its MJCF)."""
    prefix = str((record.meta or {}).get("mjcf_joint_prefix") or "")
    out = {j: j for j in scene.joint_names}
    if prefix:
        out.update({j[len(prefix):]: j for j in scene.joint_names if j.startswith(prefix)})
    return out


def fault_joint(target: str, joint_names) -> str | None:
    """Joint that a fault target refers to: ``"joint3"`` -> joint3, ``"joint5_pos"``/``"joint5_vel"`` -> joint5."""
    target = str(target).strip()
    if target in joint_names:
        return target
    head, sep, _ = target.rpartition("_")
    while sep:
        if head in joint_names:
            return head
        head, sep, _ = head.rpartition("_")
    return None


def isolated_joints(isolated: str, joint_names) -> set[str]:
    """Joints named by one ``isolated`` entry such as ``"joint3+joint5_pos"``."""
    out = set()
    for part in str(isolated).split("+"):
        j = fault_joint(part, joint_names) if part.strip() else None
        if j is not None:
            out.add(j)
    return out


def _choose_diagnoser(record, diagnoser: str | None) -> str | None:
    """``diagnoser`` if given (checked), else the run's lead (:func:`robofdi.evaluate.headline.record_lead`: the one
    the experiment named, else the accommodation's health source, else the best outcome on the labels)."""
    from robofdi.evaluate.headline import record_lead

    diags = record.diagnosers or {}
    if diagnoser is not None:
        if diagnoser not in diags:
            raise RobofdiError(f"diagnoser {diagnoser!r}: not in the record (available: {sorted(diags)})")
        return diagnoser
    return record_lead(record)


def _fault_intervals(record, joint_names) -> dict[str, list[tuple[float, float]]]:
    """Intervals of the true faults per joint; ``joint_names`` is a list, or a mapping record name → scene name."""
    alias = joint_names if isinstance(joint_names, dict) else {j: j for j in joint_names}
    faults = (record.meta or {}).get("faults") or []
    out: dict[str, list[tuple[float, float]]] = {}
    for k, f in enumerate(faults):
        if not isinstance(f, dict) or "target" not in f:
            raise RobofdiError(f"record.meta['faults'][{k}]: expected a dict with 'target' and 'onset'")
        j = fault_joint(f["target"], list(alias))
        if j is None:
            continue  # not a joint-related fault: nothing to draw on the arm
        j = alias[j]
        onset = f.get("onset")
        onset = 0.0 if onset is None else float(onset)
        end = f.get("end")
        end = math.inf if end is None or not np.isfinite(float(end)) else float(end)
        out.setdefault(j, []).append((onset, end))
    return out


def _detection_times(record, diag: str | None, joint_names) -> dict[str, float]:
    """First isolation time per joint; ``joint_names`` as in :func:`_fault_intervals`."""
    alias = joint_names if isinstance(joint_names, dict) else {j: j for j in joint_names}
    if diag is None:
        return {}
    tr = record.diagnosers[diag]
    out: dict[str, float] = {}
    for t, iso in zip(np.asarray(tr.time, dtype=float), tr.isolated):
        if isinstance(iso, bytes):
            iso = iso.decode()
        if not iso:
            continue
        for j in isolated_joints(iso, list(alias)):
            out.setdefault(alias[j], float(t))
    return out


def _resample(record, scene: MeshcatScene, fps: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame times at ``fps`` and the full qpos of the scene at each: the record's whole MuJoCo qpos if it has one
    (``signals["qpos"]``, e.g. a robosuite episode: arm, fingers and the cube's free joint), else the recorded
    joints (``meta["joint_names"]``, the first columns of the state) at their addresses and every other joint (a
    gripper) at its reference qpos0. A record without either is read as qpos first (the whole qpos)."""
    t = np.asarray(record.time, dtype=float).reshape(-1)
    x = np.asarray(record.truth_state, dtype=float)
    if t.size == 0:
        raise RobofdiError("record.time: empty; expected at least one time stamp")
    qpos = (record.signals or {}).get("qpos")
    if qpos is not None:
        qpos = np.asarray(qpos, dtype=float)
        if qpos.shape != (t.size, scene.nq):
            raise RobofdiError(f"record.signals['qpos']: expected shape ({t.size}, {scene.nq}) (the model's qpos at "
                               f"every time stamp), got {qpos.shape}")
        x = qpos
    names = [] if qpos is not None else list((record.meta or {}).get("joint_names") or [])
    if names:
        address = [scene.joint(j)["qposadr"] for j in names]
    else:
        address = list(range(scene.nq))
    if x.ndim != 2 or x.shape[0] != t.size or x.shape[1] < len(address):
        raise RobofdiError(f"record.truth_state: expected shape ({t.size}, >={len(address)}) with the joint "
                           f"positions first, got {x.shape}")
    n = int(math.floor((t[-1] - t[0]) * fps + 1e-9)) + 1
    ft = t[0] + np.arange(n) / fps
    q = np.tile(np.asarray(scene.model.qpos0, dtype=float), (n, 1))
    for column, adr in enumerate(address):
        q[:, adr] = np.interp(ft, t, x[:, column])
    return ft, q


# ---------------------------------------------------------------------------- markers
def _perp_frame(axis: np.ndarray) -> np.ndarray:
    """Rotation whose y column is ``axis`` (meshcat cylinders are along y)."""
    y = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0, 0]) if abs(y[0]) < 0.9 else np.array([0, 0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    return np.column_stack([x, y, z])


def _body_radius(scene: MeshcatScene, body: str, anchor=None, axis=None) -> float:
    """A ring radius that encloses the body's geometry near the joint (meshes: their vertices within 5 cm of the
    joint anchor along its axis, 90th percentile of the distance to the axis)."""
    r = 0.05
    for gs in scene.geoms:
        if gs.body != body:
            continue
        if gs.type == "mesh" and anchor is not None:
            v = gs.vertices @ gs.local[:3, :3].T + gs.local[:3, 3] - anchor
            a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
            along = v @ a
            near = np.abs(along) < 0.05
            if near.any():
                r = max(r, float(np.percentile(np.linalg.norm(v[near] - np.outer(along[near], a), axis=1), 90)))
        elif gs.type in ("cylinder", "capsule", "sphere"):
            r = max(r, gs.size[0])
        elif gs.type == "box":
            r = max(r, float(np.min(gs.size[:3])))
    return min(r, 0.25)


def _draw_markers(vis, scene: MeshcatScene, joint: str) -> tuple[str, str]:
    info = scene.joint(joint)
    body, anchor, axis = info["body"], info["pos"], info["axis"]
    onset = f"{ROOT}/{body}/{_ONSET_NAME.format(joint)}"
    det = f"{ROOT}/{body}/{_DETECTED_NAME.format(joint)}"
    r = _body_radius(scene, body, anchor, axis) * 1.35
    T = np.eye(4)
    T[:3, :3] = _perp_frame(axis)
    T[:3, 3] = anchor
    vis[onset]["ring"].set_object(g.Cylinder(0.05, radius=r), rgba_to_material(ONSET_RGBA))
    vis[onset]["ring"].set_transform(T)
    for gs in scene.geoms:
        if gs.body != body:
            continue
        for name, geom, pose in gs.geometries(inflate=0.012):
            node = vis[det][f"geom_{gs.index}"] if not name else vis[det][f"geom_{gs.index}"][name]
            node.set_object(geom, rgba_to_material(DETECTED_RGBA))
            node.set_transform(gs.local @ pose if not name else pose)
    S = np.eye(4)
    S[:3, 3] = anchor
    vis[det]["joint_sphere"].set_object(g.Sphere(r * 0.9), rgba_to_material(DETECTED_RGBA))
    vis[det]["joint_sphere"].set_transform(S)
    vis[onset].set_property("visible", False)
    vis[det].set_property("visible", False)
    return onset, det


def _animate_visibility(anim: Animation, vis, path: str, intervals, frame_times: np.ndarray) -> None:
    """Key ``visible`` on ``path``: shown on the frames whose time lies in any ``[start, end)`` interval.

    Keys are written at frame 0, at every change and at the last frame (so the track spans the clip).
    """
    ft = np.asarray(frame_times, dtype=float)
    shown = np.zeros(ft.size, dtype=bool)
    for a, b in intervals:
        shown |= (ft >= a - 1e-9) & (ft < b - 1e-9)
    keys = [0] + [i for i in range(1, ft.size) if shown[i] != shown[i - 1]]
    if keys[-1] != ft.size - 1:
        keys.append(ft.size - 1)
    for k in keys:
        with anim.at_frame(vis, k) as frame:
            frame[path].set_property("visible", "boolean", bool(shown[k]))


def _set_camera(vis, scene: MeshcatScene, qs: np.ndarray) -> None:
    """Place the default camera so that the robot is in view over the whole motion ``qs`` (frames x nq).

    meshcat 0.3.2's orbit controls always look at the world origin and the camera lives in the y-up frame
    ``/Cameras/default/rotated``: world (x, y, z) -> three.js (x, z, -y). The geoms of the bodies that move in the
    replay (all non-world ones if none moves; over a subsample of the frames) are framed: if their centre (taken
    low, half their height below the middle) is more than 0.3 m from the origin, the whole scene is shifted to put
    it there (grid and axes hidden). The camera is put on a raised diagonal, at the smallest distance where every
    such geom, plus its own radius, lies within a cone of 30 deg around the view axis (the vertical half field of
    view is 37.5 deg).
    """
    world = scene.body_names[0]
    idx = np.unique(np.linspace(0, len(qs) - 1, min(len(qs), 40)).astype(int))
    poses = [scene.body_transforms(qs[i]) for i in idx]
    moves = {b for b in scene.body_names if any(not np.allclose(P[b], poses[0][b], atol=1e-6) for P in poses)}
    moving = [gs for gs in scene.geoms if gs.body in moves] or [gs for gs in scene.geoms if gs.body != world]
    if not moving:
        return
    radius = np.array([gs.radius for gs in moving])
    pts, margin = [], []
    for i in idx:
        Ts = scene.geom_transforms(qs[i])
        pts += [Ts[gs.path][:3, 3] for gs in moving]
        margin.append(radius)
    pts, margin = np.array(pts), np.concatenate(margin)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    centre[2] = max(centre[2] - 0.5 * (pts[:, 2].max() - pts[:, 2].min()), 0.0)   # the orbit point: low in the motion
    if np.linalg.norm(centre) > 0.3:
        # meshcat orbits the world origin: the scene is shifted so that the motion is around it (grid and axes,
        # which stay at the origin, are hidden)
        shift = np.eye(4)
        shift[:3, 3] = -centre
        vis[ROOT].set_transform(shift)
        vis["/Grid"].set_property("visible", False)
        vis["/Axes"].set_property("visible", False)
        pts = pts - centre
    direction = np.array([1.0, -1.2, 0.55])
    direction /= np.linalg.norm(direction)
    limit = math.radians(30.0)
    dist = 10.0
    for d in np.arange(1.0, 10.0, 0.05):
        rel = pts - d * direction
        n = np.linalg.norm(rel, axis=1)
        ang = np.arccos(np.clip(rel @ -direction / n, -1, 1)) + np.arcsin(np.clip(margin / n, 0, 1))
        if np.all(ang <= limit):
            dist = float(d)
            break
    eye = dist * direction
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(eye[0]), float(eye[2]), float(-eye[1])])


# ---------------------------------------------------------------------------- public API
def build_replay(vis: meshcat.Visualizer, record, diagnoser: str | None = None, fps: int = 50,
                 folder: str | Path | None = None) -> Replay:
    """Draw ``record``'s robot into ``vis`` and set an animation of its motion with fault markers.

    ``diagnoser`` picks the trace whose isolation drives the "detected" markers (default: the run's lead,
    :func:`robofdi.evaluate.headline.record_lead`). Frames are the record's truth
    ``qpos`` linearly resampled at ``fps``. ``folder``: where a relative ``meta["mjcf"]`` is looked for first
    (:func:`resolve_mjcf`).
    """
    if not isinstance(fps, (int, np.integer)) or fps <= 0:
        raise RobofdiError(f"fps: expected a positive integer, got {fps!r}")
    fps = int(fps)
    scene = MeshcatScene(resolve_mjcf(record, folder))
    diag = _choose_diagnoser(record, diagnoser)
    ft, q = _resample(record, scene, fps)
    n = len(ft)

    vis[ROOT].delete()
    scene.draw(vis, ROOT)
    scene.set_pose(vis, q[0], ROOT)
    _set_camera(vis, scene, q)

    alias = scene_joints(record, scene)
    onsets = _fault_intervals(record, alias)
    detections = _detection_times(record, diag, alias)
    marked = [j for j in scene.joint_names if j in onsets or j in detections]

    anim = Animation(default_framerate=fps)
    for i in range(n):
        with anim.at_frame(vis, i) as frame:
            scene.set_pose(frame, q[i], ROOT)

    markers: list[Marker] = []
    for j in marked:
        onset_path, det_path = _draw_markers(vis, scene, j)
        on_iv = onsets.get(j, [])
        det_iv = [(detections[j], math.inf)] if j in detections else []
        _animate_visibility(anim, vis, onset_path, on_iv, ft)
        _animate_visibility(anim, vis, det_path, det_iv, ft)
        markers.append(Marker(j, "onset", onset_path, on_iv))
        markers.append(Marker(j, "detected", det_path, det_iv))

    vis.set_animation(anim, play=True, repetitions=1)
    return Replay(scene, anim, fps, ft, diag, markers)


def close_visualizer(vis: meshcat.Visualizer) -> None:
    """Stop the meshcat server that ``meshcat.Visualizer()`` started and close the zmq socket."""
    window = getattr(vis, "window", None)
    if window is None:
        return
    with contextlib.suppress(Exception):
        window.zmq_socket.close(linger=0)
    proc = getattr(window, "server_proc", None)
    if proc is not None and proc.poll() is None:
        proc.kill()
        with contextlib.suppress(Exception):
            proc.wait(timeout=10)
    if proc is not None:
        for stream in (proc.stdout, proc.stderr):
            with contextlib.suppress(Exception):
                stream.close()


def _as_record(record_or_path):
    if isinstance(record_or_path, (str, Path)):
        from robofdi.record import load

        p = Path(record_or_path)
        try:
            return load(p)
        except FileNotFoundError:
            raise RobofdiError(f"record file {str(p)!r}: does not exist") from None
        except (OSError, KeyError) as exc:
            raise RobofdiError(f"record file {str(p)!r}: not a robofdi record ({exc})") from exc
    return record_or_path


#: Replays of systems that are not drawn joint by joint from their model file: ``record.system`` → builder
#: ``"module:function"`` taking (visualizer, record, diagnoser, fps). A record may name its own with
#: ``meta["replay"]`` (a key of this table); :func:`register_replay` adds one.
REPLAYS: dict[str, str] = {"auv": "robofdi.viz.auv_replay:build_auv_replay"}
#: Frame rate cap of those replays [1/s] (each frame keys every marker).
SYSTEM_REPLAY_FPS = 10


def register_replay(system: str, builder: str) -> None:
    """Replay records of ``system`` with ``builder`` (``"module:function"``, see :data:`REPLAYS`)."""
    if not isinstance(builder, str) or ":" not in builder:
        raise RobofdiError(f"replay builder for {system!r}: expected 'module:function', got {builder!r}")
    REPLAYS[str(system)] = builder


def _system_replay(record):
    """The builder of a record whose system has its own replay (:data:`REPLAYS`), else None (the model file's)."""
    import importlib

    key = (record.meta or {}).get("replay") or record.system
    spec = REPLAYS.get(key)
    if spec is None:
        return None
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def _lead(record, diagnoser: str | None) -> str | None:
    return diagnoser or _choose_diagnoser(record, None)


def write_replay_html(record, path: str | Path, diagnoser: str | None = None, fps: int = 50) -> Path:
    """Write a self-contained HTML replay (meshcat's JS inlined, works offline) to ``path``; returns the path.

    ``record`` is a :class:`robofdi.record.Record` or the path of a saved one. A system with a replay of its own
    (:data:`REPLAYS`, e.g. the AUV: :func:`robofdi.viz.auv_replay.build_auv_replay`) gets it, at most
    :data:`SYSTEM_REPLAY_FPS` frames per second. ``diagnoser`` defaults to the run's lead. A relative model name in
    the record is looked for next to the saved record, else next to ``path`` (the run folder).
    """
    path = Path(path)
    folder = Path(record).parent if isinstance(record, (str, Path)) else path.parent
    record = _as_record(record)
    system_replay = _system_replay(record)
    if system_replay is not None:
        shown = _lead(record, diagnoser)

        def build(vis):
            system_replay(vis, record, shown, min(int(fps), SYSTEM_REPLAY_FPS))
    else:
        def build(vis):
            build_replay(vis, record, diagnoser=diagnoser, fps=fps, folder=folder)
    vis = offline_visualizer()              # no server: nothing listens while the replay is built
    try:
        build(vis)
        html = vis.static_html()
    finally:
        close_visualizer(vis)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return path


class _Stop(BaseException):
    """Raised by the signal handlers of :func:`view` to leave its loop (a BaseException, like KeyboardInterrupt)."""


@contextlib.contextmanager
def _stop_on_signals(signals):
    """While active, the ``signals`` request a clean stop: ``raise_pending()`` raises :class:`_Stop` once one came.

    A signal is only recorded while ``armed`` is False (e.g. during the meshcat server's start, so the server is
    never orphaned between its start and the moment the caller holds it) and raises at once when it is True.
    Outside the main thread (where handlers cannot be installed) nothing changes.
    """
    state = {"armed": False, "pending": None}

    def handler(signum, frame):
        state["pending"] = signum
        if state["armed"]:
            raise _Stop(signum)

    def arm():
        state["armed"] = True
        if state["pending"] is not None:
            raise _Stop(state["pending"])

    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in signals:
            previous[sig] = signal.signal(sig, handler)
    try:
        yield arm
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def view(record_path, diagnoser: str | None = None, open_browser: bool = True, fps: int = 50) -> None:
    """Live viewer: start meshcat, load the replay, print the URL and block until Ctrl-C (SIGINT) or SIGTERM.

    Either signal (and SIGHUP) stops the viewer cleanly: the meshcat server subprocess is killed before return.
    """
    folder = Path(record_path).parent if isinstance(record_path, (str, Path)) else None
    record = _as_record(record_path)
    stop_signals = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    vis = None
    with _stop_on_signals(stop_signals) as arm:
        try:
            vis = local_visualizer()        # listens on 127.0.0.1 only (meshcat's own server: every interface)
            arm()
            system_replay = _system_replay(record)
            if system_replay is not None:
                shown = _lead(record, diagnoser)
                system_replay(vis, record, shown, min(int(fps), SYSTEM_REPLAY_FPS))
            else:
                shown = build_replay(vis, record, diagnoser=diagnoser, fps=fps, folder=folder).diagnoser
            url = vis.url()
            print(f"robofdi view: {url}  (diagnoser: {shown or 'none'}; "
                  f"use the 'Animations' panel to replay; Ctrl-C to quit)", flush=True)
            if open_browser:
                webbrowser.open(url, new=2)
            while True:
                _time.sleep(0.5)
        except (KeyboardInterrupt, _Stop):
            pass
        finally:
            if vis is not None:
                close_visualizer(vis)
