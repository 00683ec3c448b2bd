"""Baxter carrying a tray in both hands among two boxes kept 2 cm away (examples/baxter), planned
as a user types it and every trajectory sample checked independently with Pinocchio + coal.

    python benches/baxter_tray.py [--queries 20] [--sampler uniform|gan ...] [--model F.safetensors]
                                  [--out benches/results/baxter_tray.json]

Query ``i`` (seed ``i``) draws a start and a goal target for the left gripper uniformly in the
task's [condition] box and runs, in this process, the command

    genplan plan --robot examples/baxter/baxter_tray.toml --task examples/baxter/tray.toml \\
        --scene examples/baxter/two_boxes.toml --start-target SX SY SZ --target GX GY GZ \\
        --seed i --out plan.json --trajectory plan.npz

(``genplan.cli.main``: the same argument parsing, IK, planning, TOPP-RA and checks). A target
with no collision-free IK solution (the tray inside a box, say) exits with status 2 and the query
draws again from its own generator (at most ``--redraws`` times; counted). The trajectory file it
writes is then read back and every 1 kHz sample is checked with a model built here from the files
alone, not genplan's: Pinocchio's URDF model (the robot file's locked joints at their neutral
value) and coal's geometry of the URDF's collision shapes, the robot file's attached tray on the
left gripper and the scene file's boxes:

* clearance: coal's distance from every robot geometry and the tray to each box (>= the box's
  padding: 2 cm; a geometry no active joint moves, the torso's, once);
* self-collision: every geometry pair the SRDF does not disable, on distinct rigid bodies (the
  tray: against everything but the two wrists' bodies, which hold it), in contact or not;
* limits: every sample's joint positions within the URDF's limits with no tolerance, and |qd|
  against the URDF's velocity limits;
* the tray: the right gripper's position and orientation in the left gripper's frame against
  tray.toml's target, and the angle of the left gripper's z axis from straight down.

Writes the JSON (per query and the summary) and prints the table; the load average before and
after is recorded. Torch is not used; RAYON_NUM_THREADS is left to the caller.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import platform
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "baxter"
ROBOT, TASK, SCENE = EXAMPLES / "baxter_tray.toml", EXAMPLES / "tray.toml", EXAMPLES / "two_boxes.toml"


def rel(path: Path) -> str:
    """``path`` as a user in the repository's root types it."""
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


