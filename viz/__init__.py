"""3-D inspection front-end: replay a robofdi run record of a MuJoCo robot in meshcat (browser)."""
from .replay import (Marker, Replay, build_replay, close_visualizer, fault_joint, isolated_joints, resolve_mjcf,
                     view, write_replay_html)
from .scene import MeshcatScene

__all__ = ["MeshcatScene", "build_replay", "write_replay_html", "view", "close_visualizer", "Replay", "Marker",
           "resolve_mjcf", "fault_joint", "isolated_joints"]
