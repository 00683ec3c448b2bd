"""genplan beside its peers, measured side by side in one run (issue 18, [core-speed]): FK vs
Pinocchio, collision vs Pinocchio + coal, IK vs pink, placo, ikpy and pytorch-kinematics, plan
time vs the number of obstacles.

    genplan bench peers --out benches/results/peers.json --markdown benches/results/peers.md
    genplan bench peers --quick --only fk,collision          # small sizes (the tests' run)

The peers are the optional ``genplan[peers]`` extra (pin-pink + daqp, ikpy, pytorch-kinematics);
placo pins ``pin==3.8`` and runs in an interpreter of its own (``--placo-python`` or
``$GENPLAN_PLACO_PYTHON``, see :mod:`genplan.experiments.peers.placo`). A peer that is not
installed is skipped with the install command in the output (JSON ``skipped``); Pinocchio and
coal come with genplan.

How it is measured: every figure is the median of ``--repeats`` repeats, the sides of a
comparison alternating within each repeat (so a load change hits both); the 1-minute load
average is recorded before and after each section. genplan is called through its public API;
its batched calls run in worker processes started with ``RAYON_NUM_THREADS`` = 1 and 2 (the
thread count is a process-wide choice of rayon), and the single calls and every peer in this
process (one thread; torch at 1 thread).

* **fk**: one call from Python, the Panda hand: ``robot.link_poses(q, [hand])`` vs
  ``pin.forwardKinematics`` + ``pin.updateFramePlacement`` (its result left in ``data.oMf``);
  batched Panda hand and Talos all links (``robot.link_poses(Q, links)``; Talos also into one
  preallocated array reused across calls, ``out=``: the 10,000 x 60 poses are 77 MB, which a new
  array per call first has to fault in) vs the same Pinocchio calls in a Python loop (Talos:
  ``pin.framesForwardKinematics``, every frame, left in ``data.oMf``), microseconds per
  configuration.
* **collision**: the Panda against itself and the table of the ``panda_shelf`` scene, Talos
  against itself; ``world.in_collision(Q)`` vs Pinocchio + coal with the same pairs
  (:func:`genplan.experiments.benchmarks.robots.coal_geometry`), on the raw meshes and on coal's
  convex hulls: a Python loop of ``pin.computeCollisions`` (stop at the first contact), the
  C++ batch ``pin.computeCollisionsInParallel`` over a ``GeometryPool`` (all pairs, no broad
  phase) and over a ``BroadPhaseManagerPool`` (coal's ``DynamicAABBTreeCollisionManager``), each
  with 1 and 2 threads. Agreement with coal on the same convex hulls (and on the raw meshes):
  :func:`genplan.experiments.benchmarks.robots.agreement`, every disagreement with its distance.
* **ik**: the Panda IK task on reachable targets (the hand poses of configurations on the task's
  manifold, seed 2000 + seed, as ``genplan bench ik``) from the same uniform random starts for
  every solver, one attempt each, judged by one test
  (:func:`genplan.experiments.peers.ik.success`); the problems are split in ``repeats`` chunks and
  the solvers alternate chunk by chunk. genplan: ``genplan.solve_ik(init=starts, restarts=0,
  iterations=ik_iterations, parallel=False)``, the peers' step cap (solve_ik's solver:
  ``genplan.ik.IK_SETTINGS``, the posture towards the joint-range middle); the same with the
  paper's solver (``genplan_paper_solver``: ``settings=SolverSettings(), nominal="start"``); and
  ``genplan_retries``, the
  user's call ``solve_ik(init=starts, time_budget_s=0.005)`` (first attempt from the same start,
  failed ones redrawn from uniform starts as TRAC-IK's random restarts do; its time per target
  includes every attempt), beside the peers' one start. Talos' whole-body IK task the
  same way, from starts drawn once from its shipped GAN (``GanModel.sample``, not timed), genplan
  vs pink and placo (ikpy and pytorch-kinematics are set up for the Panda's fixed base). Success
  rate, time per problem and per solved problem (all the time spent over the problems solved).
* **plan**: ``environment("panda_shelf")`` with 0, 50 and 200 extra boxes out of the Panda's reach
  (:func:`add_extra_boxes`): ``world.in_collision`` on a batch (microseconds per configuration)
  and a GAN plan per query; the answers must not change.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import itertools
import multiprocessing
import os
import statistics
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

import genplan
from genplan._files import write_text
from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json

SECTIONS = ("fk", "collision", "ik", "plan")
#: the scene the Panda's table (and the plan section) come from
SHELF = "panda_shelf"
TABLE = "table_top"
THREADS = (1, 2)


@dataclass(frozen=True)
class Sizes:
    fk_calls: int = 2000  #: single calls per repeat
    fk_batch: int = 10_000
    collision: int = 10_000  #: configurations per genplan batch
    coal: tuple[tuple[str, int], ...] = (("panda", 10_000), ("talos", 2000))  #: configurations per coal setup
    agreement: tuple[tuple[str, int], ...] = (("panda", 10_000), ("talos", 10_000))
    ik_targets: int = 500
    talos_ik_targets: int = 500
    ik_iterations: int = 100  #: every solver's step cap (Gauss-Newton iterations, QP steps, ...)
    obstacles: tuple[int, ...] = (0, 50, 200)
    plan_queries: int = 20
    plan_check: int = 10_000


QUICK = Sizes(fk_calls=200, fk_batch=500, collision=300, coal=(("panda", 100), ("talos", 20)),
              agreement=(("panda", 300), ("talos", 100)), ik_targets=10, talos_ik_targets=4, ik_iterations=50,
              obstacles=(0, 20), plan_queries=1, plan_check=300)


def load() -> float:
    return os.getloadavg()[0]


def _median(xs: list[float]) -> dict[str, Any]:
    return {"median": statistics.median(xs), "all": xs}


def interleaved(sides: dict[str, Callable[[], float]], repeats: int) -> dict[str, dict[str, Any]]:
    """Each side (returning microseconds per item) once untimed (a warm-up: a worker's first
    large output faults its pages in, 13-24 us per Talos configuration instead of 2.5 on the first
    calls), then once per repeat, in turn; medians."""
    for f in sides.values():
        f()
    runs: dict[str, list[float]] = {k: [] for k in sides}
    for _ in range(repeats):
        for k, f in sides.items():
            runs[k].append(float(f()))
    return {k: _median(v) for k, v in runs.items()}


# --------------------------------------------------------------------------------------------
# shared scene pieces
# --------------------------------------------------------------------------------------------


def table_box() -> Any:
    """The table of the ``panda_shelf`` scene (its one definition: the scene file)."""
    from genplan.scene import load_scene

    return next(o for o in load_scene(SHELF).obstacles if o.name == TABLE)


def collision_world(robot: genplan.Robot) -> genplan.CollisionWorld:
    """The collision section's world: the Panda with the shelf scene's table, Talos alone."""
    world = robot.collision_world()
    if robot.name == "panda":
        box = table_box()
        world.add_box(box.name, box.half_extents, box.pose.position, box.pose.matrix())
    return world


def coal_model(robot: genplan.Robot, hulls: bool) -> Any:
    """The same geometry and pairs for Pinocchio + coal (the Panda's table: a coal box, paired with
    every robot geometry, as genplan checks every robot shape against the obstacles)."""
    import coal
    import pinocchio as pin

    from genplan.experiments.benchmarks.robots import coal_geometry

    geom = coal_geometry(robot, hulls)
    if robot.name == "panda":
        box = table_box()
        n = geom.ngeoms
        geom.addGeometryObject(pin.GeometryObject(box.name, 0, 0, pin.SE3(box.pose.matrix(), np.asarray(box.pose.position)),
                                                  coal.Box(*(2 * np.asarray(box.half_extents)))))
        for i in range(n):
            geom.addCollisionPair(pin.CollisionPair(i, n))
    return geom


def add_extra_boxes(world: genplan.CollisionWorld, n: int, seed: int) -> None:
    """n seeded random boxes out of the Panda's reach (about 1.2 m from its base): centres 1.6 to
    3 m from the base horizontally, z in [-0.4, 1.6], half extents 0.03 to 0.15 m, random
    rotations (also used by benches/obstacles.py)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        r, a, z = rng.uniform(1.6, 3.0), rng.uniform(0.0, 2 * np.pi), rng.uniform(-0.4, 1.6)
        half = rng.uniform(0.03, 0.15, size=3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(0.0, 1.0)
        k_ = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rot = np.eye(3) + np.sin(angle) * k_ + (1 - np.cos(angle)) * k_ @ k_  # Rodrigues
        world.add_box(f"extra_{k}", half, (r * np.cos(a), r * np.sin(a), z), rot)


# --------------------------------------------------------------------------------------------
# genplan's batched calls in worker processes with a fixed rayon thread count
# --------------------------------------------------------------------------------------------

_CACHE: dict[Any, Any] = {}


def _robot(name: str) -> genplan.Robot:
    if ("robot", name) not in _CACHE:
        _CACHE[("robot", name)] = genplan.load(name)
    return _CACHE[("robot", name)]  # type: ignore[no-any-return]


def configurations(robot: genplan.Robot, n: int, seed: int) -> Any:
    return robot.random_configurations(n, seed)


def _genplan_batch(job: tuple[str, str, int, int]) -> float:
    """Microseconds per configuration of one genplan batched call (in a worker)."""
    kind, name, n, seed = job
    robot = _robot(name)
    if (job, "q") not in _CACHE:
        _CACHE[(job, "q")] = configurations(robot, n, seed)
    qs = _CACHE[(job, "q")]
    if kind == "collision":
        if ("world", name) not in _CACHE:
            _CACHE[("world", name)] = collision_world(robot)
        world = _CACHE[("world", name)]
        t0 = time.perf_counter()
        world.in_collision(qs)
    else:
        links = [robot.frames["hand"]] if kind == "fk_hand" else None
        # "fk_all_out": into one preallocated array, reused across calls (``out=``), as a user
        # repeating batches would; otherwise a new array per call
        out = None
        if kind == "fk_all_out":
            if (job, "out") not in _CACHE:
                _CACHE[(job, "out")] = np.empty((n, len(robot.kinematics.link_names), 4, 4))
            out = _CACHE[(job, "out")]
        t0 = time.perf_counter()
        robot.link_poses(qs, links, out=out)
    return (time.perf_counter() - t0) / n * 1e6


def _worker_threads() -> int:
    return int(os.environ.get("RAYON_NUM_THREADS", "0"))


@contextlib.contextmanager
def workers(threads: tuple[int, ...]) -> Iterator[dict[int, Any]]:
    """One worker process per thread count (rayon reads RAYON_NUM_THREADS when it starts)."""
    ctx = multiprocessing.get_context("spawn")
    pools: dict[int, Any] = {}
    old = os.environ.get("RAYON_NUM_THREADS")
    try:
        for k in threads:
            os.environ["RAYON_NUM_THREADS"] = str(k)
            pools[k] = ctx.Pool(1)
            assert pools[k].apply(_worker_threads) == k
    finally:
        if old is None:
            os.environ.pop("RAYON_NUM_THREADS", None)
        else:
            os.environ["RAYON_NUM_THREADS"] = old
    try:
        yield pools
    finally:
        for p in pools.values():
            p.terminate()
            p.join()


# --------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------


def run_fk(sizes: Sizes, repeats: int, seed: int, pools: dict[int, Any]) -> dict[str, Any]:
    import pinocchio as pin

    out: dict[str, Any] = {"load_before": load()}
    panda = _robot("panda")
    hand = panda.frames["hand"]
    fid = panda.model.getFrameId(hand)
    model, data = panda.model, panda.model.createData()
    calls = [q.copy() for q in configurations(panda, sizes.fk_calls, seed)]

    def genplan_single() -> float:
        t0 = time.perf_counter()
        for q in calls:
            panda.link_poses(q, [hand])
        return (time.perf_counter() - t0) / len(calls) * 1e6

    def pin_single() -> float:
        t0 = time.perf_counter()
        for q in calls:
            pin.forwardKinematics(model, data, q)
            pin.updateFramePlacement(model, data, fid)
        return (time.perf_counter() - t0) / len(calls) * 1e6

    out["panda_hand_single"] = interleaved({"genplan": genplan_single, "pinocchio": pin_single}, repeats)

    def batch_sides(kind: str, name: str) -> dict[str, Callable[[], float]]:
        robot = _robot(name)
        m, d = robot.model, robot.model.createData()
        qs = configurations(robot, sizes.fk_batch, seed)
        sides: dict[str, Callable[[], float]] = {
            f"genplan_{k}_thread": functools.partial(pools[k].apply, _genplan_batch, ((kind, name, sizes.fk_batch, seed),))
            for k in pools}
        if kind == "fk_all":
            sides.update({f"genplan_{k}_thread_out": functools.partial(
                pools[k].apply, _genplan_batch, (("fk_all_out", name, sizes.fk_batch, seed),)) for k in pools})
        f = m.getFrameId(robot.frames["hand"]) if kind == "fk_hand" else 0

        def loop() -> float:
            t0 = time.perf_counter()
            if kind == "fk_hand":
                for q in qs:
                    pin.forwardKinematics(m, d, q)
                    pin.updateFramePlacement(m, d, f)
            else:
                for q in qs:
                    pin.framesForwardKinematics(m, d, q)
            return (time.perf_counter() - t0) / len(qs) * 1e6

        sides["pinocchio_loop"] = loop
        return sides

    out["panda_hand_batch"] = interleaved(batch_sides("fk_hand", "panda"), repeats)
    out["talos_all_links_batch"] = interleaved(batch_sides("fk_all", "talos"), repeats)
    out["talos_links"] = len(_robot("talos").kinematics.link_names)
    out["batch"] = sizes.fk_batch
    out["load_after"] = load()
    return out


def run_collision(sizes: Sizes, repeats: int, seed: int, pools: dict[int, Any]) -> dict[str, Any]:
    import pinocchio as pin

    from genplan.experiments.benchmarks.robots import agreement

    out: dict[str, Any] = {}
    coal_n, agree_n = dict(sizes.coal), dict(sizes.agreement)
    for name in ("panda", "talos"):
        row: dict[str, Any] = {"load_before": load()}
        robot = _robot(name)
        world = collision_world(robot)
        qs = configurations(robot, sizes.collision, seed)
        m = min(coal_n[name], sizes.collision)
        qc = qs[:m]
        qt = np.asfortranarray(qc.T)
        sides: dict[str, Callable[[], float]] = {
            f"genplan_{k}_thread": functools.partial(pools[k].apply, _genplan_batch,
                                                     (("collision", name, sizes.collision, seed),))
            for k in pools}
        for hulls in (False, True):
            geom = coal_model(robot, hulls)
            gdata = pin.GeometryData(geom)
            shape = "hulls" if hulls else "meshes"

            def loop(geom: Any = geom, gdata: Any = gdata) -> float:
                t0 = time.perf_counter()
                for q in qc:
                    pin.computeCollisions(robot.model, robot.data, geom, gdata, q, True)
                return (time.perf_counter() - t0) / m * 1e6

            sides[f"coal_{shape}_python_loop"] = loop
            for k in THREADS:
                pool = pin.GeometryPool(robot.model, geom, k)
                broad = pin.BroadPhaseManagerPool_DynamicAABBTreeCollisionManager(robot.model, geom, k)

                def batch(pool: Any = pool, k: int = k) -> float:
                    t0 = time.perf_counter()
                    pin.computeCollisionsInParallel(k, pool, qt, True)
                    return (time.perf_counter() - t0) / m * 1e6

                sides[f"coal_{shape}_batch_{k}_thread"] = batch
                sides[f"coal_{shape}_broad_phase_{k}_thread"] = functools.partial(batch, broad, k)
        row["timings_us_per_config"] = interleaved(sides, repeats)
        row["configurations"] = sizes.collision
        row["coal_configurations"] = m
        row["pairs"] = {"self": len(world.self_pairs), "obstacles": len(world.obstacle_names)}
        row["collision_rate"] = float(np.mean(world.in_collision(qs)))
        qa = qs[: agree_n[name]]
        for hulls in (True, False):
            a = agreement(robot, qa, hulls, world=world, geom=coal_model(robot, hulls))
            row[f"agreement_{'hulls' if hulls else 'meshes'}"] = {**a, "configurations": len(qa)}
        row["load_after"] = load()
        out[name] = row
    return out


IK_PEERS = ("pink", "placo", "ikpy", "pytorch_kinematics")
#: the per-target time budget of the ``genplan_retries`` row (``solve_ik(time_budget_s=)``)
IK_RETRY_BUDGET_S = 0.005


def _peer_module(name: str) -> Any:
    import importlib

    return importlib.import_module(f"genplan.experiments.peers.{name}")


#: which peers take which robot's task (ikpy and pytorch-kinematics are set up for a fixed base
#: and the Panda's one-free-axis orientation)
IK_PEERS_FOR = {"panda": IK_PEERS, "talos": ("pink", "placo")}


def _compare_ik(pb: Any, peers: tuple[str, ...], sizes: Sizes, repeats: int, placo_python: str | None,
                skipped: dict[str, str]) -> dict[str, Any]:
    """genplan and ``peers`` on the same problems, the solvers alternating chunk by chunk."""
    from genplan.experiments.peers import ik as K
    from genplan.ik import solve_ik
    from genplan.projection import SolverSettings

    def genplan_ik(p: K.IKProblems) -> K.IKOutcome:
        res = solve_ik(p.robot, p.task, p.positions, init=p.starts, restarts=0, parallel=False,
                       iterations=sizes.ik_iterations)
        return K.IKOutcome("genplan", res.q, K.success(p, res.q), res.solve_s,
                           note=f"solve_ik(init=starts, restarts=0, iterations={sizes.ik_iterations}), one core")

    def genplan_paper_solver(p: K.IKProblems) -> K.IKOutcome:
        # the same call with the paper's solver (line search, posture towards the start): before
        # solve_ik's own defaults (genplan.ik.IK_SETTINGS, nominal "mid")
        res = solve_ik(p.robot, p.task, p.positions, init=p.starts, restarts=0, parallel=False,
                       iterations=sizes.ik_iterations, settings=SolverSettings(), nominal="start")
        return K.IKOutcome("genplan_paper_solver", res.q, K.success(p, res.q), res.solve_s,
                           note=f"solve_ik(init=starts, restarts=0, iterations={sizes.ik_iterations}, "
                                "settings=SolverSettings(), nominal='start'): the paper's solver, one core")

    def genplan_retries(p: K.IKProblems) -> K.IKOutcome:
        # the user's call: the first attempt from the same start, a failed one redrawn from a
        # uniform start (TRAC-IK's random restarts), solve_ik's defaults, 5 ms per target
        # solve_ik's budget is the call's wall clock: IK_RETRY_BUDGET_S per problem of the chunk
        res = solve_ik(p.robot, p.task, p.positions, init=p.starts, parallel=False,
                       time_budget_s=IK_RETRY_BUDGET_S * len(p.positions))
        return K.IKOutcome("genplan_retries", res.q, K.success(p, res.q), res.solve_s,
                           note=f"solve_ik(init=starts, time_budget_s={IK_RETRY_BUDGET_S}): defaults "
                                "(restarts=20, iterations=20), retries from uniform starts, one core")

    solvers: dict[str, Callable[[K.IKProblems], K.IKOutcome]] = {
        "genplan": genplan_ik, "genplan_paper_solver": genplan_paper_solver, "genplan_retries": genplan_retries}
    for name in peers:
        mod = _peer_module(name)
        if not (mod.available(placo_python) if name == "placo" else mod.available()):
            skipped[name] = mod.HINT
            print(f"peers: {name} skipped: {mod.HINT}")
            continue
        kw: dict[str, Any] = {"max_iter" if name == "ikpy" else "iterations": sizes.ik_iterations}
        if name == "placo":
            kw["placo_python"] = placo_python
        solvers[name] = functools.partial(mod.solve, **kw)
    chunks = [c for c in np.array_split(np.arange(len(pb)), max(1, min(repeats, len(pb)))) if len(c)]
    parts: dict[str, list[K.IKOutcome]] = {k: [] for k in solvers}
    for rows in chunks:
        sub = pb.take(rows)
        for k, solve in solvers.items():
            parts[k].append(solve(sub))
    return {"task": pb.task.name, "targets": len(pb), "chunks": len(chunks), "position_tol": pb.position_tol,
            "solvers": {k: K.IKOutcome.concat(v).summary() for k, v in parts.items()}}


def run_ik(sizes: Sizes, repeats: int, seed: int, placo_python: str | None) -> dict[str, Any]:
    """Panda: uniform random starts (seed 3000 + seed); Talos: starts from its shipped GAN (one
    sample per target, seed ``seed``; the sampling is not timed, for any solver)."""
    from genplan.experiments.peers import ik as K
    from genplan.projection import load_task
    from genplan.samplers.data import valid_configurations
    from genplan.samplers.gan import load_model

    from genplan.experiments.benchmarks.ik import TASKS

    out: dict[str, Any] = {"load_before": load(), "skipped": {}}
    for name, n in (("panda", sizes.ik_targets), ("talos", sizes.talos_ik_targets)):
        robot = _robot(name)
        task = load_task(TASKS[name], robot)
        valid = valid_configurations(robot, n, 2000 + seed, progress=False, task=task)
        pb = K.problems(robot, task, valid, valid)
        assert K.success(pb, valid).all(), "a target's own configuration fails the success test"
        if name == "panda":
            starts, how = robot.random_configurations(n, 3000 + seed), f"uniform (seed {3000 + seed})"
        else:
            starts, how = load_model(robot, None, task=task).sample(pb.positions, rng=seed), f"GAN (seed {seed})"
        pb = K.problems(robot, task, valid, starts)
        out[name] = {**_compare_ik(pb, IK_PEERS_FOR[name], sizes, repeats, placo_python, out["skipped"]),
                     "target_seed": 2000 + seed, "starts": how}
    out["load_after"] = load()
    return out


def run_plan(sizes: Sizes, repeats: int, seed: int) -> dict[str, Any]:
    from genplan.planning import Planner
    from genplan.planning.environments import environment

    out: dict[str, Any] = {"load_before": load()}
    panda = _robot("panda")
    env = environment(SHELF)
    worlds = {}
    for k in sizes.obstacles:
        worlds[k] = env.world(panda)
        add_extra_boxes(worlds[k], k, seed + 11)
    qs = configurations(panda, sizes.plan_check, seed)
    queries = env.queries(panda, n=sizes.plan_queries, seed=1)
    flags: dict[int, Any] = {}
    outcomes: dict[int, Any] = {}

    def check(k: int) -> float:
        t0 = time.perf_counter()
        flags[k] = np.asarray(worlds[k].in_collision(qs))
        return (time.perf_counter() - t0) / len(qs) * 1e6

    def plan(k: int) -> float:
        planner = Planner(panda, world=worlds[k], sampler="gan", seed=0)
        t0 = time.perf_counter()
        results = [planner.plan(q.start, q.goals) for q in queries]
        dt = (time.perf_counter() - t0) / len(queries) * 1e3
        outcomes[k] = [(bool(r.success), len(r.path)) for r in results]
        return dt

    sides: dict[str, Callable[[], float]] = {}
    for k in sizes.obstacles:
        sides[f"check_{k}"] = functools.partial(check, k)
    for k in sizes.obstacles:
        sides[f"plan_{k}"] = functools.partial(plan, k)
    t = interleaved(sides, repeats)
    base = sizes.obstacles[0]
    out.update({
        "obstacles": {str(k): len(w.obstacle_names) for k, w in worlds.items()},
        "check_us_per_config": {str(k): t[f"check_{k}"] for k in sizes.obstacles},
        "plan_ms_per_query": {str(k): t[f"plan_{k}"] for k in sizes.obstacles},
        "same_answers": all(np.array_equal(flags[base], flags[k]) for k in sizes.obstacles),
        "same_plans": all(outcomes[base] == outcomes[k] for k in sizes.obstacles),
        "plan_success": {str(k): sum(s for s, _ in outcomes[k]) for k in sizes.obstacles},
        "queries": len(queries), "configurations": len(qs), "threads": "rayon default (all cores)",
        "load_after": load()})
    return out


# --------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------


def _med(x: dict[str, Any]) -> float:
    return float(x["median"])


def _us(v: float) -> str:
    return f"{v:.3g} us" if v < 1000 else f"{v / 1000:.3g} ms"


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3g} ms"


