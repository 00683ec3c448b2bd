"""Point clouds as obstacles: the Panda shelf scene as a cloud against the same scene's primitives.

    python benches/point_clouds.py [--points 100000] [--voxel 0.01] [--radius 0.01] [--n 10000]
                                   [--rounds 5] [--queries 20] [--plan-radius 0.0045] [--baseline DIR]
                                   [--out benches/results/point_clouds.json]

The cloud: ``--points`` points drawn uniformly (by area) on the surfaces of the shelf scene's
boxes (table, boards, side panels; seeded), down-sampled by the world to one point per
``--voxel`` (m), each a ball of ``--radius``; the floor stays a half-space in both scenes. The
figures:

* ``check_us``: ``world.in_collision`` on ``--n`` uniform random configurations (one batched
  call), microseconds per configuration, for the primitive scene and the cloud scene,
  interleaved over ``--rounds`` rounds; medians and their ratio (cloud / primitives);
* ``spheres_us``: the same with the sphere checker (``planning.sphere_checker``) on both scenes;
* ``agreement``: the share of the ``--n`` configurations where the cloud world's obstacle answer
  (self-collision off) equals coal's on the same balls (each a ``coal.Sphere`` of the same
  radius in a ``DynamicAABBTreeCollisionManager``, against the robot's coal geometry with its
  meshes as convex hulls, as genplan collides them) and the same floor (a ``coal.Halfspace``);
* ``replace_ms``: ``world.replace_points`` with a new frame of ``--points`` points (the same
  surfaces, another seed), with and without the voxel, median of ``--rounds``;
* ``plans``: the environment's first ``--queries`` seeded Panda shelf queries (Table II; the GAN
  sampler, simplified, seed 0) planned in the primitive world and in the cloud world with balls
  of ``--radius`` and of ``--plan-radius`` (the queries start 5 mm above the table: balls wider
  than that refuse the starts); per world the plans found, the queries refused (the start or
  every goal in contact), and the plans' states and the states every 0.002 rad along their
  motions in contact with the true (primitive) scene.

``--baseline DIR``: DIR holds another build of the ``genplan`` package (a copy of
``python/genplan`` with its ``_core`` extension, e.g. made before a change). The check and replace
timings then run in two worker processes, this build and the baseline's, with the same scene,
cloud and configurations, alternating which goes first in each round; ``baseline`` in the JSON
holds the baseline's medians and the ratios (this build / the baseline). The 1-minute load
average is recorded before and after (the machine may be shared).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
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


class Bench:
    """The scene, the worlds, the cloud's two frames and the configurations of one run."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.panda = genplan.load("panda")
        scene = load_scene("panda_shelf")
        boxes = [o for o in scene.obstacles if isinstance(o, Box)]
        self.floor = next(o for o in scene.obstacles if isinstance(o, HalfSpace))
        self.primitives = self.panda.collision_world()
        self.primitives.add_scene(scene)
        self.cloud = self.panda.collision_world()
        self.cloud.add_halfspace(self.floor.name, self.floor.normal, self.floor.offset)
        self.pts = surface_points(boxes, args.points, args.seed)
        self.kept = self.cloud.add_points("shelf", self.pts, args.radius, args.voxel)
        self.qs = self.panda.random_configurations(args.n, args.seed + 1)
        self.frame = surface_points(boxes, args.points, args.seed + 7)
        self.raw = self.panda.collision_world()
        self.raw.add_points("raw", self.pts, args.radius)
        self.replaced = 0

    def check(self) -> dict[str, float]:
        """One round of ``in_collision`` per configuration (us), primitives then cloud."""
        out = {}
        for name, world in (("primitives", self.primitives), ("cloud", self.cloud)):
            t = time.perf_counter()
            world.in_collision(self.qs)
            out[name] = (time.perf_counter() - t) / len(self.qs) * 1e6
        return out

    def spheres(self) -> dict[str, float | None]:
        """One round of the sphere checker per configuration (us); None where it refuses a world."""
        from genplan.errors import GenplanError
        from genplan.planning import sphere_checker

        out: dict[str, float | None] = {}
        for name, world in (("primitives", self.primitives), ("cloud", self.cloud)):
            try:
                checker = sphere_checker(self.panda, world)
            except GenplanError:
                out[name] = None
                continue
            t = time.perf_counter()
            checker.in_collision(self.qs)
            out[name] = (time.perf_counter() - t) / len(self.qs) * 1e6
        return out

    def replace(self) -> dict[str, float]:
        """One round of ``replace_points`` (ms) with and without the voxel, the frames alternating."""
        out = {}
        frame = self.frame if self.replaced % 2 == 0 else self.pts
        for name, world, cname in (("voxel", self.cloud, "shelf"), ("no_voxel", self.raw, "raw")):
            t = time.perf_counter()
            world.replace_points(cname, frame)
            out[name] = (time.perf_counter() - t) * 1e3
        self.replaced += 1
        return out

    def restore(self) -> None:
        """Back to the measured frame."""
        self.cloud.replace_points("shelf", self.pts)
        self.raw.replace_points("raw", self.pts)


