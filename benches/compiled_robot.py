"""What compiling a robot would buy: genplan's data-driven sphere checker against a Panda compiled
in (its joints, spheres and counts as constants, as VAMP compiles its robots), on the same states
and the same MotionBenchMaker-style scene, and what that speed-up would make of genplan's planning
time against VAMP's.

    python benches/compiled_robot.py --generate          # rewrite benches/compiled_robot_panda.rs
    python benches/compiled_robot.py --out benches/results/compiled_robot.json

``--generate`` writes benches/compiled_robot_panda.rs (generated, committed): the Panda of
benches/../python/genplan/experiments/benchmarks/motion.py (fingers open 0.04 m) compiled in: its
joints' fixed placements as constants of a forward kinematics written out term by term (zero terms
dropped, as VAMP's generated C++ does), the fixed links (the hand and fingers) folded into link 7's
frame, genplan's cover (``robot_spheres``) and VAMP's 59 spheres (``motion.vamp_spheres``) as
constant tables grouped by link, their self pairs, and one problem's scene (the first
``--family`` problem of ``motion.make_problems`` at ``--seed``: boxes and upright capsules).

The run (default) then:

* runs the criterion bench benches/compiled_robot.rs (``cargo bench --bench compiled_robot``),
  which asserts that both checkers give the same answer on every state and edge, and collects its
  medians: ns per state for one state, batches of 8, and edges (``motion_free``), data-driven
  (``genplan``) and compiled, on both sphere sets;
* plans ``--problems`` problems per family of benches' motion families with genplan's sphere
  checker (genplan's cover and VAMP's spheres) and with VAMP, records genplan's share of the
  planning time spent in the checker (``stats.checker_s / stats.time_s``) and the plan-time
  ratio to VAMP, and gives the ratio the compiled checker would bring (Amdahl: the checker's
  share divided by the speed-up measured per edge state);
* measures VAMP's own cost per state: ``validate_motion`` on free edges of different lengths,
  the slope of time against states (VAMP's resolution, ``vamp.panda.resolution()`` states per
  unit length), so that Python's per-call overhead is the intercept, not part of the slope.
"""

from __future__ import annotations

import os

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from genplan.experiments.benchmarks import motion as M  # noqa: E402
from genplan.experiments.common import machine, write_json  # noqa: E402
from genplan.planning import Planner, sphere_checker  # noqa: E402
from genplan.scene import Box, Scene  # noqa: E402
from genplan.spheres import RobotSpheres, robot_spheres  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ROOT / "benches" / "compiled_robot_panda.rs"
#: the arm's links, parents first (joint i places LINKS[i] from LINKS[i - 1])
LINKS = [f"panda_link{i}" for i in range(8)]
#: links fixed to link 7 (locked or fixed joints), their spheres folded into its frame
HELD = ["panda_hand", "panda_leftfinger", "panda_rightfinger"]
#: a coefficient this small is a zero of the placement (the URDF's pi/2 turns leave 6e-17)
ZERO = 1e-9


def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _lit(v: float) -> str:
    return f"{float(np.float32(v))!r}f32"


