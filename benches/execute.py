"""The 1 kHz loop on every robot: the cost of one tick, and what the disturbance
observer buys on the Panda's shelf plans.

    python benches/execute.py --plans 20 --out benches/results/execute.json

1. **Ticks.** Per robot, a 2 s motion (a smooth joint motion about the robot's default
   configuration: 0.25 of its speed limits' reach, in phase per joint) executed unpaced
   ``--repeats`` times with joint friction, offsets and an unknown payload in the plant; the
   median and the best wall time of the loop per tick (controller + plant RK4 + observer +
   logging) over the runs, how much faster than real time the median is, and the median over
   the runs of each run's median tick compute time (a tick preempted by another job moves the
   wall time, not this median). The configurations take turns (one run each per round), so a
   load that changes while the bench runs reaches every row alike. The load average while
   timing is recorded: on a shared machine the wall times follow the other jobs. Rows: the UR5
   in the seq2seq paper's spatula configuration (task space on the spatula point, eq. 23, the
   pancake), every fixed-base robot of ``genplan bench robots`` in task space on its tool frame
   (a redundant arm: the damped pseudo-inverse and the null-space posture term), and the
   7-joint Panda in joint space.
2. **The observer on 20 Panda shelf plans.** The Table II protocol's queries of
   ``panda_shelf`` (seed ``--seed``), planned with the shipped GAN and shortcuts, timed by
   ``PlanResult.trajectory()`` (TOPP-RA, 1 kHz), executed in the task space of the hand (full
   pose), and in joint space, after 0.5 s holding the start, with and without the observer, under the plant
   deviations :data:`DEVIATIONS`: an unknown 0.6 kg load 10 cm in front of the hand (20 % of the
   Panda's rated 3 kg), Coulomb and viscous friction and a torque offset on every joint. Per
   plan: the hand's largest position and attitude error, the largest torque / limit, ticks over
   a limit, the task's largest residual along the executed path (and the plan's own), and a
   collision check of the executed motion against the shelf. Target: the largest error with the
   observer at most a third of without, torques within limits.

Times depend on the machine and its load (recorded in the JSON); the errors are deterministic.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Callable, Literal

import numpy as np

import genplan
from genplan import control
from genplan.control import ControllerSettings, Disturbances, JointLimits, Payload
from genplan.experiments.benchmarks.robots import ROBOTS
from genplan.experiments.common import machine, table, write_json

#: the Panda's plant deviations of part 2 (per joint: Coulomb N m, viscous N m s/rad, offset N m)
DEVIATIONS = {
    "payload": {"link": "panda_hand", "mass": 0.6, "com": [0.0, 0.0, 0.1]},
    "coulomb": [1.5, 1.5, 1.5, 1.5, 0.3, 0.3, 0.3],
    "viscous": [1.0, 1.0, 1.0, 1.0, 0.2, 0.2, 0.2],
    "offset": [0.8, -0.8, 0.6, -0.6, 0.15, -0.15, 0.1],
}


def panda_deviations() -> Any:
    d = DEVIATIONS
    return Disturbances(coulomb=d["coulomb"], viscous=d["viscous"], offset=d["offset"], payload=Payload(**d["payload"]))


def generic_deviations(robot: Any) -> Any:
    """Friction 1 % and an offset 0.5 % of each joint's rated torque, a 0.5 kg unknown payload
    at the tool frame: the tick's work, whatever the robot."""
    effort = np.minimum(np.asarray(robot.model.effortLimit, dtype=np.float64), 200.0)
    return Disturbances(coulomb=(0.01 * effort).tolist(), viscous=(0.005 * effort).tolist(),
                        offset=(0.005 * effort).tolist(), payload=Payload(mass=0.5))


#: candidate centres of a bench motion besides the default configuration (seeded)
CENTRE_CANDIDATES = 64
#: the smallest singular value of the tool frame's Jacobian below which the default
#: configuration is too near a singularity to swing about
SINGULAR = 0.05


