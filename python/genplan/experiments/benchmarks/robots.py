"""Any robot through one path: load, kinematics and collision checked against Pinocchio + coal.

    genplan bench robots --out benches/results/robots.json [--samples N] [--seed S]

Every robot is loaded by :func:`genplan.load` (the presets as robot files, xArm7 from its URDF
with keywords, as a user would), then on random configurations (continuous joints as unit
complex numbers):

* ``fk_max_error``: the largest difference of any link pose (4x4 entries, metres) between the
  Rust kinematics and Pinocchio;
* ``agreement_hulls``: share of configurations where the Rust collision answer equals coal's on
  the same geometry (coal's convex hulls of the meshes, the same self-collision pairs), with
  ``disagree_max_distance_hulls`` the largest |signed distance| (Rust) of a disagreement; a
  disagreement is asked again of coal with a fresh GeometryData, since coal's answer depends on
  the queries before it (``coal_history_flips_*`` counts the answers that changed);
* ``agreement_meshes``: the same against coal on the raw meshes (genplan collides hulls, so
  this measures the cost of that choice), with its largest disagreement distance;
* ``contacts_missed_*``: configurations coal finds in collision and genplan free (a hull contains
  its mesh, so 0 on raw meshes means the hulls only ever err on the safe side);
* ``load_ms``: time of a fresh :func:`genplan.load` plus the first collision world (self-
  collision pairs computed for a robot without an SRDF, cache disabled).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import tempfile
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

import genplan
from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json
from genplan.robots import robots_dir


def xarm7() -> Any:
    """example-robot-data's xArm7, not a preset: loaded from its URDF with keywords."""
    root = robots_dir() / "xarm_description"
    return genplan.load(urdf=root / "urdf" / "xarm7.urdf", srdf=root / "srdf" / "xarm7.srdf",
                        frames={"tool": "link_eef"})


#: name -> how to load it (the same genplan.load path for every robot).
ROBOTS: dict[str, Callable[[], Any]] = {
    "panda": functools.partial(genplan.load, "panda"),
    "ur3": functools.partial(genplan.load, "ur3"),
    "ur5": functools.partial(genplan.load, "ur5"),
    "ur10": functools.partial(genplan.load, "ur10"),
    "xarm7": xarm7,
    "kinova": functools.partial(genplan.load, "kinova"),
    "talos": functools.partial(genplan.load, "talos"),
}