class _Fk:
    """The forward kinematics written out: each frame entry a float constant or a named value."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def lin(self, terms: list[tuple[float, Any]], const: float = 0.0) -> Any:
        """sum coef * entry (+ const): a constant when no named entry is left, else an expression."""
        out, c = [], const
        for k, e in terms:
            if abs(k) < ZERO:
                continue
            if isinstance(e, float):
                c += k * e
            elif abs(k - 1) < ZERO:
                out.append(f"+ {e}")
            elif abs(k + 1) < ZERO:
                out.append(f"- {e}")
            else:
                out.append(f"+ {_lit(k)} * {e}")
        if not out:
            return 0.0 if abs(c) < ZERO else c
        s = " ".join(out)
        if abs(c) >= ZERO:
            s += f" + {_lit(c)}"
        return s.removeprefix("+ ")

    def bind(self, name: str, e: Any) -> Any:
        if isinstance(e, float):
            return e
        self.lines.append(f"        let {name} = {e};")
        return name

    def turn(self, name: str, terms: list[tuple[Any, float, str]]) -> Any:
        """Bind sum sign * a * v over (a, sign, v): a an entry, v a lane value (a cosine, a sine)."""
        parts = []
        for a, sign, v in terms:
            if isinstance(a, float):
                if abs(a) >= ZERO:
                    parts.append(f"{_lit(sign * a)} * {v}")
            else:
                parts.append(f"{'-' if sign < 0 else ''}{a} * {v}")
        return self.bind(name, " + ".join(parts)) if parts else 0.0


def _fk_code(origins: list[np.ndarray]) -> str:
    """Rust: the frames of links 1..7 per lane from the joints' cosines and sines."""
    g = _Fk()
    R: list[list[Any]] = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    t: list[Any] = [0.0, 0.0, 0.0]
    outs = []
    for j, o in enumerate(origins):
        a = [[g.bind(f"a{j}_{r}{c}", g.lin([(o[k, c], R[r][k]) for k in range(3)])) for c in range(3)] for r in range(3)]
        t = [g.bind(f"t{j}_{r}", g.lin([(o[k, 3], R[r][k]) for k in range(3)] + [(1.0, t[r])])) for r in range(3)]
        # R = A Rz: column 0 = a0 c + a1 s, column 1 = a1 c - a0 s, column 2 = a2
        R = [[g.turn(f"r{j}_{r}0", [(a[r][0], 1.0, f"c{j}"), (a[r][1], 1.0, f"s{j}")]),
              g.turn(f"r{j}_{r}1", [(a[r][1], 1.0, f"c{j}"), (a[r][0], -1.0, f"s{j}")]),
              a[r][2]] for r in range(3)]
        outs.append([R[r][c] for r in range(3) for c in range(3)] + t)
    body = "\n".join(g.lines)
    return (
        "/// The frames of links 1..7 (rotation row-major, then translation) per lane from the joints'\n"
        "/// cosines `c` and sines `s`: the joints' placements folded in as constants, each value a\n"
        "/// lane vector (`V`: one operation per vector instruction).\n"
        "#[inline(always)]\n"
        "pub fn fk<const N: usize>(c: &[V<N>; 7], s: &[V<N>; 7]) -> [[V<N>; 12]; 7] {\n"
        + "\n".join(f"    let (c{j}, s{j}) = (c[{j}], s[{j}]);" for j in range(7)) + "\n"
        + body.replace("\n        ", "\n    ").removeprefix("    ") + "\n    [\n"
        + "\n".join("        [" + ", ".join(e if not isinstance(e, float) else f"V([{_lit(e)}; N])" for e in entries) + "],"
                    for entries in outs)
        + "\n    ]\n}\n"
    )


