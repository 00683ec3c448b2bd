"""Non-convex meshes kept as meshes or decomposed (``Mesh(shape=...)``, a robot's ``mesh_shape``):
agreement with coal on the raw meshes, check time and plans.

    .venv/bin/python benches/nonconvex_meshes.py --out benches/results/nonconvex_meshes.json
        [--samples 10000] [--queries 20] [--rounds 5] [--seed 0]

(a) The Panda shelf scene with its bookshelf (five boards, two side panels) merged into ONE closed
    triangle mesh (the union of the seven boxes, written as an OBJ: :func:`box_union_obj`), the
    table and the floor as they are. For each shape of the shelf ("mesh", "decomposed", "hull")
    and for the seven boxes: agreement of ``in_collision`` with Pinocchio + coal on the same
    robot hulls and the raw shelf mesh (a coal ``BVHModelOBBRSS``) over ``--samples`` random
    configurations, the check time per configuration (batched, interleaved rounds, medians, the
    ratio to the boxes), and the Table II Panda shelf queries (``--queries``, the environment's
    seeded queries, the GAN sampler) planned in each world: success and time.
(b) UR10 with its collision meshes as hulls (today's default) and decomposed by V-HACD:
    agreement with coal on the raw meshes (benches/results/robots.json's measure), the check time
    per configuration (interleaved rounds, medians, the ratio) and the world's build time.
    ``--baseline DIR`` (DIR: a copy of the ``genplan`` package with another build's ``_core``,
    e.g. made before a change): the UR10 check times of this build and DIR's, each in a worker
    process of its own answering one round at a time, the order alternating per round; the JSON's
    ``ur10.baseline`` holds both builds' medians, their ratios to the hulls and after / before.

Every run is on one thread (rayon and torch).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import genplan  # noqa: E402
from genplan import _core  # noqa: E402
from genplan.collision import CollisionWorld  # noqa: E402
from genplan.errors import InvalidGoalError, InvalidStartError  # noqa: E402
from genplan.experiments.benchmarks.robots import agreement, coal_geometry, configurations  # noqa: E402
from genplan.experiments.common import machine, table, write_json  # noqa: E402
from genplan.planning import Planner, environment  # noqa: E402
from genplan.scene import Box, HalfSpace, Mesh, Scene  # noqa: E402

SHELF = "shelf_"


def box_union_obj(boxes: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The union of axis-aligned boxes (lo, hi) as one closed, outward-facing triangle mesh: the
    grid of every box face's coordinates, a cell inside when a box holds its centre, two
    triangles wherever an inside cell meets an outside one. Returns (vertices (n, 3), triangles
    (m, 3)), vertices shared on the grid so that the mesh is watertight."""
    axes = [np.unique(np.concatenate([[lo[k], hi[k]] for lo, hi in boxes])) for k in range(3)]
    n = [len(a) - 1 for a in axes]
    mids = [0.5 * (a[1:] + a[:-1]) for a in axes]
    inside = np.zeros(n, dtype=bool)
    for lo, hi in boxes:
        sel = [(m > lo[k]) & (m < hi[k]) for k, m in enumerate(mids)]
        inside |= sel[0][:, None, None] & sel[1][None, :, None] & sel[2][None, None, :]
    index: dict[tuple[int, int, int], int] = {}
    verts: list[tuple[float, float, float]] = []
    tris: list[tuple[int, int, int]] = []

    def vid(c: tuple[int, int, int]) -> int:
        if c not in index:
            index[c] = len(verts)
            verts.append((axes[0][c[0]], axes[1][c[1]], axes[2][c[2]]))
        return index[c]

    def is_in(c: list[int]) -> bool:
        return all(0 <= c[k] < n[k] for k in range(3)) and bool(inside[c[0], c[1], c[2]])

    for cell in zip(*np.nonzero(inside)):
        for axis in range(3):
            for d in (-1, 1):
                nb = list(cell)
                nb[axis] += d
                if is_in(nb):
                    continue
                u, v = (axis + 1) % 3, (axis + 2) % 3
                corners = []
                for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    g = [0, 0, 0]
                    g[axis] = cell[axis] + (1 if d > 0 else 0)
                    g[u], g[v] = cell[u] + du, cell[v] + dv
                    corners.append(vid((g[0], g[1], g[2])))
                if d < 0:
                    corners.reverse()
                tris += [(corners[0], corners[1], corners[2]), (corners[0], corners[2], corners[3])]
    return np.asarray(verts, dtype=np.float64), np.asarray(tris, dtype=np.int64)