class Oracle:
    """The independent model: Pinocchio + coal from the URDF, SRDF, robot, task and scene files."""

    def __init__(self, urdf: Path, srdf: Path, package_dirs: list[str]) -> None:
        import coal
        import pinocchio as pin

        self.pin, self.coal = pin, coal
        robot_file = tomllib.loads(ROBOT.read_text())
        task_file = tomllib.loads(TASK.read_text())
        scene_file = tomllib.loads(SCENE.read_text())
        full = pin.buildModelFromUrdf(str(urdf))
        geom_full = pin.buildGeomFromUrdf(full, str(urdf), pin.GeometryType.COLLISION, package_dirs)
        q_lock = pin.neutral(full)
        locked = []
        for name in robot_file["locked_joints"]:  # at 0, or the middle of its range where 0 is outside it
            jid = full.getJointId(name)
            iq = full.joints[jid].idx_q
            lo, hi = full.lowerPositionLimit[iq], full.upperPositionLimit[iq]
            q_lock[iq] = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
            locked.append(jid)
        self.model, geoms = pin.buildReducedModel(full, [geom_full], locked, q_lock)
        self.robot_geom = geoms[0]
        self.data = self.model.createData()
        self.joint_names = [self.model.names[j] for j in range(1, self.model.njoints)]
        # the tray, on the frame of the link that holds it
        (tray,) = robot_file["attached"]
        frame = self.model.frames[self.model.getFrameId(tray["link"])]
        offset = pin.SE3(np.eye(3), np.array(tray["position"], dtype=float))
        self.tray_index = self.robot_geom.addGeometryObject(pin.GeometryObject(
            "tray", frame.parentJoint, frame.parentFrame, frame.placement * offset, coal.Box(*tray["box"]["size"])))
        self.holders = {frame.parentJoint, self.model.frames[self.model.getFrameId(tray["touch_links"][0])].parentJoint}
        # self pairs: all, less the SRDF's, less pairs on one rigid body, less the tray's holders
        self.robot_geom.addAllCollisionPairs()
        pin.removeCollisionPairs(self.model, self.robot_geom, str(srdf))
        for k in reversed(range(len(self.robot_geom.collisionPairs))):
            p = self.robot_geom.collisionPairs[k]
            a, b = (self.robot_geom.geometryObjects[i] for i in (p.first, p.second))
            tray_held = "tray" in (a.name, b.name) and (a.parentJoint if b.name == "tray" else b.parentJoint) in self.holders
            if a.parentJoint == b.parentJoint or tray_held:
                self.robot_geom.removeCollisionPair(p)
        self.self_pairs = len(self.robot_geom.collisionPairs)
        self.robot_data = pin.GeometryData(self.robot_geom)
        # the boxes, with their padding, in a geometry model of their own with the robot's
        # geometries: the pairs (robot geometry or tray, box), their distances in one call; the
        # geometries fixed to the base (torso, pedestal, head: no active joint moves them) are at
        # one distance from the fixed boxes, measured once (static_clearance_m)
        self.clear_geom = pin.GeometryModel()
        for g in self.robot_geom.geometryObjects:
            self.clear_geom.addGeometryObject(g)
        robot_count = len(self.robot_geom.geometryObjects)
        self.boxes: list[tuple[str, int, float]] = []
        for b in scene_file["box"]:
            placement = pin.SE3(np.eye(3), np.array(b["position"], dtype=float))
            index = self.clear_geom.addGeometryObject(pin.GeometryObject(b["name"], 0, 0, placement, coal.Box(*b["size"])))
            self.boxes.append((b["name"], index, float(b.get("padding", 0.0))))
            for g in range(robot_count):
                self.clear_geom.addCollisionPair(pin.CollisionPair(g, index))
        self.clear_data = pin.GeometryData(self.clear_geom)
        pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
        pin.computeDistances(self.model, self.data, self.clear_geom, self.clear_data, pin.neutral(self.model))
        self.static_clearance: dict[str, tuple[float, str]] = {}
        for k in reversed(range(len(self.clear_geom.collisionPairs))):
            p = self.clear_geom.collisionPairs[k]
            g, box = self.clear_geom.geometryObjects[p.first], self.clear_geom.geometryObjects[p.second]
            if g.parentJoint == 0:
                d = float(self.clear_data.distanceResults[k].min_distance)
                if d < self.static_clearance.get(box.name, (np.inf, ""))[0]:
                    self.static_clearance[box.name] = (d, g.name)
                self.clear_geom.removeCollisionPair(p)
        self.clear_data = pin.GeometryData(self.clear_geom)
        pairs = [(p.first, p.second) for p in self.clear_geom.collisionPairs]
        self.pair_box = np.array([b for _, b in pairs])
        self.pair_geom = [self.clear_geom.geometryObjects[g].name for g, _ in pairs]
        self.padding_of = {index: padding for _, index, padding in self.boxes}
        # the task's terms, for the tray's check
        prim = {t.get("name", t["kind"]): t for t in task_file["primary"]}
        self.grip = pin.SE3(np.array(prim["grip"]["target"], dtype=float))
        self.left = self.model.getFrameId(prim["grip"]["relative_to"])
        self.right = self.model.getFrameId(prim["grip"]["frame"])
        self.lower, self.upper = self.model.lowerPositionLimit, self.model.upperPositionLimit
        self.vmax = self.model.velocityLimit

    def check(self, traj_q: np.ndarray, traj_qd: np.ndarray, joint_names: list[str]) -> dict[str, Any]:
        """Every sample of a trajectory (its columns named ``joint_names``) checked."""
        pin = self.pin
        if list(joint_names) != self.joint_names:
            raise ValueError(f"joint order differs: trajectory {joint_names}, URDF {self.joint_names}")
        below = (traj_q < self.lower).sum()
        above = (traj_q > self.upper).sum()
        margin_low = float((traj_q - self.lower).min())
        margin_high = float((self.upper - traj_q).min())
        v_ratio = float((np.abs(traj_qd) / self.vmax).max())
        geoms = self.robot_geom.geometryObjects
        min_clear: dict[str, float] = {name: self.static_clearance.get(name, (np.inf, ""))[0] for name, *_ in self.boxes}
        nearest: dict[str, str] = {name: self.static_clearance.get(name, (np.inf, ""))[1] for name, *_ in self.boxes}
        static_short = sum(d < pad for (d, _), (_, _, pad) in zip(
            (self.static_clearance.get(n, (np.inf, "")) for n, *_ in self.boxes), self.boxes))
        pad = np.array([self.padding_of[b] for b in self.pair_box])
        short = self_contacts = 0
        first_self: str | None = None
        pos_err = rot_err = tilt = 0.0
        for i, q in enumerate(traj_q):
            pin.framesForwardKinematics(self.model, self.data, q)
            pin.updateGeometryPlacements(self.model, self.data, self.robot_geom, self.robot_data)
            pin.updateGeometryPlacements(self.model, self.data, self.clear_geom, self.clear_data)
            pin.computeDistances(self.clear_geom, self.clear_data)
            d = np.array([r.min_distance for r in self.clear_data.distanceResults])
            for name, index, _ in self.boxes:
                k = int(np.argmin(np.where(self.pair_box == index, d, np.inf)))
                if d[k] < min_clear[name]:
                    min_clear[name], nearest[name] = float(d[k]), self.pair_geom[k]
            short += int(static_short > 0 or bool((d < pad).any()))
            if pin.computeCollisions(self.robot_geom, self.robot_data, True):
                self_contacts += 1
                if first_self is None:
                    k = next(k for k, r in enumerate(self.robot_data.collisionResults) if r.isCollision())
                    p = self.robot_geom.collisionPairs[k]
                    first_self = f"sample {i}: {geoms[p.first].name} and {geoms[p.second].name}"
            rel_pose = self.data.oMf[self.left].actInv(self.data.oMf[self.right])
            err = self.grip.actInv(rel_pose)
            pos_err = max(pos_err, float(np.linalg.norm(err.translation)))
            rot_err = max(rot_err, float(np.linalg.norm(pin.log3(err.rotation))))
            z = self.data.oMf[self.left].rotation[:, 2]
            tilt = max(tilt, float(np.arccos(np.clip(-z[2], -1.0, 1.0))))
        return {
            "samples": int(len(traj_q)),
            "outside_position_limits": int(below + above),
            "position_limit_margin_rad": min(margin_low, margin_high),
            "max_velocity_ratio_urdf": v_ratio,
            "min_clearance_m": min_clear,
            "nearest_geometry": nearest,
            "samples_closer_than_padding": short,
            "samples_in_self_collision": self_contacts,
            "first_self_collision": first_self,
            "grip_position_error_m": pos_err,
            "grip_rotation_error_rad": rot_err,
            "tray_tilt_rad": tilt,
        }


