"""Point clouds as obstacles: the Panda shelf scene as a cloud against the same scene's primitives.

    python benches/point_clouds.py [--points 100000] [--voxel 0.01] [--radius 0.01] [--n 10000]
                                   [--rounds 5] [--out benches/results/point_clouds.json]

The cloud: ``--points`` points drawn uniformly (by area) on the surfaces of the shelf scene's
boxes (table, boards, side panels; seeded), down-sampled by the world to one point per
``--voxel`` (m), each a ball of ``--radius``; the floor stays a half-space in both scenes. The
figures:

* ``check_us``: ``world.in_collision`` on ``--n`` uniform random configurations (one batched
  call), microseconds per configuration, for the primitive scene and the cloud scene,
  interleaved over ``--rounds`` rounds; medians and their ratio (cloud / primitives);
* ``agreement``: the share of the ``--n`` configurations where the cloud world's obstacle answer
  (self-collision off) equals coal's on the same balls (each a ``coal.Sphere`` of the same
  radius in a ``DynamicAABBTreeCollisionManager``, against the robot's coal geometry with its
  meshes as convex hulls, as genplan collides them) and the same floor (a ``coal.Halfspace``);
* ``replace_ms``: ``world.replace_points`` with a new frame of ``--points`` points (the same
  surfaces, another seed), with and without the voxel, median of ``--rounds``.

The 1-minute load average is recorded before and after (the machine may be shared).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

import genplan
from genplan.scene import Box, HalfSpace, load_scene

ROOT = Path(__file__).resolve().parents[1]


def surface_points(boxes: list[Box], n: int, seed: int) -> np.ndarray:
    """``n`` points uniform by area on the boxes' surfaces, in the world frame."""
    rng = np.random.default_rng(seed)
    faces = []  # (box, axis, sign, area)
    for b in boxes:
        h = np.asarray(b.half_extents)
        for axis in range(3):
            area = 4 * np.prod(np.delete(h, axis))
            faces += [(b, axis, s, area) for s in (-1.0, 1.0)]
    areas = np.array([f[3] for f in faces])
    pick = rng.choice(len(faces), size=n, p=areas / areas.sum())
    out = np.empty((n, 3))
    for k, (b, axis, sign, _) in enumerate(faces):
        rows = np.nonzero(pick == k)[0]
        h = np.asarray(b.half_extents)
        local = rng.uniform(-h, h, size=(len(rows), 3))
        local[:, axis] = sign * h[axis]
        out[rows] = local @ b.pose.matrix().T + np.asarray(b.pose.position)
    return out