def _robot_tables(name: str, sph: RobotSpheres, pairs: list[tuple[str, str]], held_in_7: dict[str, np.ndarray]) -> str:
    """Rust: one sphere set grouped by link, each group's frame (-1: the world; 0..6: links 1..7),
    centres in that frame, radii, and the self pairs (group indices)."""
    links = list(sph.links)
    order = [l for l in LINKS + HELD if l in links]
    spheres: list[tuple[np.ndarray, float]] = []
    groups: list[tuple[str, int, int, int, np.ndarray, float]] = []
    for gl in order:
        idx = [i for i, l in enumerate(links) if l == gl]
        start = len(spheres)
        for i in idx:
            c = np.append(np.asarray(sph.centers[i], dtype=np.float64), 1.0)
            if gl in held_in_7:
                c = held_in_7[gl] @ c
            spheres.append((c[:3], float(sph.radii[i])))
        frame = LINKS.index(gl) - 1 if gl in LINKS else 6
        # the group's bounding sphere (its frame): the centre of the spheres' box, the farthest reach
        cs = np.array([s[0] for s in spheres[start:]])
        rs = np.array([s[1] for s in spheres[start:]])
        mid = 0.5 * ((cs - rs[:, None]).min(axis=0) + (cs + rs[:, None]).max(axis=0))
        reach = float((np.linalg.norm(cs - mid, axis=1) + rs).max()) * (1 + 1e-6) + 1e-5
        groups.append((gl, frame, start, len(spheres), mid, reach))
    gi = {g[0]: k for k, g in enumerate(groups)}
    pair_idx = [(gi[a], gi[b]) for a, b in pairs]
    n, ng = len(spheres), len(groups)
    out = [f"/// {name}: {n} spheres on {ng} links.", f"pub mod {name} {{"]
    out.append(f"    pub const SPHERES: usize = {n};")
    out.append(f"    pub const GROUPS: usize = {ng};")
    out.append(f"    pub const PAIRS: usize = {len(pair_idx)};")
    out.append("    /// Per group: its link's name, its frame (-1 the world, k link k + 1), its spheres\n"
               "    /// `start..end`, its bounding sphere's centre (its frame) and radius (with the slack).")
    out.append(f"    pub const GROUP: [(&str, i32, usize, usize, [f32; 3], f32); {ng}] = [")
    for gl, frame, s, e, mid, reach in groups:
        out.append(f"        (\"{gl}\", {frame}, {s}, {e}, [{', '.join(_lit(v) for v in mid)}], {_lit(reach)}),")
    out.append("    ];")
    out.append("    /// Per sphere: centre in its group's frame (f64, as the data-driven model takes it), radius.")
    out.append(f"    pub const SPHERE: [([f64; 3], f64); {n}] = [")
    for c, r in spheres:
        out.append(f"        ([{', '.join(repr(float(v)) for v in c)}], {float(r)!r}),")
    out.append("    ];")
    out.append("    /// The spheres as the data-driven checker is given them: link name, centre in the link's frame, radius.")
    out.append(f"    pub const LINK_SPHERE: [(&str, [f64; 3], f64); {len(links)}] = [")
    for l, c, r in zip(links, sph.centers, sph.radii):
        out.append(f"        (\"{l}\", [{', '.join(repr(float(v)) for v in c)}], {float(r)!r}),")
    out.append("    ];")
    out.append("    /// Self pairs (group indices), as the world's self pairs among the links with spheres.")
    out.append(f"    pub const PAIR: [(usize, usize); {len(pair_idx)}] = {pair_idx!r};".replace("[(", "[(").replace(")]", ")]"))
    out.append("}")
    return "\n".join(out) + "\n"