def write_obj(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> Path:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n")
    return path


def shelf_scene(obj: Path, shape: str) -> Scene:
    """The panda_shelf scene with its shelf boxes replaced by the one mesh ``obj`` used as ``shape``."""
    env = environment("panda_shelf")
    kept = tuple(o for o in env.scene.obstacles if not o.name.startswith(SHELF))
    return Scene(f"panda_shelf_{shape}", (*kept, Mesh("shelf", obj, shape=shape)))


def coal_shelf(robot: Any, vertices: np.ndarray, triangles: np.ndarray) -> Any:
    """The robot's coal model (genplan's hulls and pairs) plus the table, the floor and the raw
    shelf mesh (a BVHModelOBBRSS), each paired with every robot geometry."""
    import coal
    import pinocchio as pin

    geom = coal_geometry(robot, hulls=True)
    n = geom.ngeoms
    env = environment("panda_shelf")
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(len(triangles), len(vertices))
    mesh.addVertices(np.ascontiguousarray(vertices))
    mesh.addTriangles(np.ascontiguousarray(triangles))
    mesh.endModel()
    objects = [("shelf", pin.SE3.Identity(), mesh)]
    for o in env.scene.obstacles:
        if isinstance(o, Box) and not o.name.startswith(SHELF):
            objects.append((o.name, pin.SE3(o.pose.matrix(), np.asarray(o.pose.position)), coal.Box(*(2 * np.asarray(o.half_extents)))))
        elif isinstance(o, HalfSpace):
            objects.append((o.name, pin.SE3.Identity(), coal.Halfspace(np.asarray(o.normal), o.offset)))
    for name, pose, shape in objects:
        k = geom.addGeometryObject(pin.GeometryObject(name, 0, 0, pose, shape))
        for i in range(n):
            geom.addCollisionPair(pin.CollisionPair(i, k))
    return geom


def timed_rounds(worlds: dict[str, CollisionWorld], qs: np.ndarray, rounds: int) -> dict[str, float]:
    """Median seconds per configuration of ``in_collision`` on the batch ``qs``, each world once
    per round, the rounds interleaved."""
    times: dict[str, list[float]] = {k: [] for k in worlds}
    for w in worlds.values():
        w.in_collision(qs[:100])  # warm up
    for _ in range(rounds):
        for k, w in worlds.items():
            t0 = time.perf_counter()
            w.in_collision(qs)
            times[k].append((time.perf_counter() - t0) / len(qs))
    return {k: statistics.median(v) for k, v in times.items()}


def shelf_part(samples: int, queries: int, rounds: int, seed: int, workdir: Path) -> dict[str, Any]:
    env = environment("panda_shelf")
    robot = genplan.load("panda")
    boxes = [(np.asarray(o.pose.position) - o.half_extents, np.asarray(o.pose.position) + o.half_extents)
             for o in env.scene.obstacles if isinstance(o, Box) and o.name.startswith(SHELF)]
    vertices, triangles = box_union_obj(boxes)
    obj = write_obj(workdir / "panda_shelf_bookcase.obj", vertices, triangles)
    worlds: dict[str, CollisionWorld] = {"boxes": env.world(robot)}
    build_s: dict[str, float] = {}
    for shape in _core.MESH_SHAPES:
        t0 = time.perf_counter()
        w = robot.collision_world()
        w.add_scene(shelf_scene(obj, shape))
        build_s[shape] = time.perf_counter() - t0
        worlds[shape] = w
    qs = configurations(robot, samples, seed)
    geom = coal_shelf(robot, vertices, triangles)
    rows: dict[str, dict[str, Any]] = {}
    for k, w in worlds.items():
        a = agreement(robot, qs, hulls=True, world=w, geom=geom)
        rows[k] = {"agreement": a["agreement"], "missed": a["missed"], "false_alarms": len(a["disagreements"]) - a["missed"],
                   "max_distance": a["max_distance"], "collision_rate_coal": a["rate"]}
    per_q = timed_rounds(worlds, qs, rounds)
    for k in worlds:
        rows[k]["check_us"] = per_q[k] * 1e6
        rows[k]["check_ratio_to_boxes"] = per_q[k] / per_q["boxes"]
        rows[k]["build_s"] = build_s.get(k)
    plan_queries = env.queries(robot, queries, seed=seed)
    for k, w in worlds.items():
        planner = Planner(robot, world=w, sampler="gan", seed=seed)
        ok, times, certified = [], [], []
        for q in plan_queries:
            t0 = time.perf_counter()
            try:
                r = planner.plan(q.start, q.goals)
            except (InvalidStartError, InvalidGoalError):
                # the hull fills the shelf: its goals are in collision there
                times.append(time.perf_counter() - t0)
                ok.append(False)
                continue
            times.append(time.perf_counter() - t0)
            ok.append(bool(r.success))
            # every state of a found path checked against the seven boxes
            if r.success:
                path = np.asarray(r.path)
                certified.append(not bool(np.any(worlds["boxes"].in_collision(path))))
        rows[k].update(plan_success=float(np.mean(ok)), plan_time_mean_s=float(np.mean(times)),
                       plan_time_median_s=float(np.median(times)),
                       paths_free_of_the_boxes=float(np.mean(certified)) if certified else None)
    return {"mesh": {"vertices": len(vertices), "triangles": len(triangles), "closed": True},
            "samples": samples, "queries": queries, "rounds": rounds, "rows": rows}


def ur10_worlds() -> tuple[Any, dict[str, CollisionWorld], dict[str, float]]:
    """The UR10 and its worlds with the meshes as hulls and decomposed, and their build times (s)."""
    robot = genplan.load("ur10")
    pairs = robot.disabled_pairs if robot.srdf_path is None or robot.merge_computed_pairs else None
    worlds: dict[str, CollisionWorld] = {}
    build_s: dict[str, float] = {}
    for shape in ("hull", "decomposed"):
        t0 = time.perf_counter()
        native = _core.CollisionWorld(robot.kinematics, robot.collision_urdf_path, robot.package_dirs, robot.srdf_path,
                                      pairs, mesh_shape=shape)
        build_s[shape] = time.perf_counter() - t0
        worlds[shape] = CollisionWorld(native)
    return robot, worlds, build_s


def ur10_worker(samples: int, seed: int) -> None:
    """Answer each line read with one round of the UR10 check times (s per configuration, JSON)."""
    robot, worlds, _ = ur10_worlds()
    qs = configurations(robot, samples, seed)
    for w in worlds.values():
        w.in_collision(qs[:100])  # warm up
    print("ready", flush=True)
    for _ in sys.stdin:
        out = {}
        for k, w in worlds.items():
            t0 = time.perf_counter()
            w.in_collision(qs)
            out[k] = (time.perf_counter() - t0) / len(qs)
        print(json.dumps(out), flush=True)


def ur10_baseline(samples: int, rounds: int, seed: int, baseline: Path) -> dict[str, Any]:
    """This build's and ``baseline``'s UR10 check times, rounds alternating (see the module text)."""
    cmd = [sys.executable, __file__, "--ur10-worker", f"--samples={samples}", f"--seed={seed}"]
    procs = {}
    for name, path in (("after", None), ("before", baseline)):
        env = dict(os.environ)
        if path is not None:
            env["PYTHONPATH"] = str(path) + os.pathsep + env.get("PYTHONPATH", "")
        procs[name] = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    for p in procs.values():
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    times: dict[str, list[dict[str, float]]] = {k: [] for k in procs}
    for r in range(rounds):
        for name in (("before", "after") if r % 2 == 0 else ("after", "before")):
            p = procs[name]
            assert p.stdin is not None and p.stdout is not None
            p.stdin.write("round\n")
            p.stdin.flush()
            times[name].append(json.loads(p.stdout.readline()))
    for p in procs.values():
        assert p.stdin is not None
        p.stdin.close()
        p.wait()
    out: dict[str, Any] = {}
    for name, rows in times.items():
        med = {k: statistics.median(row[k] for row in rows) * 1e6 for k in rows[0]}
        out[name] = {"check_us": med, "ratio_to_hulls": med["decomposed"] / med["hull"], "rounds_us": rows}
    out["after_before"] = {k: out["after"]["check_us"][k] / out["before"]["check_us"][k] for k in out["after"]["check_us"]}
    return out


def ur10_part(samples: int, rounds: int, seed: int) -> dict[str, Any]:
    robot, worlds, build_s = ur10_worlds()
    qs = configurations(robot, samples, seed)
    geom = coal_geometry(robot, hulls=False)
    rows: dict[str, dict[str, Any]] = {}
    for k, w in worlds.items():
        a = agreement(robot, qs, hulls=False, world=w, geom=geom)
        rows[k] = {"agreement": a["agreement"], "missed": a["missed"], "false_alarms": len(a["disagreements"]) - a["missed"],
                   "max_distance": a["max_distance"], "collision_rate_coal": a["rate"], "build_s": build_s[k]}
    per_q = timed_rounds(worlds, qs, rounds)
    for k in worlds:
        rows[k]["check_us"] = per_q[k] * 1e6
        rows[k]["check_ratio_to_hulls"] = per_q[k] / per_q["hull"]
    return {"samples": samples, "rounds": rounds, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=10_000)
    p.add_argument("--queries", type=int, default=20)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--parts", nargs="+", choices=("shelf", "ur10"), default=["shelf", "ur10"])
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--baseline", type=Path, default=None,
                   help="a directory holding another build of the genplan package, its UR10 check timed against this one's")
    p.add_argument("--ur10-worker", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.ur10_worker:
        ur10_worker(args.samples, args.seed)
        return 0
    import torch

    torch.set_num_threads(1)
    payload: dict[str, Any] = {"benchmark": "nonconvex_meshes", "machine": machine(), "seed": args.seed,
                               "load_average_start": os.getloadavg()}
    with tempfile.TemporaryDirectory() as tmp:
        if "ur10" in args.parts:
            payload["ur10"] = ur10_part(args.samples, args.rounds, args.seed)
            if args.baseline is not None:
                b = payload["ur10"]["baseline"] = ur10_baseline(args.samples, args.rounds, args.seed, args.baseline)
                print("UR10 decomposed / hulls: after", f"{b['after']['ratio_to_hulls']:.3f},", "before",
                      f"{b['before']['ratio_to_hulls']:.3f}; after / before:",
                      {k: round(v, 3) for k, v in b["after_before"].items()})
            print(table(["UR10 meshes", "agreement", "missed", "false alarms", "check us", "ratio", "build s"],
                        [[k, f"{100 * r['agreement']:.2f} %", r["missed"], r["false_alarms"], f"{r['check_us']:.2f}",
                          f"{r['check_ratio_to_hulls']:.2f}", f"{r['build_s']:.2f}"]
                         for k, r in payload["ur10"]["rows"].items()]))
        if "shelf" in args.parts:
            payload["shelf"] = shelf_part(args.samples, args.queries, args.rounds, args.seed, Path(tmp))
            print(table(["shelf as", "agreement", "missed", "false alarms", "check us", "ratio", "plan success",
                         "plan s (mean)"],
                        [[k, f"{100 * r['agreement']:.2f} %", r["missed"], r["false_alarms"], f"{r['check_us']:.2f}",
                          f"{r['check_ratio_to_boxes']:.2f}", f"{100 * r['plan_success']:.0f} %",
                          f"{r['plan_time_mean_s']:.2f}"] for k, r in payload["shelf"]["rows"].items()]))
    payload["load_average_end"] = os.getloadavg()
    if args.out is not None:
        write_json(args.out, payload)
    return 0


if __name__ == "__main__":
    sys.exit(main())