def _ratio(peer: float, ours: float) -> str:
    return f"{peer / ours:.2g}x"


def summary_rows(payload: dict[str, Any]) -> list[list[str]]:
    """The issue's table: work | genplan | best peer | ratio (peer time / genplan time: > 1 means
    genplan is faster)."""
    rows: list[list[str]] = []
    fk = payload.get("fk")
    if fk:
        s = fk["panda_hand_single"]
        rows.append(["Panda hand FK, one call from Python", _us(_med(s["genplan"])), f"Pinocchio {_us(_med(s['pinocchio']))}",
                     _ratio(_med(s["pinocchio"]), _med(s["genplan"]))])
        for key, what in (("panda_hand_batch", "Panda hand FK"), ("talos_all_links_batch", f"Talos all {fk['talos_links']} link poses")):
            b = fk[key]
            for k, suffix in itertools.product(THREADS, ("", "_out")):
                g = b.get(f"genplan_{k}_thread{suffix}")
                if g:
                    into = ", into a reused out= array" if suffix else ""
                    rows.append([f"{what}, batch {fk['batch']}, genplan {k} thread(s){into}", _us(_med(g)) + "/config",
                                 f"Pinocchio loop {_us(_med(b['pinocchio_loop']))}", _ratio(_med(b["pinocchio_loop"]), _med(g))])
    col = payload.get("collision")
    if col:
        for name, what in (("panda", "Panda self + table collision"), ("talos", "Talos self-collision")):
            r = col.get(name)
            if not r:
                continue
            t = r["timings_us_per_config"]
            for k in THREADS:
                g = t.get(f"genplan_{k}_thread")
                if not g:
                    continue
                peers = {n: _med(v) for n, v in t.items() if n.startswith("coal") and
                         (n.endswith(f"_{k}_thread") or (k == 1 and n.endswith("python_loop")))}
                best = min(peers, key=lambda n: peers[n])
                rows.append([f"{what}, {r['configurations']} configs, {k} thread(s)", _us(_med(g)) + "/config",
                             f"{best.replace('_', ' ')}: {_us(peers[best])}", _ratio(peers[best], _med(g))])
            loop = t.get("coal_meshes_python_loop")
            g1 = t.get("genplan_1_thread")
            if loop and g1:
                rows.append([f"{what} vs coal's Python loop (meshes)", _us(_med(g1)) + "/config",
                             f"coal loop {_us(_med(loop))}", _ratio(_med(loop), _med(g1))])
            a = r["agreement_hulls"]
            rows.append([f"{what}: agreement with coal (same convex hulls, {a['configurations']} configs)",
                         f"{100 * a['agreement']:.3f} %", f"{len(a['disagreements'])} disagreements, max |d| "
                         f"{1e3 * a['max_distance']:.2f} mm", "-"])
    ik = payload.get("ik")
    if ik:
        for robot, what in (("panda", "Panda IK, uniform random starts"), ("talos", "Talos whole-body IK, GAN starts")):
            r = ik.get(robot)
            if not r:
                continue
            sol = r["solvers"]
            g = sol["genplan"]
            mine = f"{g['success_percent']:.1f} %, {_ms(g['ms_per_solved'])}/solved"
            for name, s in sol.items():
                if name.startswith("genplan"):
                    continue
                ratio = (f"{s['ms_per_solved'] / g['ms_per_solved']:.2g}x per solved"
                         if s["ms_per_solved"] and g["ms_per_solved"] else "-")
                rows.append([f"{what}, {r['targets']} reachable targets, vs {s['solver']}", mine,
                             f"{s['success_percent']:.1f} %, {_ms(s['ms_per_solved'])}/solved", ratio])
            peers_ran = {k: v for k, v in sol.items() if not k.startswith("genplan")}
            if not peers_ran:
                rows.append([f"{what}, {r['targets']} reachable targets", mine, "no peer ran", "-"])
            pp = sol.get("genplan_paper_solver")
            if pp:
                ratio = (f"{pp['ms_per_solved'] / g['ms_per_solved']:.2g}x per solved"
                         if pp["ms_per_solved"] and g["ms_per_solved"] else "-")
                rows.append([f"{what}, {r['targets']} reachable targets, vs genplan with the paper's solver "
                             "(line search, posture towards the start)", mine,
                             f"{pp['success_percent']:.1f} %, {_ms(pp['ms_per_solved'])}/solved", ratio])
            rr = sol.get("genplan_retries")
            if rr:
                best = max(peers_ran.values(), key=lambda s: s["success_percent"], default=None)
                ratio = (f"{best['ms_per_solved'] / rr['ms_per_solved']:.2g}x per solved"
                         if best and best["ms_per_solved"] and rr["ms_per_solved"] else "-")
                rows.append([f"{what}, {r['targets']} reachable targets, solve_ik with retries (uniform redraws, "
                             f"{1e3 * IK_RETRY_BUDGET_S:g} ms budget) vs the best peer's one start",
                             f"{rr['success_percent']:.1f} %, {_ms(rr['ms_per_solved'])}/solved",
                             f"{best['solver']} {best['success_percent']:.1f} %, {_ms(best['ms_per_solved'])}/solved" if best else "no peer ran",
                             ratio])
        for name, hint in ik.get("skipped", {}).items():
            rows.append([f"IK vs {name}", "-", f"skipped: {hint}", "-"])
    plan = payload.get("plan")
    if plan:
        ks = list(plan["check_us_per_config"])
        c0, p0 = _med(plan["check_us_per_config"][ks[0]]), _med(plan["plan_ms_per_query"][ks[0]])
        for k in ks[1:]:
            c, p = _med(plan["check_us_per_config"][k]), _med(plan["plan_ms_per_query"][k])
            rows.append([f"Panda shelf + {k} extra boxes (vs + {ks[0]})",
                         f"check {c0:.3g} -> {c:.3g} us; GAN plan {p0:.3g} -> {p:.3g} ms", "-",
                         f"check {c / c0:.2f}x, plan {p / p0:.2f}x"])
    return rows


