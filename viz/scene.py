"""A MuJoCo model drawn in meshcat: one meshcat group per body, one primitive or triangle mesh per geom.

Layout of the meshcat tree (below the visualizer's root)::

    robot/<body>/geom_<i>        one primitive per MuJoCo geom, fixed pose in its body's frame
    robot/<body>                 a group whose transform is the body's world pose

Posing the robot is therefore a matter of setting the (few) body transforms; anything attached
below ``robot/<body>`` (e.g. fault markers) moves with that link.

Mesh geoms are drawn from the *compiled* model's own mesh data (``mesh_vert``/``mesh_face``: already recentred
and reoriented by MuJoCo's compiler, so ``geom_pos``/``geom_quat`` place them), thinned by vertex clustering;
nothing is read from the mesh files at drawing time. Colliding geoms (contype or conaffinity not 0) other than
planes are skipped where visual-only geoms stand for them: in a body that has visual-only geoms, and in a geom group
that holds no visual-only geom while another group does (robosuite: group 1 visual, group 0 collision).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import meshcat.geometry as g
import mujoco
import numpy as np

from robofdi import RobofdiError
from robofdi.mjcf import load_model

__all__ = ["MeshcatScene", "GeomSpec", "rgba_to_material", "cluster_vertices", "MESH_CELL"]

_T = mujoco.mjtGeom
#: Rotation taking meshcat's cylinder axis (+y) onto MuJoCo's (+z): +90 deg about x.
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
#: Thickness of the slab that stands in for a plane [m]; a plane of size 0 (infinite) is drawn this big.
_PLANE_THICKNESS = 0.01
_PLANE_DEFAULT_HALF = 2.0
#: Default cell of the vertex clustering that thins meshes for drawing [m].
MESH_CELL = 0.004


def cluster_vertices(vertices, faces, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """A lighter mesh: vertices merged per cubic cell of edge ``cell`` [m] at their mean, collapsed and repeated
    faces dropped, unused vertices removed (vertex clustering, Rossignac & Borrel 1993, eq. of the cell index
    floor(v / cell)). ``cell`` <= 0 only drops unused vertices."""
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if cell > 0 and len(v):
        _, cluster, counts = np.unique(np.floor(v / cell).astype(np.int64), axis=0, return_inverse=True,
                                       return_counts=True)
        cluster = cluster.reshape(-1)
        merged = np.zeros((counts.size, 3))
        np.add.at(merged, cluster, v)
        v, f = merged / counts[:, None], cluster[f]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        if len(f):
            first = np.argmin(f, axis=1)                      # one rotation per triangle: repeats become equal rows
            rolled = np.take_along_axis(f, (first[:, None] + np.arange(3)) % 3, axis=1)
            _, keep = np.unique(rolled, axis=0, return_index=True)
            f = f[np.sort(keep)]
    used, f = np.unique(f, return_inverse=True)
    return v[used], f.reshape(-1, 3)


def _homogeneous(pos, rot) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.asarray(rot, dtype=float).reshape(3, 3)
    T[:3, 3] = pos
    return T


def _quat_to_mat(quat) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(quat, dtype=float))
    return m.reshape(3, 3)


def rgba_to_material(rgba, *, scale_opacity: float = 1.0) -> g.MeshPhongMaterial:
    """A meshcat Phong material of colour ``rgba`` (components in [0, 1])."""
    r, gg, b, a = (float(x) for x in rgba)
    color = (int(round(255 * r)) << 16) | (int(round(255 * gg)) << 8) | int(round(255 * b))
    opacity = float(np.clip(a * scale_opacity, 0.0, 1.0))
    return g.MeshPhongMaterial(color=color, opacity=opacity, transparent=opacity < 1.0)


def _geom_rgba(m: mujoco.MjModel, i: int) -> np.ndarray:
    """Colour of geom ``i``: its material's rgba times the mean colour of the material's texture if it has one
    (meshcat gets no textures: a textured cube keeps its hue), else the geom's rgba."""
    matid = int(m.geom_matid[i])
    if matid < 0:
        return np.array(m.geom_rgba[i], dtype=float)
    rgba = np.array(m.mat_rgba[matid], dtype=float)
    tex = next((int(t) for t in np.atleast_1d(m.mat_texid[matid]) if t >= 0), -1)
    if tex >= 0 and int(m.tex_nchannel[tex]) >= 3:
        adr, c = int(m.tex_adr[tex]), int(m.tex_nchannel[tex])
        n = int(m.tex_width[tex]) * int(m.tex_height[tex]) * c
        pixels = np.asarray(m.tex_data[adr:adr + n], dtype=float).reshape(-1, c)
        rgba[:3] *= pixels[:, :3].mean(axis=0) / 255.0
    return rgba