def plans(bench: Bench, args: argparse.Namespace) -> dict[str, dict[str, int]]:
    """The shelf queries planned in each world, checked against the primitive scene."""
    from genplan.errors import InvalidGoalError, InvalidStartError
    from genplan.planning import Planner, PlannerSettings, environment

    env = environment("panda_shelf")
    queries = env.queries(bench.panda, n=args.queries, seed=args.seed)
    worlds = {"primitives": bench.primitives, f"cloud r {args.radius:g}": bench.cloud}
    thin = bench.panda.collision_world()
    thin.add_halfspace(bench.floor.name, bench.floor.normal, bench.floor.offset)
    thin.add_points("shelf", bench.pts, args.plan_radius, args.voxel)
    worlds[f"cloud r {args.plan_radius:g}"] = thin
    out = {}
    for name, world in worlds.items():
        planner = Planner(bench.panda, world=world, sampler="gan", settings=PlannerSettings(simplify=True), seed=0)
        row = {"queries": len(queries), "planned": 0, "refused": 0, "states": 0, "states_touching": 0,
               "motion_samples": 0, "motion_samples_touching": 0}
        for q in queries:
            try:
                result = planner.plan(q.start, q.goals)
            except (InvalidStartError, InvalidGoalError):
                row["refused"] += 1
                continue
            if not result.success:
                continue
            path = np.asarray(result.path)
            steps = [np.linspace(0.0, 1.0, max(1, int(np.ceil(np.abs(b - a).max() / 0.002))) + 1)[1:, None] * (b - a) + a
                     for a, b in zip(path[:-1], path[1:])]
            dense = np.concatenate([path[:1], *steps])
            row["planned"] += 1
            row["states"] += len(path)
            row["states_touching"] += int(np.sum(bench.primitives.in_collision(path)))
            row["motion_samples"] += len(dense)
            row["motion_samples_touching"] += int(np.sum(bench.primitives.in_collision(dense)))
        out[name] = row
    return out


def worker(args: argparse.Namespace) -> None:
    """Answer one JSON line per command read ("check", "spheres", "replace") until end of input."""
    bench = Bench(args)
    print(json.dumps({"balls": bench.kept}), flush=True)
    for line in sys.stdin:
        print(json.dumps(getattr(bench, line.strip())()), flush=True)