def detail_rows(payload: dict[str, Any]) -> list[list[str]]:
    """Every measured setup: section, setup, median, repeats."""
    rows = []
    for sec, key in (("fk", "panda_hand_single"), ("fk", "panda_hand_batch"), ("fk", "talos_all_links_batch")):
        for side, v in payload.get(sec, {}).get(key, {}).items():
            rows.append([f"fk {key}", side, f"{_med(v):.3g} us", " ".join(f"{x:.3g}" for x in v["all"])])
    for name, r in payload.get("collision", {}).items():
        for side, v in r["timings_us_per_config"].items():
            rows.append([f"collision {name}", side, f"{_med(v):.3g} us", " ".join(f"{x:.3g}" for x in v["all"])])
    for sec in ("panda", "talos"):
        for name, s in payload.get("ik", {}).get(sec, {}).get("solvers", {}).items():
            rows.append([f"ik {sec}", name, f"{s['success_percent']:.1f} % / {s['ms_per_problem']:.3g} ms per problem",
                         s["note"]])
    plan = payload.get("plan")
    if plan:
        for k, v in plan["check_us_per_config"].items():
            rows.append(["plan check", f"+{k} boxes", f"{_med(v):.3g} us", " ".join(f"{x:.3g}" for x in v["all"])])
        for k, v in plan["plan_ms_per_query"].items():
            rows.append(["plan GAN", f"+{k} boxes", f"{_med(v):.3g} ms", " ".join(f"{x:.3g}" for x in v["all"])])
    return rows