@dataclass
class GeomSpec:
    """One drawable geom: its meshcat path, primitive type, sizes, colour and fixed offset in its body frame."""

    index: int
    body: str
    path: str                 # relative to the robot root, e.g. "link3/geom_7"
    type: str                 # "box", "cylinder", "sphere", "capsule", "ellipsoid", "plane"
    size: np.ndarray          # MuJoCo size vector (3,)
    rgba: np.ndarray          # (4,)
    local: np.ndarray         # (4, 4) pose of the meshcat object in the body frame (cylinder axis fix included)
    vertices: np.ndarray | None = None   # "mesh": (n, 3) in the geom frame [m]
    faces: np.ndarray | None = None      # "mesh": (m, 3) vertex indices

    @property
    def radius(self) -> float:
        """Radius of a sphere around the geom, centred at its frame origin [m]."""
        if self.type == "mesh":
            return float(np.max(np.linalg.norm(self.vertices, axis=1))) if len(self.vertices) else 0.0
        return float(np.max(self.size))

    def geometries(self, inflate: float = 0.0) -> list[tuple[str, g.Geometry, np.ndarray]]:
        """Meshcat primitives ``(name, geometry, pose in the geom's meshcat frame)``; ``inflate`` grows every size [m]."""
        s = self.size + inflate
        eye = np.eye(4)
        if self.type == "box":
            return [("", g.Box(2 * s[:3]), eye)]
        if self.type == "mesh":
            scale = 1.0 + inflate / max(self.radius, 0.02)     # grown about the geom origin (the mesh centre)
            return [("", g.TriangularMeshGeometry(self.vertices * scale, self.faces), eye)]
        if self.type == "plane":
            hx = self.size[0] if self.size[0] > 0 else _PLANE_DEFAULT_HALF
            hy = self.size[1] if self.size[1] > 0 else _PLANE_DEFAULT_HALF
            return [("", g.Box([2 * hx, 2 * hy, _PLANE_THICKNESS]), eye)]
        if self.type == "sphere":
            return [("", g.Sphere(s[0]), eye)]
        if self.type == "ellipsoid":
            return [("", g.Ellipsoid(s[:3]), eye)]
        if self.type == "cylinder":
            return [("", g.Cylinder(2 * s[1], s[0]), eye)]
        if self.type == "capsule":
            # meshcat frame here has the axis along +y (see _Y_TO_Z)
            top, bottom = np.eye(4), np.eye(4)
            top[1, 3], bottom[1, 3] = s[1], -s[1]
            return [("", g.Cylinder(2 * s[1], s[0]), eye), ("cap_top", g.Sphere(s[0]), top),
                    ("cap_bottom", g.Sphere(s[0]), bottom)]
        raise AssertionError(self.type)  # pragma: no cover - filtered in MeshcatScene


_TYPE_NAMES = {
    _T.mjGEOM_PLANE: "plane",
    _T.mjGEOM_SPHERE: "sphere",
    _T.mjGEOM_CAPSULE: "capsule",
    _T.mjGEOM_ELLIPSOID: "ellipsoid",
    _T.mjGEOM_CYLINDER: "cylinder",
    _T.mjGEOM_BOX: "box",
    _T.mjGEOM_MESH: "mesh",
}