def generate(family: str, seed: int) -> None:
    vamp = M.vamp_module()
    if vamp is None:
        raise SystemExit("--generate needs vamp (VAMP's spheres): pip install vamp_planner")
    robot = M.load_panda()
    names = list(robot.kinematics.link_names)
    rng = np.random.default_rng(seed)
    qs = np.vstack([np.zeros(7), robot.random_configurations(16, rng)])
    poses = np.asarray(robot.kinematics.forward_kinematics(qs, names))  # (c, L, 4, 4)
    T = {n: poses[:, i] for i, n in enumerate(names)}
    assert np.allclose(T["panda_link0"], np.eye(4), atol=1e-12), "link 0 is not the world frame"
    origins = []
    for j in range(1, 8):
        o = np.linalg.inv(T[LINKS[j - 1]][0]) @ T[LINKS[j]][0]
        for c in range(len(qs)):  # the joint turns about its z: T_j = T_{j-1} O Rz(q_j)
            err = np.abs(T[LINKS[j - 1]][c] @ o @ _rz(qs[c, j - 1]) - T[LINKS[j]][c]).max()
            assert err < 1e-9, f"joint {j}: not a turn about z after a fixed placement ({err})"
        origins.append(o)
    held = {}
    for h in HELD:
        m = np.linalg.inv(T["panda_link7"][0]) @ T[h][0]
        for c in range(len(qs)):
            assert np.abs(T["panda_link7"][c] @ m - T[h][c]).max() < 1e-9, f"{h} moves against link 7"
        held[h] = m
    vsph = M.vamp_spheres(vamp, robot)
    problem = M.make_problems(robot, family, 1, seed, vamp, vsph)[0]
    world = robot.collision_world()
    world.add_scene(Scene(name="problem", obstacles=tuple(problem.obstacles)))
    own = robot_spheres(robot)
    cover_pairs = list(sphere_checker(robot, world).self_pairs)
    vamp_pairs = list(sphere_checker(robot, world, spheres=vsph).self_pairs)
    boxes, capsules = [], []
    for o in problem.obstacles:
        yaw = float(o.pose.rpy[2]) if o.pose.rpy is not None else 0.0
        p = ", ".join(repr(float(v)) for v in o.pose.position)
        if isinstance(o, Box):
            boxes.append(f"    ([{p}], {yaw!r}, [{', '.join(repr(float(v)) for v in o.half_extents)}]),")
        else:
            assert o.pose.rpy is None or not any(o.pose.rpy), "a capsule that is not upright"
            capsules.append(f"    ([{p}], {float(o.radius)!r}, {float(o.length) / 2!r}),")
    text = [
        "// Generated by `python benches/compiled_robot.py --generate` (do not edit): the Panda of",
        "// python/genplan/experiments/benchmarks/motion.py compiled in for benches/compiled_robot.rs.",
        f"// Scene: the first '{family}' problem of motion.make_problems at seed {seed}.",
        "",
        "use super::V;",
        "",
        f"/// The scene's family and seed.\npub const SCENE: (&str, u64) = (\"{family}\", {seed});",
        f"/// The start and goal of the problem.\npub const START: [f64; 7] = {list(map(float, problem.start))!r};",
        f"pub const GOAL: [f64; 7] = {list(map(float, problem.goal))!r};",
        "/// The joints' fixed placements (parent to joint frame, 3 x 4 row-major) the kinematics fold in,",
        "/// checked against the model by the bench.",
        "pub const ORIGIN: [[f64; 12]; 7] = [",
        *[f"    [{', '.join(repr(float(v)) for v in o[:3, :].ravel())}]," for o in origins],
        "];",
        "/// Boxes: centre, turn about z (rad), half extents.",
        f"pub const BOXES: [([f64; 3], f64, [f64; 3]); {len(boxes)}] = [", *boxes, "];",
        "/// Upright capsules: centre, radius, half length of the segment.",
        f"pub const CAPSULES: [([f64; 3], f64, f64); {len(capsules)}] = [", *capsules, "];",
        "",
        _fk_code(origins),
        _robot_tables("cover", own, cover_pairs, held),
        _robot_tables("vamp", vsph, vamp_pairs, held),
    ]
    GENERATED.write_text("\n".join(text))
    print(f"wrote {GENERATED}")


def _env() -> dict[str, str]:
    """The bench's environment: example-robot-data's folder as genplan finds it."""
    from genplan.robots import robots_dir

    return {**os.environ, "GENPLAN_ROBOTS_DIR": str(robots_dir())}


def _criterion(run: bool) -> dict[str, Any]:
    """Run the criterion bench (short: 1 s warm-up, 3 s per measurement; unless ``run`` is
    False: the last run's) and read its medians per state, and the bench's facts."""
    if run:
        cmd = ["cargo", "bench", "--package", "genplan-core", "--bench", "compiled_robot", "--",
               "--warm-up-time", "1", "--measurement-time", "3"]
        print("+", " ".join(cmd), flush=True)
        subprocess.run(cmd, cwd=ROOT, check=True, env=_env())
    out = {}
    base = ROOT / "target" / "criterion" / "compiled_robot"
    for est in sorted(base.glob("**/new/estimates.json")):
        bench = json.loads((est.parent / "benchmark.json").read_text())
        name = bench["full_id"].removeprefix("compiled_robot/")
        n = (bench.get("throughput") or {}).get("Elements", 1)
        median = json.loads(est.read_text())["median"]
        ci = median["confidence_interval"]
        out[name] = {"states_per_iteration": n, "ns_per_state": median["point_estimate"] / n,
                     "ci95_ns_per_state": [ci["lower_bound"] / n, ci["upper_bound"] / n]}
    facts = ROOT / "target" / "criterion" / "compiled_robot_facts.json"
    return {"benches": out, "facts": json.loads(facts.read_text()) if facts.exists() else {}}