def run_query(i: int, args: argparse.Namespace, lo: np.ndarray, hi: np.ndarray, tmp: Path) -> dict[str, Any]:
    """Query ``i``: its command run (targets redrawn while one has no collision-free IK solution)."""
    from genplan.cli import main

    rng = np.random.default_rng(i)
    redraws = 0
    while True:
        start, goal = rng.uniform(lo, hi), rng.uniform(lo, hi)
        plan_file, traj_file = tmp / f"plan_{i}.json", tmp / f"plan_{i}.npz"
        argv = ["plan", "--robot", rel(ROBOT), "--task", rel(TASK), "--scene", rel(SCENE),
                "--start-target", *(f"{x:.4f}" for x in start), "--target", *(f"{x:.4f}" for x in goal),
                "--seed", str(i), "--sampler", args.sampler]
        if args.model is not None:
            argv += ["--model", rel(args.model)]
        argv += ["--out", str(plan_file), "--trajectory", str(traj_file)]
        out, err = io.StringIO(), io.StringIO()
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as e:  # a usage error (argparse)
                code = int(e.code or 0)
        wall = time.perf_counter() - t0
        if code == 2 and redraws < args.redraws and "IK solution" in err.getvalue():
            redraws += 1
            continue
        shown = " ".join(a if not a.startswith(str(tmp)) else Path(a).name for a in argv)
        row: dict[str, Any] = {"query": i, "command": f"genplan {shown}", "exit_status": code, "redraws": redraws,
                               "command_wall_s": wall, "stdout": out.getvalue().strip().splitlines()[-2:],
                               "error": err.getvalue().strip().splitlines()[-1:] if code else []}
        if code == 0:
            plan = json.loads(plan_file.read_text())
            row["plan"] = {"time_s": plan["stats"]["time_s"], "states": len(plan["path"]),
                           "extensions": plan["stats"]["extensions"]}
            row["trajectory_file"] = str(traj_file)
        return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--queries", type=int, default=20)
    ap.add_argument("--sampler", default="uniform")
    ap.add_argument("--model", type=Path, default=None, help="the learned sampler for --sampler gan|hybrid|adaptive")
    ap.add_argument("--redraws", type=int, default=5, help="target redraws a query may take (default 5)")
    ap.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "baxter_tray.json")
    args = ap.parse_args()

    import genplan
    from genplan import projection as P
    from genplan.trajectory import Trajectory

    load_start = os.getloadavg()
    t_start = time.perf_counter()
    robot = genplan.load(ROBOT)
    task = P.load_task(TASK, robot)
    assert task.condition is not None
    lo, hi = np.array(task.condition.low), np.array(task.condition.high)
    assert robot.srdf_path is not None and robot.urdf_path is not None
    oracle = Oracle(Path(robot.urdf_path), Path(robot.srdf_path), [str(p) for p in robot.package_dirs])
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for i in range(args.queries):
            row = run_query(i, args, lo, hi, Path(d))
            if row["exit_status"] == 0:
                traj = Trajectory.load(row.pop("trajectory_file"))
                t0 = time.perf_counter()
                row["trajectory"] = {"duration_s": traj.duration, "samples": len(traj),
                                     "max_velocity_ratio": traj.max_velocity_ratio,
                                     "max_residual_ratio": traj.max_residual_ratio}
                row["independent"] = oracle.check(traj.q, traj.qd, list(traj.joint_names))
                row["independent"]["check_s"] = time.perf_counter() - t0
            rows.append(row)
            ind = row.get("independent", {})
            print(f"query {i:2d}: exit {row['exit_status']}, redraws {row['redraws']}, "
                  + (f"plan {row['plan']['time_s'] * 1e3:.0f} ms, {row['trajectory']['samples']} samples, "
                     f"clearance {min(ind['min_clearance_m'].values()) * 100:.2f} cm, "
                     f"self contacts {ind['samples_in_self_collision']}, outside limits {ind['outside_position_limits']}"
                     if row["exit_status"] == 0 else f"{row['error']}"), flush=True)
    ok = [r for r in rows if r["exit_status"] == 0]
    checked_ok = [r for r in ok if r["independent"]["samples_closer_than_padding"] == 0
                  and r["independent"]["samples_in_self_collision"] == 0
                  and r["independent"]["outside_position_limits"] == 0]
    summary = {
        "queries": len(rows),
        "succeeded": len(ok),
        "all_samples_pass_independent_check": len(checked_ok),
        "redraws": sum(r["redraws"] for r in rows),
        "samples_checked": sum(r["independent"]["samples"] for r in ok),
        "min_clearance_m": min((min(r["independent"]["min_clearance_m"].values()) for r in ok), default=None),
        "padding_m": min(p for *_, p in oracle.boxes),
        "static_clearance_m": {k: v[0] for k, v in oracle.static_clearance.items()},
        "obstacle_pairs_checked": len(oracle.pair_geom),
        "max_velocity_ratio_urdf": max((r["independent"]["max_velocity_ratio_urdf"] for r in ok), default=None),
        "min_position_limit_margin_rad": min((r["independent"]["position_limit_margin_rad"] for r in ok), default=None),
        "max_grip_position_error_m": max((r["independent"]["grip_position_error_m"] for r in ok), default=None),
        "max_grip_rotation_error_rad": max((r["independent"]["grip_rotation_error_rad"] for r in ok), default=None),
        "max_tray_tilt_rad": max((r["independent"]["tray_tilt_rad"] for r in ok), default=None),
        "median_plan_ms": float(np.median([r["plan"]["time_s"] for r in ok]) * 1e3) if ok else None,
        "median_command_s": float(np.median([r["command_wall_s"] for r in ok])) if ok else None,
        "self_pairs_checked": oracle.self_pairs,
    }
    result = {
        "command": "python benches/baxter_tray.py" + (f" --queries {args.queries}" if args.queries != 20 else "")
                   + (f" --sampler {args.sampler}" if args.sampler != "uniform" else "")
                   + (f" --model {rel(args.model)}" if args.model is not None else "")
                   + (f" --out {rel(args.out)}" if args.out != ap.get_default("out") else ""),
        "files": {"robot": rel(ROBOT), "task": rel(TASK), "scene": rel(SCENE)},
        "sampler": args.sampler, "model": None if args.model is None else rel(args.model),
        "oracle": "pinocchio " + oracle.pin.__version__ + " + coal " + getattr(oracle.coal, "__version__", "?"),
        "summary": summary,
        "queries": rows,
        "load_average_1min_start_end": [load_start[0], os.getloadavg()[0]],
        "wall_s": time.perf_counter() - t_start,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "rayon_threads": os.environ.get("RAYON_NUM_THREADS")},
        "genplan_version": genplan.__version__,
    }
    from genplan._files import write_text

    write_text(args.out, json.dumps(result, indent=1) + "\n")
    print(f"\n{summary['succeeded']}/{summary['queries']} planned; {summary['all_samples_pass_independent_check']} with "
          f"every one of their samples >= {summary['padding_m'] * 100:g} cm from the boxes, free of self-collision "
          f"and within the URDF's limits (Pinocchio + coal, {summary['samples_checked']} samples); min clearance "
          f"{summary['min_clearance_m'] * 100:.2f} cm; max |qd|/limit {summary['max_velocity_ratio_urdf']:.3f}; grip "
          f"error <= {summary['max_grip_position_error_m'] * 1e3:.2f} mm, tilt <= {summary['max_tray_tilt_rad']:.2e} "
          f"rad; wrote {rel(args.out)}")


if __name__ == "__main__":
    main()
