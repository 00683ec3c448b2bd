"""The sphere checker against the exact one: the Panda in the shelf scene, one
core (``RAYON_NUM_THREADS=1``, set before genplan is imported), every measurement in alternating
rounds so that both arms see the same load.

    python benches/sphere_checker.py --configs 100000 --rounds 5 --queries 20 --out benches/results/sphere_checker.json

* ``cover``: ``--configs`` uniform configurations checked by both: how many the exact world finds
  in collision that the spheres call free (``missed``, must be 0) and the false positives (in
  collision by the spheres, free by the exact geometry) as a share of the exact world's free ones;
* ``checks``: configurations per second, exact vs spheres, one call per configuration from Python
  (``single``) and one call for 10,000 (``batch``); per arm the median over rounds, and the ratio;
* ``vamp`` (when ``import vamp`` works: the peer, never a dependency): ``vamp.panda.validate`` on
  the same scene (its boxes as VAMP cuboids, the floor as a thin box), one call per
  configuration, in the same rounds, and its own spherised Panda's answers against the exact
  world's;
* ``plans``: free-space plans (``task="free"``, RRT-Connect) between ``--queries`` pairs of
  collision-free configurations (benches/free_space_plan.py's), each planned with the exact and
  the sphere checker, the same sampler seed: success, median plan time (``stats.time_s``) per
  arm, the ratio of the medians and the median per-query ratio, the checker's share of the time.
"""

from __future__ import annotations

import os

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import genplan  # noqa: E402
from genplan import _core  # noqa: E402
from genplan.experiments.common import machine, write_json  # noqa: E402
from genplan.planning import PlannerSettings, environment, sphere_checker  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from free_space_plan import queries  # noqa: E402


def vamp_env(scene: Any) -> Any:
    """The scene's boxes as a VAMP environment (axis-aligned ones only), half-spaces as thin boxes
    under their plane; None when VAMP is not installed or a shape has no VAMP twin."""
    try:
        import vamp
    except ImportError:
        return None
    env = vamp.Environment()
    for s in scene.obstacles:
        kind = type(s).__name__
        if kind == "Box" and np.allclose(s.pose.matrix(), np.eye(3)):
            env.add_cuboid(vamp.Cuboid(list(map(float, s.pose.position)), [0.0, 0.0, 0.0], list(map(float, s.half_extents))))
        elif kind == "HalfSpace" and np.allclose(np.asarray(s.normal) / np.linalg.norm(s.normal), [0, 0, 1]):
            z = float(s.offset)
            env.add_cuboid(vamp.Cuboid([0.0, 0.0, z - 0.05], [0.0, 0.0, 0.0], [10.0, 10.0, 0.05]))
        else:
            return None
    return env