#: the bench's one-pass functions (benches/compiled_robot.rs, ``COMPILED_ROBOT_COUNT``), each run
#: twice over its inputs
COUNTED = ("single_random_genplan", "single_random_compiled", "single_free_genplan", "single_free_compiled",
           "batch8_genplan", "batch8_compiled", "batch8_compiled_place", "edge_genplan", "edge_compiled")


def _instructions(facts: dict[str, Any]) -> dict[str, Any]:
    """Instructions per state of each variant (callgrind's inclusive counts of the bench's
    one-pass functions, which run each variant twice over its states): a count the machine's
    load does not change. genplan's share of its tests (``collide_kernel``, AVX2 build) in its
    instructions, and the compiled batch's share of its kinematics and placement."""
    build = subprocess.run(["cargo", "bench", "--package", "genplan-core", "--bench", "compiled_robot", "--no-run",
                            "--message-format=json"], cwd=ROOT, check=True, capture_output=True, text=True, env=_env())
    exe = [json.loads(line)["executable"] for line in build.stdout.splitlines()
           if '"executable":"' in line and "compiled_robot" in line][-1]
    out: dict[str, Any] = {}
    for spheres in ("cover", "vamp"):
        f = facts[spheres]
        states = {"single_random": f["states"], "single_free": f["states"] - f["states_in_collision"],
                  "batch8": f["states"], "edge": f["edge_states_checked"]}
        dump = ROOT / "target" / f"compiled_robot_{spheres}.callgrind"
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={dump}", "--collect-atstart=no",
                        "--toggle-collect=compiled_robot::count_*", exe, "--bench"],
                       cwd=ROOT / "rust" / "core", check=True, capture_output=True, env={**_env(), "COMPILED_ROBOT_COUNT": spheres})
        text = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(dump)], check=True, capture_output=True,
                              text=True).stdout
        ir: dict[str, int] = {}
        for line in text.splitlines():
            m = re.match(r"\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+\S*?:(\S+)", line)
            if m:
                ir[m.group(2)] = int(m.group(1).replace(",", ""))
        row: dict[str, Any] = {}
        for name in COUNTED:
            kind = name.rsplit("_", 2)[0] if name.endswith("_place") else name.rsplit("_", 1)[0]
            total = ir.get(f"compiled_robot::count_{name}")
            if total is not None:
                row[name] = total / (2 * states[kind])
        # the tests' kernel (AVX2 build), always a function of its own
        genplan_tests = ir.get("genplan_core::collision::spheres::dispatch_collide::collide_avx2", 0)
        genplan_all = sum(ir.get(f"compiled_robot::count_{n}", 0) for n in COUNTED if n.endswith("genplan"))
        row["genplan_tests_share"] = genplan_tests / genplan_all if genplan_all else math.nan
        if "batch8_compiled_place" in row:
            row["compiled_batch8_placement_share"] = row["batch8_compiled_place"] / row["batch8_compiled"]
        out[spheres] = row
    return out


