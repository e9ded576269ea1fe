"""Mesh geoms in the meshcat replay: drawn from the compiled model's own mesh data at MuJoCo's world pose."""
from __future__ import annotations

import base64
import re

import numpy as np
import pytest

pytest.importorskip("meshcat")
mujoco = pytest.importorskip("mujoco")
import umsgpack  # noqa: E402  (installed with meshcat)

from robofdi.record import Record  # noqa: E402
from robofdi.viz import MeshcatScene, write_replay_html  # noqa: E402
from robofdi.viz.scene import cluster_vertices  # noqa: E402

# An asymmetric wedge (MuJoCo recentres it at its centroid and turns it to its principal axes at compile time),
# used twice: at the body origin, and with an explicit pos/euler; plus a collision hull that the visual geoms
# of the same body stand for.
WEDGE = np.array([[0, 0, 0], [0.3, 0, 0], [0, 0.1, 0], [0, 0, 0.05], [0.3, 0, 0.05], [0, 0.1, 0.05]])
GEOM_POS, GEOM_EULER = np.array([0.1, -0.05, 0.2]), np.array([30.0, -20.0, 60.0])     # euler in degrees, xyz
MJCF = f"""
<mujoco>
  <compiler angle="degree"/>
  <asset><mesh name="wedge" vertex="{' '.join(f'{x:g}' for x in WEDGE.ravel())}"/></asset>
  <worldbody>
    <geom type="plane" size="1 1 0.01"/>
    <body name="link1" pos="0.2 0.1 0.3" euler="0 10 0">
      <joint name="joint1" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="link2" pos="0.3 0 0.1">
        <joint name="joint2" type="hinge" axis="0 1 0"/>
        <geom name="plain" type="mesh" mesh="wedge" contype="0" conaffinity="0" rgba="0.9 0.4 0.1 1"/>
        <geom name="placed" type="mesh" mesh="wedge" pos="{' '.join(map(str, GEOM_POS))}"
              euler="{' '.join(map(str, GEOM_EULER))}" contype="0" conaffinity="0" rgba="0.1 0.4 0.9 1"/>
        <geom name="hull" type="box" size="0.2 0.1 0.1" rgba="1 1 0 1"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def wedge_xml(tmp_path_factory):
    path = tmp_path_factory.mktemp("mesh") / "wedge.xml"
    path.write_text(MJCF)
    return path


def _euler_xyz(deg) -> np.ndarray:
    """Rotation of MJCF's default euler sequence "xyz" (rotating axes: scipy's intrinsic "XYZ")."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("XYZ", deg, degrees=True).as_matrix()


def _drawn_world_vertices(scene: MeshcatScene, name: str, qpos) -> np.ndarray:
    gs = next(g for g in scene.geoms if g.index == scene.model.geom(name).id)
    T = scene.geom_transforms(qpos)[gs.path]
    return gs.vertices @ T[:3, :3].T + T[:3, 3]


def test_mesh_vertices_land_where_the_mjcf_puts_them(wedge_xml):
    scene = MeshcatScene(wedge_xml, mesh_cell=0.0)
    m = scene.model
    assert {g.type for g in scene.geoms} == {"plane", "mesh"}
    assert m.geom("hull").id in scene.skipped                      # the visual meshes of link2 stand for it
    q = np.array([0.7, -0.4])
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    body = m.body("link2").id
    R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
    expected = {"plain": WEDGE @ R.T + p,                                           # mesh frame = body frame
                "placed": (WEDGE @ _euler_xyz(GEOM_EULER).T + GEOM_POS) @ R.T + p}   # the geom's pos/euler first
    for name, want in expected.items():
        got = _drawn_world_vertices(scene, name, q)
        assert got.shape == want.shape
        # every vertex of the MJCF lands on a drawn vertex (the compiled mesh is recentred: order/frame differ)
        dist = np.linalg.norm(want[:, None, :] - got[None, :, :], axis=2).min(axis=1)
        np.testing.assert_array_less(dist, 1e-6)                     # mesh_vert is float32
    # MuJoCo moved the mesh frame at compile time: the compiled vertices alone are not the user's
    gs = next(g for g in scene.geoms if g.index == m.geom("plain").id)
    assert np.abs(gs.vertices.mean(axis=0)).max() < 1e-6 and not np.allclose(np.sort(gs.vertices, axis=0),
                                                                             np.sort(WEDGE, axis=0))