def markdown(payload: dict[str, Any]) -> str:
    m = payload["machine"]
    lines = [f"# genplan bench peers ({m['git']}, {m['date']})", "",
             f"Command: `{payload['command']}`  ",
             f"Machine: {m['cpu']}, {m['cores']} cores; load (1 min) {payload['load_before']:.2f} -> "
             f"{payload['load_after']:.2f}; repeats {payload['repeats']} (after one warm-up call per side; sides interleaved, medians); "
             "genplan batched calls in workers with RAYON_NUM_THREADS 1 and 2, single calls and peers on one thread.",
             "", "Ratio: the peer's time / genplan's (> 1: genplan is faster).", "",
             table(["work", "genplan", "best peer", "ratio"], summary_rows(payload)), "",
             "## Every setup", "", table(["section", "setup", "median", "repeats"], detail_rows(payload)), ""]
    if payload.get("skipped"):
        lines += ["Skipped: " + "; ".join(f"{k}: {v}" for k, v in payload["skipped"].items()), ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# command
# --------------------------------------------------------------------------------------------


def sections(text: str) -> list[str]:
    parts = [p.strip() for p in text.split(",") if p.strip()]
    bad = [p for p in parts if p not in SECTIONS]
    if bad or not parts:
        raise argparse.ArgumentTypeError(f"expected a comma-separated subset of {','.join(SECTIONS)}, got '{text}'")
    return parts


def run(only: list[str], sizes: Sizes, repeats: int, seed: int, placo_python: str | None = None) -> dict[str, Any]:
    from genplan._threads import torch_threads

    payload: dict[str, Any] = {"benchmark": "peers", "machine": machine(), "repeats": repeats, "seed": seed,
                               "sizes": asdict(sizes), "load_before": load(), "skipped": {},
                               "threads": {"genplan_batched": "worker processes with RAYON_NUM_THREADS 1 and 2",
                                           "genplan_single_calls_and_ik": 1, "pinocchio_loops_and_ik_peers": 1,
                                           "torch": 1, "coal_batches": "as named (computeCollisionsInParallel)",
                                           "plan_section": "rayon default (every core)"}}
    t0 = time.perf_counter()
    with torch_threads("small", 1):
        if {"fk", "collision"} & set(only):
            with workers(THREADS) as pools:
                if "fk" in only:
                    payload["fk"] = run_fk(sizes, repeats, seed, pools)
                if "collision" in only:
                    payload["collision"] = run_collision(sizes, repeats, seed, pools)
        if "ik" in only:
            payload["ik"] = run_ik(sizes, repeats, seed, placo_python)
            payload["skipped"].update(payload["ik"]["skipped"])
        if "plan" in only:
            payload["plan"] = run_plan(sizes, repeats, seed)
    payload["load_after"] = load()
    payload["wall_s"] = time.perf_counter() - t0
    return payload


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--only", type=sections, default=list(SECTIONS),
                   help=f"sections to run, comma-separated (default all: {','.join(SECTIONS)})")
    p.add_argument("--quick", action="store_true", help="small sizes (a smoke run; the figures mean little)")
    p.add_argument("--repeats", type=A.positive_int, default=5, help="repeats per figure, sides interleaved (default 5)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--placo-python", default=None,
                   help="a Python with placo installed (placo pins pin==3.8; default $GENPLAN_PLACO_PYTHON)")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")
    p.add_argument("--markdown", type=A.output_file, default=None, help="write the tables as markdown")


def main(args: argparse.Namespace) -> int:
    import sys

    sizes = QUICK if args.quick else Sizes()
    payload = run(args.only, sizes, args.repeats, args.seed, args.placo_python)
    payload["command"] = "genplan " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["bench"] else "genplan bench peers"
    print(table(["work", "genplan", "best peer", "ratio"], summary_rows(payload)))
    write_json(args.out, payload)
    if args.markdown is not None:
        write_text(args.markdown, markdown(payload))
        print(f"wrote {args.markdown}")
    return 0


__all__ = ["QUICK", "SECTIONS", "Sizes", "add_extra_boxes", "coal_model", "collision_world", "markdown", "run",
           "summary_rows"]