def _plans(families: list[str], n: int, seed: int) -> dict[str, Any]:
    """genplan's sphere planner (its cover, VAMP's spheres) and VAMP on the same problems, in
    alternating order: plan times (less simplification, as benchmarks/motion.py reports them) and
    genplan's share of its planning call spent in the checker."""
    vamp = M.vamp_module()
    robot = M.load_panda()
    vsph = M.vamp_spheres(vamp, robot) if vamp is not None else None
    arms = {"genplan_spheres": None, **({"genplan_vamp_spheres": vsph} if vsph is not None else {})}
    recs: list[dict[str, Any]] = []
    for family in families:
        for p in M.make_problems(robot, family, n, seed, vamp, vsph):
            pseed = seed * 100_003 + p.index
            order = list(arms) + (["vamp"] if vamp is not None else [])
            for arm in (order if p.index % 2 == 0 else order[::-1]):
                if arm == "vamp":
                    r = M._vamp_arm(vamp, p, pseed, M.ROBOTS["panda"])
                    recs.append({"family": family, "problem": p.index, "arm": arm, "plan_ms": r["plan_ms"],
                                 "success": r["success"]})
                    continue
                world = robot.collision_world()
                world.add_scene(Scene(name="problem", obstacles=tuple(p.obstacles)))
                checker = sphere_checker(robot, world, spheres=arms[arm])
                planner = Planner(robot, world, task="free", checker=checker, settings=M.settings(), seed=pseed)
                t0 = time.perf_counter()
                res = planner.plan(p.start, p.goal)
                wall = time.perf_counter() - t0
                st = res.stats
                recs.append({"family": family, "problem": p.index, "arm": arm, "success": bool(res.success),
                             "plan_ms": (wall - float(st.simplify_s)) * 1e3, "wall_ms": wall * 1e3,
                             "checker_ms": float(st.checker_s) * 1e3, "time_ms": float(st.time_s) * 1e3,
                             "checks": int(st.validity_checks)})
    out: dict[str, Any] = {"families": families, "problems_per_family": n, "seed": seed, "records": recs}
    for arm in arms:
        rs = [r for r in recs if r["arm"] == arm]
        # the checker's share of the whole planning call (simplification included: its checks too)
        out[arm] = {"plan_ms_median": float(np.median([r["plan_ms"] for r in rs])),
                    "checker_share": float(sum(r["checker_ms"] for r in rs) / sum(r["time_ms"] for r in rs)),
                    "checker_share_median": float(np.median([r["checker_ms"] / r["time_ms"] for r in rs])),
                    "success": sum(r["success"] for r in rs), "problems": len(rs)}
    if vamp is not None:
        vm = [r["plan_ms"] for r in recs if r["arm"] == "vamp"]
        out["vamp"] = {"plan_ms_median": float(np.median(vm)), "success": sum(r["success"] for r in recs if r["arm"] == "vamp")}
        # per family: the ratio of the medians (as benchmarks/motion.py), then their geometric mean
        for arm in arms:
            ratios = []
            for f in families:
                g = [r["plan_ms"] for r in recs if r["arm"] == arm and r["family"] == f]
                v = [r["plan_ms"] for r in recs if r["arm"] == "vamp" and r["family"] == f]
                if g and v:
                    ratios.append(float(np.median(g) / np.median(v)))
            out[arm]["plan_over_vamp_per_family"] = ratios
            out[arm]["plan_over_vamp"] = float(np.exp(np.mean(np.log(ratios)))) if ratios else math.nan
    return out