def rate(fn: Any, n: int) -> float:
    t = time.perf_counter()
    fn()
    return n / (time.perf_counter() - t)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--configs", type=int, default=100_000)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--single", type=int, default=20_000, help="configurations per round of one-at-a-time calls")
    p.add_argument("--queries", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    robot = genplan.load("panda")
    env = environment("panda_shelf")
    world = env.world(robot)
    t0 = time.perf_counter()
    sc = sphere_checker(robot, world)
    setup_s = time.perf_counter() - t0
    load0 = os.getloadavg()
    t_start = time.time()
    rng = np.random.default_rng(args.seed)

    # the cover
    qs = robot.random_configurations(args.configs, rng)
    exact = np.asarray(world.in_collision(qs), dtype=bool)
    spheres = np.asarray(sc.in_collision(qs), dtype=bool)
    missed = int(np.sum(exact & ~spheres))
    fp = int(np.sum(spheres & ~exact))
    cover = dict(configs=len(qs), exact_in_collision=int(exact.sum()), spheres_in_collision=int(spheres.sum()),
                 missed=missed, false_positives=fp, false_positive_rate=fp / max(1, int((~exact).sum())),
                 spheres=sc.n_spheres, self_link_pairs=len(sc.self_pairs))

    vam = vamp_env(env.scene)
    vamp_cover = None
    if vam is not None:
        import vamp

        vq = qs[:20_000].astype(np.float32)
        vvalid = np.array([vamp.panda.validate(q, vam) for q in vq])
        vamp_cover = dict(configs=len(vq), missed_vs_exact=int(np.sum(exact[:len(vq)] & vvalid)),
                          in_collision=int((~vvalid).sum()), exact_in_collision=int(exact[:len(vq)].sum()))

    # checks per second, alternating
    batch = qs[:10_000].copy()
    single = qs[: args.single].copy()
    single32 = single.astype(np.float32)
    arms: dict[str, Any] = {
        "exact_single": (lambda: [world.in_collision(q) for q in single], len(single)),
        "spheres_single": (lambda: [sc.in_collision(q) for q in single], len(single)),
        "exact_batch": (lambda: world.in_collision(batch), len(batch)),
        "spheres_batch": (lambda: sc.in_collision(batch), len(batch)),
    }
    if vam is not None:
        import vamp

        arms["vamp_single"] = (lambda: [vamp.panda.validate(q, vam) for q in single32], len(single))
    rates: dict[str, list[float]] = {a: [] for a in arms}
    names = list(arms)
    for r in range(args.rounds):
        for a in (names if r % 2 == 0 else names[::-1]):
            fn, n = arms[a]
            rates[a].append(rate(fn, n))
    med = {a: float(np.median(v)) for a, v in rates.items()}
    checks = dict(rounds=args.rounds, per_second_median=med, per_second=rates,
                  ratio_single=med["spheres_single"] / med["exact_single"],
                  ratio_batch=med["spheres_batch"] / med["exact_batch"])
    if vam is not None:
        checks["spheres_single_over_vamp_single"] = med["spheres_single"] / med["vamp_single"]
        checks["spheres_batch_over_vamp_single"] = med["spheres_batch"] / med["vamp_single"]

    # free-space plans, alternating
    pairs = queries(robot, sc, args.queries, args.seed)
    native = _core.Planner(robot.kinematics, PlannerSettings(algorithm="rrt_connect"))
    plan_arms = {"exact": world.native, "spheres": sc}
    times: dict[str, list[list[float]]] = {a: [[] for _ in pairs] for a in plan_arms}
    share: dict[str, list[float]] = {a: [] for a in plan_arms}
    ok = {a: 0 for a in plan_arms}
    for r in range(args.rounds):
        for i, (a, b) in enumerate(pairs):
            order = list(plan_arms) if (r + i) % 2 == 0 else list(plan_arms)[::-1]
            for arm in order:
                sampler = _core.UniformSampler(robot.kinematics, None, args.seed + i, None)
                res = native.plan(list(map(float, a)), b[None], sampler, None, plan_arms[arm], False, None)
                times[arm][i].append(res.stats.time_s)
                if r == 0:
                    ok[arm] += int(res.success)
                    if res.stats.time_s > 0:
                        share[arm].append(res.stats.checker_s / res.stats.time_s)
                    if arm == "spheres" and res.success:
                        assert not np.asarray(world.in_collision(res.path)).any(), "a sphere plan's path collides"
    pm = {a: float(np.median([t for ts in times[a] for t in ts])) for a in plan_arms}
    per_query = [np.median(times["exact"][i]) / np.median(times["spheres"][i]) for i in range(len(pairs))]
    plans = dict(algorithm="rrt_connect", queries=len(pairs), rounds=args.rounds, success=ok,
                 median_ms={a: 1e3 * v for a, v in pm.items()}, ratio_of_medians=pm["exact"] / pm["spheres"],
                 median_per_query_ratio=float(np.median(per_query)),
                 checker_share_median={a: float(np.median(v)) if v else None for a, v in share.items()})
    load1 = os.getloadavg()

    print(f"cover: {cover['configs']} configurations, {cover['exact_in_collision']} in collision (exact), "
          f"missed {missed}, false positives {fp} ({100 * cover['false_positive_rate']:.2f} % of the free ones)")
    if vamp_cover:
        print(f"vamp cover: {vamp_cover}")
    for a, v in med.items():
        print(f"{a:<16} {v / 1e6:8.3f} M/s")
    print(f"spheres / exact: single {checks['ratio_single']:.2f}x, batch {checks['ratio_batch']:.2f}x")
    print(f"plans: success {ok}, median ms {plans['median_ms']}, exact / spheres {plans['ratio_of_medians']:.2f}x "
          f"(per query {plans['median_per_query_ratio']:.2f}x), checker share {plans['checker_share_median']}")
    print(f"load average (1 min) {load0[0]:.2f} at the start, {load1[0]:.2f} at the end")
    payload = dict(benchmark="sphere_checker", env="panda_shelf", seed=args.seed, threads=1, setup_s=setup_s,
                   cover=cover, vamp_cover=vamp_cover, checks=checks, plans=plans, wall_s=time.time() - t_start,
                   load_1min_start=load0[0], load_1min_end=load1[0], machine=machine())
    write_json(args.out, payload)


if __name__ == "__main__":
    main()
