"""Missions that run the arm into itself: how many of a campaign's drawn missions touch the arm's own geometry.

    python benchmarks/arm_collisions.py [--robot FILE ...] [--missions 200] [--segments 3] [--speed fast]
                                        [--torque-motors] [--step 0.002]

Each mission is drawn as an arm campaign draws it (``ArmSystem.mission`` on ``rng(run_seed(0, i), "mission")``)
and its planned reference is sampled every ``--step`` s; at each sample MuJoCo's collision detection
(``mj_kinematics`` + ``mj_collision`` on the robot file, the file's contype/conaffinity, parent filter and
excludes) gives the closest pair of geoms, leaving out pairs on bodies that no joint moves apart (a base on its
mount: the same at every pose) and, unless they touch, a body and its parent. Printed per arm: missions whose
reference touches (distance < 0) and missions closer than ``--clearance`` m (whose tracked motion may touch),
with the body pairs. ``--out`` keeps per mission a fingerprint (SHA-256 of its description and of 64 reference
poses) and its closest distance: run it on two versions of the generator and compare with
``python benchmarks/arm_collisions.py compare BEFORE.json AFTER.json``: the missions that were clear before
must have the same fingerprint after.
"""
from __future__ import annotations

import argparse
import hashlib
import json

import mujoco
import numpy as np


def _masks(m) -> tuple[np.ndarray, np.ndarray]:
    """Geom pairs no joint moves apart (the same at every pose), and pairs on a body and its parent."""
    root = np.empty(m.nbody, dtype=int)
    for b in range(m.nbody):
        root[b] = b if (b == 0 or m.body_jntnum[b] > 0) else root[m.body_parentid[b]]
    body = np.asarray(m.geom_bodyid, dtype=int)
    rigid = root[body][:, None] == root[body][None, :]
    parent = np.asarray(m.body_parentid, dtype=int)[body]
    return rigid, ((parent[:, None] == body[None, :]) | (body[:, None] == parent[None, :])) & ~rigid


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", action="append", default=None)
    ap.add_argument("--missions", type=int, default=200)
    ap.add_argument("--segments", type=int, default=3)
    ap.add_argument("--speed", default="fast")
    ap.add_argument("--torque-motors", action="store_true")
    ap.add_argument("--step", type=float, default=0.004)
    ap.add_argument("--clearance", type=float, default=0.015)
    ap.add_argument("--out", default=None, help="JSON file: per mission its fingerprint and closest distance")
    args = ap.parse_args(argv)
    from robofdi.campaign.runs import run_seed
    from robofdi.config import compose
    from robofdi.seeding import rng
    from robofdi.systems import get_system

    system = get_system("arm")
    per_mission = {}
    for robot in args.robot or ["arm6.xml", "arm7.xml"]:
        options = compose(system.options_type, {"robot": robot, "torque_motors": args.torque_motors,
                                                "segments": args.segments, "speed": args.speed}, "system")
        sim, model, _ = system._base(options)
        m = mujoco.MjModel.from_xml_path(str(model.path))
        d = mujoco.MjData(m)
        qadr = np.array([m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in model.joint_names])
        rigid, adjacent = _masks(m)
        m.geom_margin[:] = np.maximum(m.geom_margin, 2 * args.clearance)
        touching, close, pairs, rows = 0, 0, {}, []
        for i in range(args.missions):
            mission = system.mission(options, 0, rng(run_seed(0, i), "mission"))
            plan = mission.plan
            digest = hashlib.sha256(json.dumps(mission.description, sort_keys=True).encode())
            digest.update(np.round([plan(t)[0] for t in np.linspace(0.0, float(plan.end), 64)], 9).tobytes())
            closest, who = np.inf, None
            for t in np.arange(0.0, float(plan.end) + 1e-9, args.step):
                d.qpos[:] = m.qpos0
                d.qpos[qadr] = np.asarray(plan(t)[0], dtype=float)
                mujoco.mj_kinematics(m, d)
                mujoco.mj_collision(m, d)
                for c in d.contact[:d.ncon]:
                    g1, g2 = int(c.geom1), int(c.geom2)
                    if rigid[g1, g2] or (adjacent[g1, g2] and c.dist >= 0):
                        continue
                    if c.dist < closest:
                        closest = float(c.dist)
                        who = " / ".join(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
                                         for g in (g1, g2))
            touching += closest < 0
            close += closest < args.clearance
            if closest < args.clearance:
                pairs[who] = pairs.get(who, 0) + 1
            rows.append([digest.hexdigest()[:16], None if not np.isfinite(closest) else round(closest, 5)])
        per_mission[robot] = rows
        print(json.dumps({"robot": robot, "missions": args.missions, "segments": args.segments, "speed": args.speed,
                          "collision_geometry": bool(np.any((m.geom_contype != 0) | (m.geom_conaffinity != 0))),
                          "touching": int(touching), f"closer_than_{args.clearance:g}_m": int(close), "pairs": pairs}),
              flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(per_mission, f)
    return 0


def compare(before: str, after: str, clearance: float = 0.015) -> int:
    """Missions clear (>= clearance) in BEFORE with another fingerprint in AFTER; exit 1 if any."""
    a, b = json.load(open(before)), json.load(open(after))
    bad = 0
    for robot, rows in a.items():
        clear = [i for i, (_, dist) in enumerate(rows) if dist is None or dist >= clearance]
        changed = [i for i in clear if b[robot][i][0] != rows[i][0]]
        redrawn = [i for i, (_, dist) in enumerate(rows) if dist is not None and dist < clearance]
        print(json.dumps({"robot": robot, "clear_before": len(clear), "changed_among_clear": changed,
                          "close_before_redrawn": sum(b[robot][i][0] != rows[i][0] for i in redrawn),
                          "close_before": len(redrawn)}))
        bad += len(changed)
    return 1 if bad else 0


if __name__ == "__main__":
    import sys

    if sys.argv[1:2] == ["compare"]:
        raise SystemExit(compare(*sys.argv[2:4]))
    raise SystemExit(main())