def centre(robot: Any, seed: int = 0) -> np.ndarray:
    """The configuration a bench motion swings about: the default configuration, unless its tool
    frame's Jacobian has a smallest singular value below SINGULAR; then, of CENTRE_CANDIDATES
    seeded random ones, the one whose smallest singular value is largest. A default at a singularity (a stretched UR or xArm arm) would have
    the task-space controller's damped solve and its rounding-sensitive branch run on every tick,
    which is not the tick a user's motion costs."""
    import pinocchio as pin

    frame = robot.frame_id(control.tool_frame(robot))
    data = robot.model.createData()
    qs = np.vstack([np.asarray(robot.normalize(robot.q_default))[None, :],
                    robot.random_configurations(CENTRE_CANDIDATES, seed)])

    def sigma_min(q: np.ndarray) -> float:
        j = pin.computeFrameJacobian(robot.model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
        return float(np.linalg.svd(j, compute_uv=False)[-1])

    if sigma_min(qs[0]) >= SINGULAR:
        return qs[0]
    return qs[int(np.argmax([sigma_min(q) for q in qs]))]


def motion(robot: Any, seconds: float = 2.0, rate: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """(t, q): a smooth motion about :func:`centre` (a joint whose centre is outside its range:
    about the range's middle), each joint swinging up to a quarter of what its speed limit reaches
    in the period, and within its limits."""
    x0 = control.joint_values(robot, centre(robot)[None, :])[0]
    vmax = np.asarray(robot.model.velocityLimit, dtype=np.float64)
    w = 2.0 * np.pi / seconds
    amplitude = 0.25 * vmax / w
    for k in range(robot.nv):
        lo, hi = _range(robot, k)
        if not lo <= x0[k] <= hi:  # a default configuration outside the range: its middle
            x0[k] = 0.5 * (lo + hi)
        amplitude[k] = max(0.0, min(amplitude[k], 0.9 * (x0[k] - lo), 0.9 * (hi - x0[k])))
    t = np.arange(int(round(seconds * rate)) + 1) / rate
    x = x0 + amplitude * (np.sin(w * t) * np.sin(w * t / 2.0))[:, None]
    return t, control.from_joint_values(robot, x)


def _range(robot: Any, k: int) -> tuple[float, float]:
    """The position range of joint k (v order; unbounded for a continuous joint)."""
    qi = robot.model.joints[k + 1].idx_q
    if qi in robot.continuous:
        return -math.inf, math.inf
    return float(robot.lower[qi]), float(robot.upper[qi])


def tick_configurations() -> list[tuple[dict[str, Any], Callable[[], Any]]]:
    """Each timed configuration: its row's description and a call running it once (its log)."""
    from genplan.pancake import control as pc
    from genplan.pancake.trajectories import s_curve

    arm = pc.SpatulaArm(disturbances=pc.reference_disturbances(), settle=0.5)
    x = s_curve([0.0, 0.0, 0.0], [0.05, 0.02, -0.4], K=1500)
    out: list[tuple[dict[str, Any], Callable[[], Any]]] = [
        ({"robot": "ur5", "configuration": "spatula (eq. 23, pancake)", "joints": 6}, lambda: arm.execute(x))]
    for name, load in ROBOTS.items():
        robot = load()
        if robot.floating_base:
            continue
        t, q = motion(robot)
        spaces: list[Literal["task", "joint"]] = ["task", "joint"] if name == "panda" else ["task"]
        for space in spaces:
            def run(robot: Any = robot, t: Any = t, q: Any = q, ctrl: Any = ControllerSettings(space=space)) -> Any:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", control.LimitWarning)
                    return control.execute(robot, (t, q), controller=ctrl, disturbances=generic_deviations(robot),
                                           settle=0.0)
            out.append(({"robot": name, "space": space, "joints": robot.nv}, run))
    return out


def tick_rows(repeats: int) -> list[dict[str, Any]]:
    """The rows of part 1. The configurations take turns, one run each per round, so that a load
    that changes during the bench reaches every row alike (one configuration's runs after
    another's compared different loads). Per run: the loop's wall time per tick (the mean: a tick
    preempted by another job counts whole) and the median of the ticks' own compute times, which
    such ticks do not move."""
    configurations = tick_configurations()
    us: list[list[float]] = [[] for _ in configurations]
    compute: list[list[float]] = [[] for _ in configurations]
    last: list[Any] = [None] * len(configurations)
    for _ in range(repeats):
        for i, (_, run) in enumerate(configurations):
            log = last[i] = run()
            us[i].append(log.us_per_tick)
            compute[i].append(1e6 * float(np.median(log.compute)))
    rows = []
    for (row, _), log, wall, tick in zip(configurations, last, us, compute):
        configuration = row.get("configuration") or f"{row['space']} space on {log.meta['frame']}"
        row = {"robot": row["robot"], "configuration": configuration, "joints": row["joints"], "ticks": len(log.t),
               "us_per_tick": statistics.median(wall), "us_per_tick_runs": wall, "us_per_tick_min": min(wall),
               "realtime_factor": 1e3 / statistics.median(wall), "compute_us_median": statistics.median(tick),
               "compute_us_runs": tick}
        if row["configuration"].startswith(("task", "joint")):
            row["max_error_mm"] = log.max_tracking_error_mm
        rows.append(row)
    return rows


#: the controllers of part 2: the paper's P-D + observer in the task space of the hand (full
#: pose; the redundant Panda's posture in the null space), and in joint space
CONTROLLERS = {"task": ControllerSettings(frame="hand"), "joint": ControllerSettings(frame="hand", space="joint")}


def run_plan(panda: Any, traj: Any, controller: Any, world: Any, task: Any) -> dict[str, Any]:
    """One plan with and without the observer: the errors, torques, limits, residuals, collisions."""
    out: dict[str, Any] = {}
    for dob in (True, False):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            log = control.execute(panda, traj, controller=controller.replace(dob=dob), disturbances=panda_deviations(),
                                  limits=JointLimits(), world=world, task=task)
        ratio = max(log.residuals[k] / log.tolerances[k] for k in log.residuals)
        out["dob" if dob else "no_dob"] = {
            "max_error_mm": log.max_tracking_error_mm, "max_error_deg": log.max_tracking_error_deg,
            "rms_error_mm": 1e3 * log.summary["rms_error_position"],
            "max_joint_error_deg": math.degrees(log.max_joint_error),
            "max_torque_ratio": log.summary["max_torque_ratio"], "limit_ticks": log.summary["limit_ticks"],
            "saturated_ticks": log.summary["saturated_ticks"], "max_velocity_ratio": log.summary["max_velocity_ratio"],
            "first_limit": log.limit_violation, "residual_ratio": ratio, "residuals": log.residuals,
            "collision_ticks": int(log.in_collision.sum()) if log.in_collision is not None else 0,
            "us_per_tick": log.us_per_tick, "warnings": [str(w.message) for w in caught],
        }
    out["error_ratio"] = out["no_dob"]["max_error_mm"] / out["dob"]["max_error_mm"]
    out["error_ratio_deg"] = out["no_dob"]["max_error_deg"] / out["dob"]["max_error_deg"]
    return out


def plan_rows(plans: int, seed: int) -> list[dict[str, Any]]:
    from genplan.planning import Planner, PlannerSettings, environment

    panda = genplan.load("panda")
    env = environment("panda_shelf")
    world = env.world(panda)
    planner = Planner(panda, world=world, sampler="gan", settings=PlannerSettings(simplify=True), seed=seed)
    rows = []
    for i, query in enumerate(env.queries(panda, n=plans, seed=seed)):
        res = planner.plan(query.start, query.goals)
        if not res.success:
            rows.append({"query": i, "planned": False})
            continue
        traj = res.trajectory()
        row: dict[str, Any] = {"query": i, "planned": True, "duration_s": traj.duration, "samples": len(traj),
                               "plan_residual_ratio": traj.max_residual_ratio}
        for name, controller in CONTROLLERS.items():
            row[name] = run_plan(panda, traj, controller, world, res.task)
        rows.append(row)
    return rows


def summarize(done: list[dict[str, Any]], name: str) -> dict[str, Any]:
    r = [row[name] for row in done]
    ratios = [x["error_ratio"] for x in r]
    return {
        "planned": len(done), "error_ratio_min": min(ratios), "error_ratio_median": statistics.median(ratios),
        "plans_at_least_3x": sum(x >= 3.0 for x in ratios),
        "max_error_mm_dob": max(x["dob"]["max_error_mm"] for x in r),
        "max_error_mm_no_dob": max(x["no_dob"]["max_error_mm"] for x in r),
        "max_error_deg_dob": max(x["dob"]["max_error_deg"] for x in r),
        "max_error_deg_no_dob": max(x["no_dob"]["max_error_deg"] for x in r),
        "max_torque_ratio_dob": max(x["dob"]["max_torque_ratio"] for x in r),
        "max_torque_ratio_no_dob": max(x["no_dob"]["max_torque_ratio"] for x in r),
        "torque_limit_ticks": sum(x[k]["saturated_ticks"] for x in r for k in ("dob", "no_dob")),
        "limit_ticks_dob": sum(x["dob"]["limit_ticks"] for x in r),
        "limit_ticks_no_dob": sum(x["no_dob"]["limit_ticks"] for x in r),
        "max_velocity_ratio_dob": max(x["dob"]["max_velocity_ratio"] for x in r),
        "max_residual_ratio_dob": max(x["dob"]["residual_ratio"] for x in r),
        "max_residual_ratio_no_dob": max(x["no_dob"]["residual_ratio"] for x in r),
        "max_plan_residual_ratio": max(row["plan_residual_ratio"] for row in done),
        "collision_ticks_dob": sum(x["dob"]["collision_ticks"] for x in r),
        "collision_ticks_no_dob": sum(x["no_dob"]["collision_ticks"] for x in r),
        "plans_colliding_dob": sum(x["dob"]["collision_ticks"] > 0 for x in r),
        "plans_colliding_no_dob": sum(x["no_dob"]["collision_ticks"] > 0 for x in r),
    }


def criterion_ticks() -> dict[str, Any]:
    """The last criterion medians (us) of ``control_tick/*`` (wall time) and ``control_tick_cpu/*``
    (the thread's CPU time) of ``cargo bench -p genplan-core --bench control``, if any are in
    ``target/criterion``."""
    import json

    root = Path(__file__).resolve().parents[1] / "target" / "criterion"
    out = {}
    for est in sorted(root.glob("control_tick*/new/estimates.json")):
        out[est.parent.parent.name] = json.loads(est.read_text())["median"]["point_estimate"] / 1e3
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plans", type=int, default=20, help="Panda shelf plans (default 20; 0: ticks only)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per robot (default 5)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    t0 = time.perf_counter()
    ticks = tick_rows(max(1, args.repeats))
    load = os.getloadavg()
    print(table(["robot", "controller", "joints", "us / tick (median)", "us / tick (best)", "x real time (median)",
                 "tick compute us (median)"],
                [[r["robot"], r["configuration"], r["joints"], r["us_per_tick"], r["us_per_tick_min"],
                  r["realtime_factor"], r["compute_us_median"]] for r in ticks]))
    print(f"load average while timing (1, 5, 15 min): {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} on "
          f"{os.cpu_count()} cores")
    crit = criterion_ticks()
    if crit:
        print("criterion medians (us): " + ", ".join(f"{k} {v:.2f}" for k, v in crit.items()))
    plans = plan_rows(args.plans, args.seed) if args.plans > 0 else []
    done = [r for r in plans if r["planned"]]
    summaries = {}
    for name in CONTROLLERS if done else ():
        print(f"{name} space, the hand: max error with / without the observer")
        print(table(["query", "s", "mm DOB", "mm no DOB", "ratio", "deg DOB", "deg no DOB", "torque/limit",
                     "speed/limit", "residual/tol DOB", "collision ticks DOB / no"],
                    [[r["query"], r["duration_s"], r[name]["dob"]["max_error_mm"], r[name]["no_dob"]["max_error_mm"],
                      r[name]["error_ratio"], r[name]["dob"]["max_error_deg"], r[name]["no_dob"]["max_error_deg"],
                      max(r[name]["dob"]["max_torque_ratio"], r[name]["no_dob"]["max_torque_ratio"]),
                      max(r[name]["dob"]["max_velocity_ratio"], r[name]["no_dob"]["max_velocity_ratio"]),
                      r[name]["dob"]["residual_ratio"],
                      f"{r[name]['dob']['collision_ticks']} / {r[name]['no_dob']['collision_ticks']}"] for r in done]))
        s = summaries[name] = summarize(done, name)
        print(f"{name} space: {s['planned']} of {len(plans)} planned; error ratio without / with the observer: min "
              f"{s['error_ratio_min']:.2f}, median {s['error_ratio_median']:.2f} ({s['plans_at_least_3x']} plans >= 3x); "
              f"largest error over the plans {s['max_error_mm_dob']:.2f} mm with, {s['max_error_mm_no_dob']:.2f} mm "
              f"without; largest torque / limit {s['max_torque_ratio_dob']:.2f} with, {s['max_torque_ratio_no_dob']:.2f} "
              f"without")
    payload = {"benchmark": "execute", "machine": machine(), "seconds": time.perf_counter() - t0,
               "command": " ".join(["python", *sys.argv]), "load_average": list(load), "ticks": ticks, "criterion_us": crit,
               "plans": {"environment": "panda_shelf", "seed": args.seed, "sampler": "gan", "simplify": True,
                         "controllers": {k: v.to_dict() for k, v in CONTROLLERS.items()}, "deviations": DEVIATIONS,
                         "settle_s": control.SETTLE_S, "rows": plans, "summary": summaries}}
    write_json(args.out, payload)


if __name__ == "__main__":
    main()