def _vamp_per_state(family: str, seed: int, edges: int) -> dict[str, Any] | None:
    """VAMP's cost per state on the generated scene: ``validate_motion`` on free edges from the
    problem's start, timed from Python, fitted as overhead + states x cost (the states: VAMP's
    resolution times the edge's length); and ``validate`` of one state, less that overhead."""
    vamp = M.vamp_module()
    if vamp is None:
        return None
    robot = M.load_panda()
    vsph = M.vamp_spheres(vamp, robot)
    p = M.make_problems(robot, family, 1, seed, vamp, vsph)[0]
    env = M.vamp_environment(vamp, p.obstacles)
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(vamp.panda.lower_bounds()), np.asarray(vamp.panda.upper_bounds())
    a = p.start.astype(np.float32)
    pairs: list[np.ndarray] = []
    while len(pairs) < edges:
        d = rng.normal(size=7)
        b = np.clip(a + d / np.linalg.norm(d) * rng.uniform(0.05, 1.5), lo, hi).astype(np.float32)
        if vamp.panda.validate_motion(a, b, env):
            pairs.append(b)
    res = vamp.panda.resolution()
    states = np.array([math.ceil(np.linalg.norm(b - a) * res) for b in pairs], dtype=np.float64)
    reps, rounds = 50, 7
    best = np.full(len(pairs), np.inf)
    for _ in range(rounds):  # each edge once per round: the fastest round per edge (the load adds)
        for i, b in enumerate(pairs):
            t0 = time.perf_counter()
            for _ in range(reps):
                vamp.panda.validate_motion(a, b, env)
            best[i] = min(best[i], (time.perf_counter() - t0) / reps)
    ns = best * 1e9
    slope, intercept = np.polyfit(states, ns, 1)
    single = math.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(20 * reps):
            vamp.panda.validate(a, env)
        single = min(single, (time.perf_counter() - t0) / (20 * reps) * 1e9)
    scene = ROOT / "target" / "compiled_robot_vamp_scene.json"
    scene.write_text(json.dumps({"obstacles": [
        {"kind": "box", "p": list(map(float, o.pose.position)), "yaw": float(o.pose.rpy[2]) if o.pose.rpy is not None else 0.0,
         "h": list(map(float, o.half_extents))} if isinstance(o, Box) else
        {"kind": "capsule", "p": list(map(float, o.pose.position)), "r": float(o.radius), "l": float(o.length)}
        for o in p.obstacles], "a": a.tolist(), "bs": [b.tolist() for b in pairs]}))
    instructions = _vamp_instructions(scene, int(states.sum()))
    return {"edges": edges, "resolution_states_per_unit": res, "instructions_per_edge_state": instructions, "states_min": int(states.min()),
            "states_max": int(states.max()), "ns_per_edge_state": float(slope), "ns_per_call_overhead": float(intercept),
            "validate_ns_per_call": float(single), "validate_ns_less_overhead": float(single - intercept)}


_VAMP_PASS = """
import json, sys, numpy as np, vamp
d = json.load(open(sys.argv[1]))
env = vamp.Environment()
for o in d["obstacles"]:
    if o["kind"] == "box":
        env.add_cuboid(vamp.Cuboid(o["p"], [0.0, 0.0, o["yaw"]], o["h"]))
    else:
        env.add_capsule(vamp.Cylinder(o["p"], [0.0, 0.0, 0.0], o["r"], o["l"]))
a = np.array(d["a"], dtype=np.float32)
bs = [np.array(b, dtype=np.float32) for b in d["bs"]]
for _ in range(int(sys.argv[2])):
    for b in bs:
        assert vamp.panda.validate_motion(a, b, env)
"""