def coal_agreement(robot: genplan.Robot, qs: np.ndarray, centres: np.ndarray, radius: float, floor: HalfSpace,
                   ours: np.ndarray) -> dict[str, float]:
    """Share of configurations where coal (robot hulls against the balls and the floor) agrees."""
    import coal
    import pinocchio as pin

    from genplan.experiments.benchmarks.robots import coal_geometry

    geom = coal_geometry(robot, hulls=True)
    gdata = pin.GeometryData(geom)
    manager = coal.DynamicAABBTreeCollisionManager()
    ball = coal.Sphere(radius)
    objects = [coal.CollisionObject(ball, coal.Transform3s(np.eye(3), c)) for c in centres]
    plane = coal.CollisionObject(coal.Halfspace(np.asarray(floor.normal), floor.offset), coal.Transform3s())
    manager.registerObjects([*objects, plane])
    manager.setup()
    robot_objects = [coal.CollisionObject(g.geometry) for g in geom.geometryObjects]
    ref = np.zeros(len(qs), dtype=bool)
    for i, q in enumerate(qs):
        pin.updateGeometryPlacements(robot.model, robot.data, geom, gdata, q)
        for o, m in zip(robot_objects, gdata.oMg):
            o.setTransform(coal.Transform3s(m.rotation, m.translation))
            o.computeAABB()
            cb = coal.CollisionCallBackDefault()
            manager.collide(o, cb)
            if cb.data.result.isCollision():
                ref[i] = True
                break
    return {"agreement": float(np.mean(ref == ours)), "coal_rate": float(ref.mean()),
            "missed": int(np.sum(ref & ~ours)), "extra": int(np.sum(~ref & ours))}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--voxel", type=float, default=0.01)
    parser.add_argument("--radius", type=float, default=0.01)
    parser.add_argument("--n", type=int, default=10_000, help="configurations")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "point_clouds.json")
    args = parser.parse_args()

    load_before = os.getloadavg()[0]
    panda = genplan.load("panda")
    scene = load_scene("panda_shelf")
    boxes = [o for o in scene.obstacles if isinstance(o, Box)]
    floor = next(o for o in scene.obstacles if isinstance(o, HalfSpace))
    primitives = panda.collision_world()
    primitives.add_scene(scene)
    cloud = panda.collision_world()
    cloud.add_halfspace(floor.name, floor.normal, floor.offset)
    pts = surface_points(boxes, args.points, args.seed)
    kept = cloud.add_points("shelf", pts, args.radius, args.voxel)
    qs = panda.random_configurations(args.n, args.seed + 1)

    check: dict[str, list[float]] = {"primitives": [], "cloud": []}
    for _ in range(args.rounds):
        for name, world in (("primitives", primitives), ("cloud", cloud)):
            t = time.perf_counter()
            world.in_collision(qs)
            check[name].append((time.perf_counter() - t) / len(qs) * 1e6)
    med = {k: statistics.median(v) for k, v in check.items()}

    frame = surface_points(boxes, args.points, args.seed + 7)
    raw = panda.collision_world()
    raw.add_points("raw", pts, args.radius)
    replace: dict[str, list[float]] = {"voxel": [], "no_voxel": []}
    for _ in range(args.rounds):
        for name, world, cname in (("voxel", cloud, "shelf"), ("no_voxel", raw, "raw")):
            t = time.perf_counter()
            world.replace_points(cname, frame if len(replace[name]) % 2 == 0 else pts)
            replace[name].append((time.perf_counter() - t) * 1e3)
    cloud.replace_points("shelf", pts)  # back to the measured frame

    rates = {"primitives": float(np.mean(primitives.in_collision(qs))), "cloud": float(np.mean(cloud.in_collision(qs)))}
    cloud.check_self = False
    ours = np.asarray(cloud.in_collision(qs))
    # the balls the world holds: the same down-sampling, done again here through a one-ball-per-voxel copy
    centres = _voxel_centroids(pts, args.voxel)
    assert len(centres) == kept, (len(centres), kept)
    agree = coal_agreement(panda, qs, centres, args.radius, floor, ours)

    result = {
        "command": "python benches/point_clouds.py " + " ".join(f"--{k} {v}" for k, v in vars(args).items() if k != "out"),
        "points": args.points, "voxel": args.voxel, "radius": args.radius, "balls": kept, "configurations": args.n,
        "check_us": {"primitives": med["primitives"], "cloud": med["cloud"], "ratio": med["cloud"] / med["primitives"],
                     "rounds": check},
        "collision_rate": rates,
        "obstacle_collision_rate_cloud": float(ours.mean()),
        "coal": agree,
        "replace_ms": {k: statistics.median(v) for k, v in replace.items()} | {"rounds": replace},
        "load_average": [load_before, os.getloadavg()[0]],
        "machine": platform.machine(), "cpus": os.cpu_count(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from genplan._files import write_text

    write_text(args.out, json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k not in ("check_us", "replace_ms")}, indent=1))
    print("check us/config:", {k: round(v, 3) for k, v in med.items()}, "ratio", round(med["cloud"] / med["primitives"], 2))
    print("replace ms:", {k: round(statistics.median(v), 1) for k, v in replace.items()})


def _voxel_centroids(points: np.ndarray, voxel: float) -> np.ndarray:
    """One centroid per occupied voxel (the world's down-sampling, written again in numpy)."""
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse.reshape(-1), points)
    return sums / counts[:, None]


if __name__ == "__main__":
    main()
