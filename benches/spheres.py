"""Collision spheres per robot (genplan.spheres): count, time, the cover's check, tightness, and
the false positives against coal on the raw geometry.

    python benches/spheres.py [--robots panda ur5 baxter kinova xarm7] [--max-error 0.01]
                              [--configurations 2000] [--points 20000] [--seed 0] [--cache]
                              [--out benches/results/spheres.json]

Per robot (``xarm7`` is example-robot-data's xArm7 URDF, loaded with ``genplan.load(urdf=...)``;
``baxter`` is examples/baxter/baxter.toml, both arms active):

* ``spheres``, ``generation_s``: :func:`genplan.spheres.robot_spheres` in an empty cache folder
  (``link_max_error_m``: the links it covered with a max_error of their own, by default)
  (a temporary ``$GENPLAN_CACHE``; with ``--cache`` the user's, ``cached_from_disk`` true when the
  spheres were read from it, not generated); ``cached_load_s``: the same call again in a fresh process's
  state (the in-memory copy dropped), read from the cache file;
* ``cover``: ``--points`` points per collision geometry (uniform on its surface and in its solid
  (a mesh's solid: :class:`MeshSolid`, a vertical line's crossings), plus a mesh's vertices and
  edge points), each placed in its link's frame with Pinocchio's
  geometry placement and the link's pose from genplan's kinematics, and the largest
  ``|p - c| - (r - padding)`` over the link's spheres' nearest: <= 0 means every point covered
  without the padding's help;
* ``excess_max_m``, ``excess_mean_m``: the generator's bound of how far each sphere reaches beyond
  its link's solid (padding included); ``volume_ratio``: the volume of the union of a link's
  spheres over its solid's, summed over the links (Monte Carlo, 200k points per link);
* against coal: ``--configurations`` random configurations, in 10 scenes of 3 random boxes
  (half extents 2-10 cm, random rotations) each centred near a link of a random configuration;
  coal's robot-box contacts on the raw collision geometry (Pinocchio's collision model) against
  the spheres' (sphere-box distances): ``missed`` (coal in contact, the spheres free: must be 0)
  and ``false_positive_rate`` (the spheres in contact where coal finds none, over coal's free
  configurations).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

import genplan
from genplan.robots import robots_dir

ROOT = Path(__file__).resolve().parents[1]


def load_robot(name: str) -> genplan.Robot:
    """A preset, ``xarm7`` (example-robot-data's URDF) or a URDF path."""
    if name == "xarm7":
        return genplan.load(urdf=robots_dir() / "xarm_description" / "urdf" / "xarm7.urdf", name="xarm7")
    if name == "baxter":
        return genplan.load(ROOT / "examples" / "baxter" / "baxter.toml")
    if name.endswith(".urdf"):
        return genplan.load(urdf=name)
    return genplan.load(name)


class _Crossings:
    """One connected part of a mesh as a solid, by the crossings of a vertical line through each
    point, the triangles binned by the cells of a grid over their xy extent so that a point meets
    only the triangles of its cell. A closed, consistently oriented part: the signed crossings above
    the point (+1 where a triangle's normal points up, -1 down), whose sum is the part's winding
    number, inside where it is not 0. Any other part (open, or closed but not oriented): inside
    where the line crosses it an odd number of times both above and below the point (the sphere
    generator's rule for such parts: an open part's winding number is not an integer). A line
    that grazes an edge or a vertex, or a point on the surface, is decided by the winding number
    (above 1/2 in magnitude)."""

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, oriented: bool) -> None:
        v, tri = vertices, triangles
        self.v, self.tri, self.oriented = v, tri, oriented
        self.a, self.b, self.c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
        lo = np.minimum(np.minimum(self.a, self.b), self.c)[:, :2]
        hi = np.maximum(np.maximum(self.a, self.b), self.c)[:, :2]
        self.k = int(np.clip(np.sqrt(len(tri)), 1, 256))
        self.origin = lo.min(axis=0)
        self.cell = np.maximum((hi.max(axis=0) - self.origin) / self.k, 1e-12)
        i0, i1 = self._cells(lo), self._cells(hi)
        nj = i1[:, 1] - i0[:, 1] + 1
        count = (i1[:, 0] - i0[:, 0] + 1) * nj
        t = np.repeat(np.arange(len(tri)), count)
        local = np.arange(len(t)) - np.repeat(np.cumsum(count) - count, count)
        key = (i0[t, 0] + local // nj[t]) * self.k + i0[t, 1] + local % nj[t]
        self.cell_triangles = t[np.argsort(key, kind="stable")]
        self.cell_start = np.concatenate([[0], np.cumsum(np.bincount(key, minlength=self.k * self.k))])

    def _cells(self, xy: np.ndarray) -> np.ndarray:
        return np.clip(np.floor((xy - self.origin) / self.cell), 0, self.k - 1).astype(np.int64)

    def contains(self, p: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
        from genplan.spheres import _winding

        inside = np.zeros(len(p), dtype=bool)
        rel = (p[:, :2] - self.origin) / self.cell
        within = np.flatnonzero(np.all((rel >= 0) & (rel <= self.k), axis=1))  # beyond the xy extent: outside
        key = self._cells(p[within, :2]) @ np.array([self.k, 1])
        n = self.cell_start[key + 1] - self.cell_start[key]
        ends = np.cumsum(n)
        lo = 0
        while lo < len(within):  # as many points as have `chunk` (point, triangle) pairs
            hi = max(lo + 1, int(np.searchsorted(ends, (ends[lo - 1] if lo else 0) + chunk, side="right")))
            pts, cnt = within[lo:hi], n[lo:hi]
            which = np.repeat(np.arange(len(pts)), cnt)
            first = np.repeat(self.cell_start[key[lo:hi]] - (np.cumsum(cnt) - cnt), cnt)
            t = self.cell_triangles[first + np.arange(len(which))]
            q = p[pts[which]]
            a, b, c = self.a[t], self.b[t], self.c[t]
            area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
            w0 = (b[:, 0] - q[:, 0]) * (c[:, 1] - q[:, 1]) - (b[:, 1] - q[:, 1]) * (c[:, 0] - q[:, 0])
            w1 = (c[:, 0] - q[:, 0]) * (a[:, 1] - q[:, 1]) - (c[:, 1] - q[:, 1]) * (a[:, 0] - q[:, 0])
            flat = area == 0  # parallel to the ray: its neighbours' edges say whether the ray grazes it
            safe = np.where(flat, 1.0, area)
            u0, u1 = w0 / safe, w1 / safe
            u2 = 1 - u0 - u1
            tol = 1e-9
            hit = ~flat & (u0 > tol) & (u1 > tol) & (u2 > tol)
            z = u0 * a[:, 2] + u1 * b[:, 2] + u2 * c[:, 2]
            graze = ~flat & (u0 >= -tol) & (u1 >= -tol) & (u2 >= -tol) & ~hit
            graze |= hit & (np.abs(z - q[:, 2]) <= tol * (1 + np.abs(z)))
            up = hit & (z > q[:, 2])
            if self.oriented:
                inside[pts] = np.abs(np.bincount(which[up], weights=np.sign(area[up]), minlength=len(pts))) > 0.5
            else:
                above = np.bincount(which[up], minlength=len(pts))
                below = np.bincount(which[hit & ~up], minlength=len(pts))
                inside[pts] = (above % 2 == 1) & (below % 2 == 1)
            doubt = pts[np.bincount(which[graze], minlength=len(pts)) > 0]
            if len(doubt):
                inside[doubt] = np.abs(_winding(p[doubt], self.v, self.tri)) > 0.5
            lo = hi
        return inside


class MeshSolid:
    """A mesh geometry's solid for many points at once, independently of the sphere generator's
    inside test: the union of its connected parts' solids (``genplan.spheres``' parts: identical
    vertices merged, degenerate triangles dropped), a closed and oriented part's by its ray
    crossings (:class:`_Crossings`; :meth:`genplan.spheres.LinkGeometry.contains`, the winding
    number of the whole mesh, agrees with it but for an open part). Built once per geometry: the cover
    check and the volume ratio ask it for hundreds of thousands of points, which the winding
    number alone (every point against every triangle) took minutes per robot for."""

    def __init__(self, geometry) -> None:
        from genplan.spheres import _mesh_solids

        self.geometry = geometry
        self.parts = [_Crossings(s.vertices, s.triangles, s.oriented) for s in _mesh_solids(geometry)]

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Which points (n, 3), in the link's frame, lie in the solid."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        inside = np.zeros(len(p), dtype=bool)
        for part in self.parts:
            rest = np.flatnonzero(~inside)
            inside[rest] = part.contains(p[rest])
        return inside


def solid_contains(geometry, points: np.ndarray) -> np.ndarray:
    """Which points (link frame) lie in a :class:`genplan.spheres.LinkGeometry`'s solid: a
    primitive's own test, a mesh's :class:`MeshSolid`."""
    if geometry.kind != "mesh":
        return geometry.contains(points)
    return MeshSolid(geometry).contains(points)


def surface_and_solid_points(geometry, n: int, rng: np.random.Generator) -> np.ndarray:
    """Points of one coal geometry in its own frame: on its surface and in its solid (a mesh's
    solid: :class:`MeshSolid`), with a mesh's vertices and points on its edges."""
    import coal

    from genplan.spheres import LinkGeometry

    g = geometry
    if isinstance(g, coal.Box):
        h = np.array(g.halfSide)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        surf = rng.uniform(-h, h, (n, 3))
        axis = rng.integers(0, 3, n)
        surf[np.arange(n), axis] = np.where(rng.uniform(size=n) < 0.5, -1, 1) * h[axis]
        return np.concatenate([corners, surf, rng.uniform(-h, h, (n, 3))])
    if isinstance(g, coal.Sphere):
        d = rng.normal(size=(2 * n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.concatenate([d[:n] * g.radius, d[n:] * g.radius * rng.uniform(size=(n, 1)) ** (1 / 3)])
    if isinstance(g, (coal.Cylinder, coal.Capsule)):
        r, h = g.radius, g.halfLength
        ang = rng.uniform(0, 2 * np.pi, (4, n))
        rad = r * np.sqrt(rng.uniform(size=(4, n)))
        z = rng.uniform(-h, h, (4, n))
        ends = np.where(rng.uniform(size=n) < 0.5, -h, h)
        side = np.c_[r * np.cos(ang[0]), r * np.sin(ang[0]), z[0]]
        solid = np.c_[rad[1] * np.cos(ang[1]), rad[1] * np.sin(ang[1]), z[1]]
        if isinstance(g, coal.Cylinder):
            caps = np.c_[rad[2] * np.cos(ang[2]), rad[2] * np.sin(ang[2]), ends]
            rims = np.c_[r * np.cos(ang[3]), r * np.sin(ang[3]), ends]
            return np.concatenate([side, solid, caps, rims])
        d = rng.normal(size=(2 * n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        caps = d[:n] * r + np.c_[np.zeros(n), np.zeros(n), np.where(d[:n, 2] > 0, h, -h)]
        balls = d[n:] * r * rng.uniform(size=(n, 1)) ** (1 / 3) + np.c_[np.zeros(n), np.zeros(n), ends]
        return np.concatenate([side, solid, caps, balls])
    v = np.array(g.vertices())
    t = np.array([[x[0], x[1], x[2]] for x in (g.tri_indices(i) for i in range(g.num_tris))])
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    k = rng.choice(len(t), size=n, p=area / area.sum())
    u, w = rng.uniform(size=(2, n))
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    surf = a[k] + u[:, None] * (b[k] - a[k]) + w[:, None] * (c[k] - a[k])
    e = rng.integers(0, len(t), n)
    edges = a[e] + rng.uniform(size=(n, 1)) * (b[e] - a[e])
    box = rng.uniform(v.min(axis=0), v.max(axis=0), (n, 3))
    mesh = LinkGeometry("probe", "probe", "mesh", (), np.eye(4), v, t)
    return np.concatenate([v, surf, edges, box[MeshSolid(mesh).contains(box)]])


def cover_check(robot: genplan.Robot, spheres, n: int, rng: np.random.Generator) -> dict:
    """The largest distance of a geometry point outside its link's spheres (radii without the
    padding): <= 0 when every point is covered."""
    import pinocchio as pin

    geom = robot.collision_model
    data = pin.GeometryData(geom)
    q = robot.q_default
    pin.framesForwardKinematics(robot.model, robot.data, q)
    pin.updateGeometryPlacements(robot.model, robot.data, geom, data, q)
    worst, count = -np.inf, 0
    for i, go in enumerate(geom.geometryObjects):
        link = robot.model.frames[go.parentFrame].name
        to_link = np.linalg.inv(robot.link_poses(q, [link])[0]) @ data.oMg[i].homogeneous
        p = surface_and_solid_points(go.geometry, n, rng) @ to_link[:3, :3].T + to_link[:3, 3]
        mine = np.array([x == link for x in spheres.links])
        c, r = spheres.centers[mine], spheres.radii[mine] - spheres.padding
        for lo in range(0, len(p), 20000):
            d = np.linalg.norm(p[lo:lo + 20000, None] - c[None], axis=2) - r[None]
            worst = max(worst, float(d.min(axis=1).max()))
        count += len(p)
    return {"points": count, "max_outside_m": worst, "covered": bool(worst <= 1e-12)}


def volume_ratio(robot: genplan.Robot, spheres, rng: np.random.Generator, n: int = 200_000) -> float:
    """Sum over links of the union of its spheres' volume over its solid's (Monte Carlo)."""
    from genplan.spheres import link_geometries

    geoms = link_geometries(robot)
    v_spheres, v_solid = 0.0, 0.0
    for link in spheres.link_names:
        mine = np.array([x == link for x in spheres.links])
        c, r = spheres.centers[mine], spheres.radii[mine]
        lo, hi = (c - r[:, None]).min(axis=0), (c + r[:, None]).max(axis=0)
        p = rng.uniform(lo, hi, (n, 3))
        in_s = np.zeros(n, dtype=bool)
        for k in range(len(r)):
            in_s |= np.linalg.norm(p - c[k], axis=1) <= r[k]
        in_g = np.zeros(n, dtype=bool)
        for g in geoms:
            if g.link == link:
                in_g |= solid_contains(g, p)
        box = float(np.prod(hi - lo))
        v_spheres += box * in_s.mean()
        v_solid += box * in_g.mean()
    return v_spheres / v_solid


def box_distance(points: np.ndarray, center: np.ndarray, rotation: np.ndarray, half: np.ndarray) -> np.ndarray:
    q = np.abs((points - center) @ rotation) - half
    return np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(axis=-1), 0)


def against_coal(robot: genplan.Robot, spheres, n: int, rng: np.random.Generator, scenes: int = 10) -> dict:
    import coal
    import pinocchio as pin

    missed = coal_contacts = sphere_contacts = false_pos = 0
    per_scene = max(1, n // scenes)
    links = list(robot.kinematics.link_names)
    for _ in range(scenes):
        geom = robot.collision_model.copy()
        n_robot = geom.ngeoms
        q0 = robot.random_configurations(1, rng)[0]
        where = robot.link_poses(q0)[:, :3, 3]
        boxes = []
        for k in range(3):
            half = rng.uniform(0.02, 0.1, 3)
            center = where[rng.integers(0, len(links))] + rng.uniform(-0.1, 0.1, 3)
            rot = pin.exp3(rng.normal(size=3))
            boxes.append((center, rot, half))
            geom.addGeometryObject(pin.GeometryObject(f"box{k}", 0, 0, pin.SE3(rot, center), coal.Box(*(2 * half))))
        geom.removeAllCollisionPairs()
        for i in range(n_robot):
            for j in range(n_robot, geom.ngeoms):
                geom.addCollisionPair(pin.CollisionPair(i, j))
        data = pin.GeometryData(geom)
        qs = robot.random_configurations(per_scene, rng)
        ref = np.array([pin.computeCollisions(robot.model, robot.data, geom, data, q, True) for q in qs])
        ours = np.zeros(len(qs), dtype=bool)
        for lo in range(0, len(qs), 1000):  # (1000, S, 3) centres at a time: memory
            centers = spheres.world_centers(robot, qs[lo:lo + 1000])
            for center, rot, half in boxes:
                ours[lo:lo + 1000] |= np.any(box_distance(centers, center, rot, half) <= spheres.radii, axis=1)
        coal_contacts += int(ref.sum())
        sphere_contacts += int(ours.sum())
        missed += int((ref & ~ours).sum())
        false_pos += int((ours & ~ref).sum())
    total = per_scene * scenes
    free = total - coal_contacts
    return {"configurations": total, "coal_contacts": coal_contacts, "sphere_contacts": sphere_contacts,
            "missed": missed, "false_positives": false_pos,
            "false_positive_rate": false_pos / free if free else None}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--robots", nargs="+", default=["panda", "ur5", "kinova", "xarm7"],
                        help="presets, xarm7 or URDF paths; NAME:MAX_ERROR (m) for another max_error than --max-error")
    parser.add_argument("--max-error", type=float, default=None, help="m; the generator's default if not given")
    parser.add_argument("--configurations", type=int, default=2000)
    parser.add_argument("--points", type=int, default=20000, help="cover check points per geometry and kind")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "spheres.json")
    parser.add_argument("--cache", action="store_true",
                        help="use $GENPLAN_CACHE (spheres generated before are read: generation_s is then "
                             "the read's time, and cached_from_disk true) instead of an empty temporary one")
    args = parser.parse_args()

    from genplan import spheres as sph

    rows = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as cache:
        old = os.environ.get("GENPLAN_CACHE")
        if not args.cache:
            os.environ["GENPLAN_CACHE"] = cache
        try:
            for entry in args.robots:
                name, _, given = entry.rpartition(":") if ":" in entry else (entry, "", "")
                max_error = float(given) if given else args.max_error
                kwargs = {} if max_error is None else {"max_error": max_error}
                robot = load_robot(name)
                robot.collision_model  # read the meshes before the clock starts
                rng = np.random.default_rng(args.seed)
                t0 = time.perf_counter()
                spheres = sph.robot_spheres(robot, **kwargs)
                generation = time.perf_counter() - t0
                sph.clear_cache()
                t0 = time.perf_counter()
                again = sph.robot_spheres(robot, **kwargs)
                cached = time.perf_counter() - t0
                assert again == spheres
                row = {
                    "robot": robot.name, "spheres": len(spheres), "per_link": spheres.counts(),
                    "max_error_m": spheres.max_error, "resolution_m": spheres.resolution,
                    "link_max_error_m": dict(spheres.link_max_error),
                    "padding_m": spheres.padding, "generation_s": round(generation, 2),
                    "cached_from_disk": spheres.generation_s == 0.0,
                    "cached_load_s": round(cached, 4),
                    "cover": cover_check(robot, spheres, args.points, rng),
                    "excess_max_m": float(spheres.excess.max()), "excess_mean_m": float(spheres.excess.mean()),
                    "volume_ratio": round(volume_ratio(robot, spheres, rng), 3),
                    "coal": against_coal(robot, spheres, args.configurations, rng),
                }
                rows.append(row)
                c = row["coal"]
                print(f"{robot.name:7s} {spheres.max_error * 100:.0f} cm {row['spheres']:4d} spheres  generated {generation:7.1f} s  cached {cached * 1e3:6.1f} ms  "
                      f"cover {'ok' if row['cover']['covered'] else 'FAILED'} ({row['cover']['points']} points, "
                      f"max outside {row['cover']['max_outside_m']:.2e} m)  excess max {row['excess_max_m'] * 1e3:.1f} mm "
                      f"mean {row['excess_mean_m'] * 1e3:.1f} mm  volume x{row['volume_ratio']}  "
                      f"coal: {c['coal_contacts']}/{c['configurations']} in contact, missed {c['missed']}, "
                      f"false positives {c['false_positive_rate']:.1%}", flush=True)
        finally:
            if old is None:
                os.environ.pop("GENPLAN_CACHE", None)
            else:
                os.environ["GENPLAN_CACHE"] = old
    out = {"machine": platform.machine(), "cpus": os.cpu_count(), "load_1min_before": load_before,
           "load_1min_after": os.getloadavg()[0], "seed": args.seed, "configurations": args.configurations,
           "points": args.points, "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from genplan._files import write_text

    write_text(args.out, json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