def _vamp_instructions(scene: Path, states: int) -> float | None:
    """VAMP's instructions per edge state: a Python process that builds the scene and checks the
    free edges once, then three times, under callgrind; the instructions run in VAMP's extension
    module (its call wrappers included), the difference of the two runs (the import and the
    scene's construction cancel) over the states of two passes (None without valgrind)."""
    counts = []
    for passes in (1, 3):
        dump = ROOT / "target" / f"compiled_robot_vamp_{passes}.callgrind"
        try:
            subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={dump}", sys.executable, "-c",
                            _VAMP_PASS, str(scene), str(passes)], check=True, capture_output=True)
        except (OSError, subprocess.CalledProcessError):
            return None
        text = subprocess.run(["callgrind_annotate", "--threshold=100", str(dump)], check=True, capture_output=True,
                              text=True).stdout
        total = 0
        for line in text.splitlines():
            m = re.match(r"\s*([\d,]+)\s+\(", line)
            if m and "vamp/_core" in line:
                total += int(m.group(1).replace(",", ""))
        counts.append(total)
    return (counts[1] - counts[0]) / (2 * states)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--generate", action="store_true", help="rewrite benches/compiled_robot_panda.rs and stop")
    p.add_argument("--family", default="bookshelf_thin", choices=list(M.FAMILIES), help="the bench's scene")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--problems", type=int, default=3, help="planning problems per family for the checker's share")
    p.add_argument("--skip-bench", action="store_true", help="read the last criterion run instead of running it")
    p.add_argument("--skip-plans", action="store_true", help="no planning (no checker share, no Amdahl figures)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    if args.generate:
        generate(args.family, args.seed)
        return 0
    load0 = os.getloadavg()
    crit = _criterion(run=not args.skip_bench)
    instr = _instructions(crit["facts"])
    plans = {} if args.skip_plans else _plans(list(M.FAMILIES), args.problems, args.seed)
    vamp = _vamp_per_state(args.family, args.seed, edges=64)
    b = crit["benches"]
    summary: dict[str, Any] = {}
    for spheres, arm in (("cover", "genplan_spheres"), ("vamp", "genplan_vamp_spheres")):
        row: dict[str, Any] = {}
        ins = instr.get(spheres, {})
        for kind in ("single_random", "single_free", "batch8", "edge"):
            g, c = b.get(f"{spheres}/{kind}/genplan"), b.get(f"{spheres}/{kind}/compiled")
            if g and c:
                row[kind] = {"genplan_ns": g["ns_per_state"], "compiled_ns": c["ns_per_state"],
                             "speedup": g["ns_per_state"] / c["ns_per_state"]}
            if f"{kind}_genplan" in ins and f"{kind}_compiled" in ins:
                row.setdefault(kind, {}).update(
                    genplan_instructions=ins[f"{kind}_genplan"], compiled_instructions=ins[f"{kind}_compiled"],
                    instruction_speedup=ins[f"{kind}_genplan"] / ins[f"{kind}_compiled"])
        if arm in plans and "edge" in row:
            share = plans[arm]["checker_share"]
            measured = plans[arm].get("plan_over_vamp", math.nan)
            row["amdahl"] = {"checker_share": share, "plan_over_vamp_measured": measured}
            # the edge speed-up stands for the planner's checks: its states come in edges
            for key, k in (("time", row["edge"].get("speedup")), ("instructions", row["edge"].get("instruction_speedup"))):
                if k:
                    factor = (1 - share) + share / k
                    row["amdahl"][f"by_{key}"] = {"checker_speedup": k, "plan_time_factor": factor,
                                                  "plan_over_vamp_compiled": measured * factor}
        if vamp is not None:
            row["vamp_ns_per_edge_state"] = vamp["ns_per_edge_state"]
        summary[spheres] = row
    for spheres, row in summary.items():
        for kind in ("single_random", "single_free", "batch8", "edge"):
            r = row.get(kind, {})
            if "speedup" in r:
                print(f"{spheres:5s} {kind:13s} genplan {r['genplan_ns']:7.1f} ns/state  compiled {r['compiled_ns']:7.1f}  x{r['speedup']:.2f}", end="")
            if "instruction_speedup" in r:
                print(f"   instructions {r['genplan_instructions']:7.0f} vs {r['compiled_instructions']:7.0f}  x{r['instruction_speedup']:.2f}", end="")
            print()
        if "amdahl" in row:
            a = row["amdahl"]
            print(f"{spheres:5s} checker share {a['checker_share']:.2f} of planning; plan time / VAMP measured {a['plan_over_vamp_measured']:.2f}")
            for key in ("time", "instructions"):
                if f"by_{key}" in a:
                    x = a[f"by_{key}"]
                    print(f"      compiled (edge speed-up by {key} x{x['checker_speedup']:.2f}): plan time x{x['plan_time_factor']:.2f} "
                          f"-> {x['plan_over_vamp_compiled']:.2f}x VAMP")
    if vamp is not None:
        print(f"VAMP: {vamp['instructions_per_edge_state'] or math.nan:.0f} instructions per edge state; timed from Python, "
              f"{vamp['ns_per_call_overhead']:.0f} ns per validate_motion call plus {vamp['ns_per_edge_state']:.1f} ns per state "
              f"(the call's overhead hides the states' cost), validate {vamp['validate_ns_per_call']:.0f} ns per call")
    load1 = os.getloadavg()
    print(f"load average (1 min): {load0[0]:.2f} at the start, {load1[0]:.2f} at the end")
    payload = {"benchmark": "compiled_robot", "scene": {"family": args.family, "seed": args.seed},
               "summary": summary, "criterion": crit, "instructions_per_state": instr, "plans": plans, "vamp": vamp,
               "load_1min_start": load0[0], "load_1min_end": load1[0], "machine": machine()}
    write_json(args.out, payload)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