def configurations(robot: Any, n: int, seed: int) -> NDArray[np.float64]:
    """Joints uniform in their limits (continuous joints as unit complex numbers); a free-flyer
    base anywhere in a 2 m cube with a uniformly random orientation (so FK is checked away from
    the default base placement too)."""
    rng = np.random.default_rng(seed)
    q = robot.random_configurations(n, rng)
    if robot.floating_base:
        q[:, :3] = rng.uniform(-1.0, 1.0, size=(n, 3))
        quat = rng.normal(size=(n, 4))
        q[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return q


def fk_max_error(robot: Any, qs: NDArray[np.float64]) -> float:
    """Largest |Rust - Pinocchio| over every link pose entry and configuration."""
    import pinocchio as pin

    links = list(robot.kinematics.link_names)
    fids = [robot.model.getFrameId(name) for name in links]
    ours = robot.link_poses(qs, links)
    worst = 0.0
    for q, poses in zip(qs, ours):
        pin.framesForwardKinematics(robot.model, robot.data, q)
        ref = np.stack([robot.data.oMf[f].homogeneous for f in fids])
        worst = max(worst, float(np.max(np.abs(poses - ref))))
    return worst


def coal_geometry(robot: Any, hulls: bool) -> Any:
    """The robot's coal collision model (its pairs as genplan's), meshes as convex hulls or raw."""
    import coal

    geom = robot.collision_model.copy()
    if hulls:
        for g in geom.geometryObjects:
            if isinstance(g.geometry, coal.BVHModelBase):
                g.geometry.buildConvexHull(True, "Qt")
                g.geometry = g.geometry.convex
    return geom


def agreement(robot: Any, qs: NDArray[np.float64], hulls: bool, world: Any = None, geom: Any = None) -> dict[str, Any]:
    """Share of equal answers, largest |distance| (Rust) of a disagreement, share in collision
    (coal). coal's answer depends on its history (a cached GJK guess in the GeometryData): a
    disagreement is asked again of a fresh GeometryData, and ``coal_history_flips`` counts the
    answers that changed (coal misses a contact after other queries; seen on UR3/UR10 hulls).
    ``world`` / ``geom``: the same scene on both sides (default: the robot alone, its
    :func:`coal_geometry`); ``disagreements`` lists each (row, genplan's answer, distance)."""
    import pinocchio as pin

    geom = coal_geometry(robot, hulls) if geom is None else geom
    gdata = pin.GeometryData(geom)
    world = robot.collision_world() if world is None else world
    ours = world.in_collision(qs)
    ref = np.array([bool(pin.computeCollisions(robot.model, robot.data, geom, gdata, q, True)) for q in qs])
    flips = 0
    for i in np.nonzero(ours != ref)[0]:
        fresh = bool(pin.computeCollisions(robot.model, robot.data, geom, pin.GeometryData(geom), qs[i], True))
        flips += int(fresh != ref[i])
        ref[i] = fresh
    disagree = ours != ref
    d = np.asarray(world.min_distance(qs[disagree])) if disagree.any() else np.zeros(0)
    dist = float(np.max(np.abs(d))) if len(d) else 0.0
    listed = [{"row": int(i), "genplan_collides": bool(ours[i]), "distance": float(x)}
              for i, x in zip(np.nonzero(disagree)[0], d)]
    return {"agreement": float(1.0 - disagree.mean()), "max_distance": dist, "rate": float(ref.mean()),
            "coal_history_flips": flips, "missed": int(np.sum(ref & ~ours)), "disagreements": listed}


@contextlib.contextmanager
def _env(key: str, value: str) -> Iterator[None]:
    old = os.environ.get(key)
    os.environ[key] = value
    try:
        yield
    finally:
        if old is None:
            del os.environ[key]
        else:
            os.environ[key] = old


def check_robot(name: str, samples: int, seed: int, fresh: bool = True) -> dict[str, Any]:
    """One row of the table; ``fresh``: time a load from scratch (no cached robot, pairs
    computed anew), else use the caches (for tests)."""
    with contextlib.ExitStack() as stack:
        if fresh:  # an empty cache folder: nothing loaded or computed before counts
            genplan.robots.clear_cache()
            stack.enter_context(_env("GENPLAN_CACHE", stack.enter_context(tempfile.TemporaryDirectory())))
        t0 = time.perf_counter()
        robot = ROBOTS[name]()
        world = robot.collision_world()
        load_ms = (time.perf_counter() - t0) * 1e3
    qs = configurations(robot, samples, seed)
    h = agreement(robot, qs, hulls=True)
    m = agreement(robot, qs, hulls=False)
    return {
        "robot": name, "nq": robot.nq, "nv": robot.nv, "continuous_joints": len(robot.continuous),
        "srdf": robot.srdf_path is not None, "geometries": len(world.geometry_names),
        "self_pairs": len(world.self_pairs), "load_ms": load_ms, "samples": samples,
        "fk_max_error": fk_max_error(robot, qs[: min(samples, 1000)]), "collision_rate": h["rate"],
        "agreement_hulls": h["agreement"], "disagree_max_distance_hulls": h["max_distance"],
        "coal_history_flips_hulls": h["coal_history_flips"],
        "agreement_meshes": m["agreement"], "disagree_max_distance_meshes": m["max_distance"],
        "coal_history_flips_meshes": m["coal_history_flips"],
        "contacts_missed_hulls": h["missed"], "contacts_missed_meshes": m["missed"],
    }


def run(names: list[str], samples: int, seed: int) -> dict[str, Any]:
    rows = [check_robot(n, samples, seed) for n in names]
    return {"benchmark": "robots", "machine": machine(), "samples": samples, "seed": seed, "rows": rows}


def print_table(payload: dict[str, Any]) -> None:
    print(table(
        ["robot", "nq", "SRDF", "pairs", "FK err", "agree hulls", "max |d|", "coal flips", "agree meshes", "max |d|",
         "load ms"],
        [[r["robot"], r["nq"], "yes" if r["srdf"] else "computed", r["self_pairs"], f"{r['fk_max_error']:.1e}",
          f"{100 * r['agreement_hulls']:.2f} %", f"{r['disagree_max_distance_hulls'] * 1e3:.2f} mm",
          r["coal_history_flips_hulls"] + r["coal_history_flips_meshes"],
          f"{100 * r['agreement_meshes']:.2f} %", f"{r['disagree_max_distance_meshes'] * 1e3:.1f} mm",
          f"{r['load_ms']:.0f}"] for r in payload["rows"]],
    ))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=list(ROBOTS), metavar="ROBOT",
                   help=f"robots to check (default: all: {', '.join(ROBOTS)})")
    p.add_argument("--samples", type=A.positive_int, default=10_000, help="random configurations per robot")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


def main(args: argparse.Namespace) -> int:
    payload = run(args.robots, args.samples, args.seed)
    print_table(payload)
    write_json(args.out, payload)
    return 0