class MeshcatScene:
    """A MuJoCo model, ready to be drawn into a :class:`meshcat.Visualizer` and posed from ``qpos``.

    ``mjcf``: an MJCF XML file, a compiled binary model (``.mjb``) or a :class:`mujoco.MjModel`. Height fields,
    fully transparent geoms and collision geoms that visual geoms stand for (module docstring) are skipped
    (listed in :attr:`skipped`). ``mesh_cell``: the vertex-clustering cell that thins mesh geoms [m] (0: every vertex).
    """

    def __init__(self, mjcf: str | Path | mujoco.MjModel, mesh_cell: float = MESH_CELL):
        if isinstance(mjcf, mujoco.MjModel):
            self.model, path = mjcf, Path("<MjModel>")
        else:
            path = Path(mjcf)
            if not path.is_file():
                raise RobofdiError(f"mjcf file {str(path)!r}: does not exist (expected an MJCF XML file or an .mjb)")
            if path.suffix == ".mjb":
                try:
                    self.model = mujoco.MjModel.from_binary_path(str(path))
                except Exception as exc:  # mujoco raises ValueError with the loader's message
                    msg = str(exc).strip().replace("\n", " ")
                    raise RobofdiError(f"mjcf file {str(path)!r}: not a valid MuJoCo model ({msg})") from exc
            else:       # as the simulator compiles it (a mesh too thin to be a solid gets shell inertia, robofdi.mjcf)
                self.model = load_model(path)
        if not (isinstance(mesh_cell, (int, float)) and mesh_cell >= 0):
            raise RobofdiError(f"mesh_cell: expected a clustering cell >= 0 m, got {mesh_cell!r}")
        self.path = path
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.body_names: list[str] = [m.body(i).name or f"body{i}" for i in range(m.nbody)]
        self.joint_names: list[str] = [m.joint(i).name or f"joint{i}" for i in range(m.njnt)]
        self.geoms: list[GeomSpec] = []
        self.skipped: list[int] = []
        colliding = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        has_visual = set(int(b) for b in m.geom_bodyid[~colliding])
        visual_groups = set(int(k) for k in m.geom_group[~colliding])
        meshes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for i in range(m.ngeom):
            tname = _TYPE_NAMES.get(int(m.geom_type[i]))
            rgba = _geom_rgba(m, i)
            hull = bool(colliding[i]) and tname != "plane" and (
                int(m.geom_bodyid[i]) in has_visual or (visual_groups and int(m.geom_group[i]) not in visual_groups))
            if tname is None or rgba[3] <= 0.0 or hull:
                self.skipped.append(i)
                continue
            vertices = faces = None
            if tname == "mesh":
                mesh = int(m.geom_dataid[i])
                if mesh not in meshes:
                    va, vn = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
                    fa, fn = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
                    meshes[mesh] = cluster_vertices(m.mesh_vert[va:va + vn], m.mesh_face[fa:fa + fn], mesh_cell)
                vertices, faces = meshes[mesh]
                if not len(faces):
                    self.skipped.append(i)
                    continue
            body = self.body_names[int(m.geom_bodyid[i])]
            local = _homogeneous(m.geom_pos[i], _quat_to_mat(m.geom_quat[i]))
            if tname in ("cylinder", "capsule"):
                local = local @ _Y_TO_Z
            elif tname == "plane":
                local = local.copy()
                local[:3, 3] -= local[:3, 2] * _PLANE_THICKNESS / 2  # top face at the plane
            self.geoms.append(GeomSpec(i, body, f"{body}/geom_{i}", tname, np.array(m.geom_size[i], dtype=float),
                                       rgba, local, vertices, faces))

    # ------------------------------------------------------------------ kinematics
    @property
    def nq(self) -> int:
        return int(self.model.nq)

    def joint(self, name: str) -> dict:
        """Body, anchor and axis (in the body frame) of joint ``name``."""
        try:
            j = self.model.joint(name)
        except KeyError:
            raise RobofdiError(f"joint {name!r}: not in model {self.path.name} (joints: {self.joint_names})") from None
        return {"body": self.body_names[int(j.bodyid[0])], "pos": np.array(j.pos, dtype=float),
                "axis": np.array(j.axis, dtype=float), "type": int(j.type[0]), "qposadr": int(j.qposadr[0])}

    def _forward(self, qpos) -> None:
        qpos = np.asarray(qpos, dtype=float).reshape(-1)
        if qpos.shape[0] != self.model.nq:
            raise RobofdiError(f"qpos: expected {self.model.nq} values for {self.path.name}, got {qpos.shape[0]}")
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)

    def body_transforms(self, qpos) -> dict[str, np.ndarray]:
        """World pose (4x4) of every body at ``qpos`` (``mujoco.mj_kinematics``)."""
        self._forward(qpos)
        return {name: _homogeneous(self.data.xpos[b], self.data.xmat[b]) for b, name in enumerate(self.body_names)}

    def geom_transforms(self, qpos) -> dict[str, np.ndarray]:
        """World pose (4x4) of every drawn geom's meshcat object at ``qpos``, from ``geom_xpos``/``geom_xmat``."""
        self._forward(qpos)
        out = {}
        for gs in self.geoms:
            T = _homogeneous(self.data.geom_xpos[gs.index], self.data.geom_xmat[gs.index])
            if gs.type in ("cylinder", "capsule"):
                T = T @ _Y_TO_Z
            elif gs.type == "plane":
                T[:3, 3] -= T[:3, 2] * _PLANE_THICKNESS / 2
            out[gs.path] = T
        return out

    def extent(self, qpos=None) -> tuple[np.ndarray, float]:
        """Centre and radius of a sphere around the robot's (non-world) geoms at ``qpos`` (default: qpos0)."""
        q = self.model.qpos0 if qpos is None else qpos
        Ts = self.geom_transforms(q)
        pts = [Ts[gs.path][:3, 3] for gs in self.geoms if gs.body != self.body_names[0]]
        if not pts:
            pts = [np.zeros(3)]
        pts = np.array(pts)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = (lo + hi) / 2
        radius = float(np.max(np.linalg.norm(pts - centre, axis=1))) + 0.2
        return centre, radius

    # ------------------------------------------------------------------ drawing
    def draw(self, vis, root: str = "robot") -> None:
        """Create every geom's object below ``vis[root]`` (bodies at their qpos0 pose)."""
        base = vis[root]
        for gs in self.geoms:
            for name, geom, pose in gs.geometries():
                node = base[gs.path] if not name else base[gs.path][name]
                node.set_object(geom, rgba_to_material(gs.rgba))
                node.set_transform(gs.local @ pose if not name else pose)
        self.set_pose(vis, self.model.qpos0, root)

    def set_pose(self, vis, qpos, root: str = "robot") -> None:
        """Move the drawn robot to ``qpos`` (works on a Visualizer or an animation frame)."""
        for name, T in self.body_transforms(qpos).items():
            vis[root][name].set_transform(T)