def compare(args: argparse.Namespace) -> dict[str, object]:
    """This build and the baseline's (``args.baseline``) in two workers, rounds interleaved."""
    cmd = [sys.executable, __file__, "--worker"] + [f"--{k}={v}" for k, v in vars(args).items()
                                                    if k in ("points", "voxel", "radius", "n", "seed")]
    env = dict(os.environ)
    builds = {}
    for name, path in (("after", None), ("before", args.baseline)):
        e = dict(env)
        if path is not None:
            e["PYTHONPATH"] = str(path) + os.pathsep + e.get("PYTHONPATH", "")
        builds[name] = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=e)
    balls = {name: json.loads(p.stdout.readline())["balls"] for name, p in builds.items()}

    def ask(name: str, what: str) -> dict[str, float]:
        p = builds[name]
        p.stdin.write(what + "\n")
        p.stdin.flush()
        return json.loads(p.stdout.readline())

    rounds: dict[str, dict[str, list]] = {b: {"check": [], "spheres": [], "replace": []} for b in builds}
    for r in range(args.rounds):
        order = ("before", "after") if r % 2 == 0 else ("after", "before")
        for what in ("check", "spheres", "replace"):
            for name in order:
                rounds[name][what].append(ask(name, what))
    for p in builds.values():
        p.stdin.close()
        p.wait()

    def medians(rows: list[dict]) -> dict[str, float | None]:
        return {k: (statistics.median(v) if None not in (v := [row[k] for row in rows]) else None) for k in rows[0]}

    out: dict[str, object] = {"balls": balls}
    for name in builds:
        out[name] = {what: medians(rows) | {"rounds": rows} for what, rows in rounds[name].items()}
    ratio = {}
    for what in ("check", "spheres", "replace"):
        a, b = out["after"][what], out["before"][what]
        ratio[what] = {k: (a[k] / b[k] if a[k] is not None and b[k] else None) for k in a if k != "rounds"}
    out["ratio_after_before"] = ratio
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--voxel", type=float, default=0.01)
    parser.add_argument("--radius", type=float, default=0.01)
    parser.add_argument("--n", type=int, default=10_000, help="configurations")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--queries", type=int, default=20, help="shelf queries planned in each world (0: none)")
    parser.add_argument("--plan-radius", type=float, default=0.0045,
                        help="the ball radius of the second cloud world the queries are planned in (m)")
    parser.add_argument("--baseline", type=Path, default=None,
                        help="a directory holding another build of the genplan package, timed against this one")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "point_clouds.json")
    args = parser.parse_args()
    if args.worker:
        worker(args)
        return

    load_before = os.getloadavg()[0]
    baseline = compare(args) if args.baseline is not None else None
    bench = Bench(args)
    check: dict[str, list[float]] = {"primitives": [], "cloud": []}
    spheres: dict[str, list[float]] = {"primitives": [], "cloud": []}
    replace: dict[str, list[float]] = {"voxel": [], "no_voxel": []}
    for _ in range(args.rounds):
        for into, row in ((check, bench.check()), (spheres, bench.spheres()), (replace, bench.replace())):
            for k, v in row.items():
                into[k].append(v)
    bench.restore()
    med = {k: statistics.median(v) for k, v in check.items()}
    sph = {k: (statistics.median(v) if None not in v else None) for k, v in spheres.items()}

    cloud, qs, kept = bench.cloud, bench.qs, bench.kept
    rates = {"primitives": float(np.mean(bench.primitives.in_collision(qs))), "cloud": float(np.mean(cloud.in_collision(qs)))}
    cloud.check_self = False
    ours = np.asarray(cloud.in_collision(qs))
    # the balls the world holds: the same down-sampling, done again here through a one-ball-per-voxel copy
    centres = _voxel_centroids(bench.pts, args.voxel)
    assert len(centres) == kept, (len(centres), kept)
    agree = coal_agreement(bench.panda, qs, centres, args.radius, bench.floor, ours)
    cloud.check_self = True
    planned = plans(bench, args) if args.queries > 0 else None

    result = {
        "command": "python benches/point_clouds.py " + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items()
                                                               if k not in ("out", "worker") and v is not None),
        "points": args.points, "voxel": args.voxel, "radius": args.radius, "balls": kept, "configurations": args.n,
        "check_us": {"primitives": med["primitives"], "cloud": med["cloud"], "ratio": med["cloud"] / med["primitives"],
                     "rounds": check},
        "spheres_us": sph | {"ratio": (sph["cloud"] / sph["primitives"]) if sph["cloud"] and sph["primitives"] else None,
                             "rounds": spheres},
        "collision_rate": rates,
        "obstacle_collision_rate_cloud": float(ours.mean()),
        "coal": agree,
        "replace_ms": {k: statistics.median(v) for k, v in replace.items()} | {"rounds": replace},
        "plans": planned,
        "baseline": baseline,
        "load_average": [load_before, os.getloadavg()[0]],
        "machine": platform.machine(), "cpus": os.cpu_count(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from genplan._files import write_text

    write_text(args.out, json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k not in ("check_us", "spheres_us", "replace_ms", "baseline")}, indent=1))
    print("check us/config:", {k: round(v, 3) for k, v in med.items()}, "ratio", round(med["cloud"] / med["primitives"], 2))
    print("spheres us/config:", {k: (round(v, 3) if v is not None else None) for k, v in sph.items()})
    print("replace ms:", {k: round(statistics.median(v), 1) for k, v in replace.items()})
    for name, row in (planned or {}).items():
        print(f"plans, {name}: {row['planned']} of {row['queries']} ({row['refused']} refused), states touching the "
              f"primitives {row['states_touching']} of {row['states']}, motion samples {row['motion_samples_touching']} "
              f"of {row['motion_samples']}")
    if baseline is not None:
        print("after / before:", json.dumps(baseline["ratio_after_before"]))
        for b in ("before", "after"):
            print(b, {w: {k: v for k, v in baseline[b][w].items() if k != "rounds"} for w in ("check", "spheres", "replace")})


def _voxel_centroids(points: np.ndarray, voxel: float) -> np.ndarray:
    """One centroid per occupied voxel (the world's down-sampling, written again in numpy)."""
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse.reshape(-1), points)
    return sums / counts[:, None]


if __name__ == "__main__":
    main()