def test_replay_html_carries_the_meshes_at_their_compiled_pose(wedge_xml, tmp_path):
    t = np.linspace(0, 1, 11)
    q = np.column_stack([0.5 * t, -0.3 * t])
    rec = Record(system="wedge", scenario="test", seed=0, rates={}, time=t, truth_state=np.hstack([q, 0 * q]),
                 meta={"mjcf": str(wedge_xml), "joint_names": ["joint1", "joint2"],
                       "faults": [{"name": "f", "kind": "actuator_bias", "target": "joint2", "onset": 0.5}]})
    html = write_replay_html(rec, tmp_path / "replay.html", fps=10).read_text()
    cmds = [umsgpack.unpackb(base64.b64decode(b))
            for b in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)]
    scene = MeshcatScene(wedge_xml)
    gs = next(g for g in scene.geoms if g.index == scene.model.geom("placed").id)
    (obj,) = [c for c in cmds if c["type"] == "set_object" and c["path"] == f"/meshcat/robot/{gs.path}"]
    (geom,) = obj["object"]["geometries"]
    assert geom["type"] == "BufferGeometry"
    position = geom["data"]["attributes"]["position"]
    drawn = np.frombuffer(position["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(drawn, gs.vertices, atol=1e-6)
    (pose,) = [c for c in cmds if c["type"] == "set_transform" and c["path"] == f"/meshcat/robot/{gs.path}"]
    np.testing.assert_allclose(np.array(pose["matrix"]).reshape(4, 4).T, gs.local, atol=1e-6)
    # the fault markers ride on link2; the red "detected" copy of the link is an inflated copy of its meshes
    paths = {c["path"]: c for c in cmds if c["type"] == "set_object"}
    assert any(p.startswith("/meshcat/robot/link2/fault_onset_joint2/") for p in paths)
    red = paths[f"/meshcat/robot/link2/fault_detected_joint2/geom_{gs.index}"]["object"]["geometries"][0]
    grown = np.frombuffer(red["data"]["attributes"]["position"]["array"].data, dtype=np.float32).reshape(-1, 3)
    ratio = np.linalg.norm(grown, axis=1) / np.linalg.norm(gs.vertices, axis=1)
    assert np.all(ratio > 1.01) and np.ptp(ratio) < 1e-5

def test_vertex_clustering_thins_a_dense_mesh_and_keeps_its_shape():
    # a finely subdivided unit square (two triangles per cell) in the z = 0 plane
    n = 41
    xs = np.linspace(0, 0.1, n)
    vx, vy = np.meshgrid(xs, xs, indexing="ij")
    v = np.column_stack([vx.ravel(), vy.ravel(), np.zeros(n * n)])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    v2, f2 = cluster_vertices(v, f, 0.01)
    assert len(v2) < len(v) / 10 and len(f2) < len(f) / 10 and len(f2) > 0
    assert f2.min() >= 0 and f2.max() < len(v2)
    assert np.all((f2[:, 0] != f2[:, 1]) & (f2[:, 1] != f2[:, 2]) & (f2[:, 0] != f2[:, 2]))
    np.testing.assert_allclose(v2.min(axis=0)[:2], [0, 0], atol=0.01)
    np.testing.assert_allclose(v2.max(axis=0)[:2], [0.1, 0.1], atol=0.01)
    same_v, same_f = cluster_vertices(v, f, 0.0)                  # cell 0: unchanged
    np.testing.assert_array_equal(same_v, v)
    np.testing.assert_array_equal(same_f, f)
