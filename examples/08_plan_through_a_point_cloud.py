"""Plan through what a depth camera sees: the Panda shelf scene (a table, a bookshelf, the floor)
rendered by simulated depth cameras, the images turned into one point cloud
(``genplan.clouds.points_from_depth``), down-sampled to one point per 1 cm voxel, and that cloud
as the only obstacle besides the floor; the paper's shelf queries planned through it with every
state checked against the cloud, then every state and the motions between them checked afterwards against the true scene. Then the
bookshelf as ONE non-convex triangle mesh (kept as a mesh, not its hull) planned through.

    python examples/08_plan_through_a_point_cloud.py [--queries 5] [--width 320 --height 240]

Prints one row per world: what it holds, the plans' success, and how many of the plans' states
(and of the states sampled every ``--check-step`` rad along each motion between them) touch the
true scene. Nothing is downloaded; the cameras are pinhole ray casts of the scene's boxes (as
trimesh meshes) written here with numpy.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import trimesh  # noqa: E402

import genplan  # noqa: E402
from genplan.clouds import points_from_depth  # noqa: E402
from genplan.planning import Planner, PlannerSettings, environment  # noqa: E402
from genplan.scene import Box, HalfSpace, Mesh, Pose, Scene  # noqa: E402

# Three cameras (position, the point they look at), as a cell's fixed sensors: one facing the
# shelf's open side, one over the table, one above the shelf looking down into it.
CAMERAS = (((-0.2, -0.7, 0.7), (-0.2, 0.8, 0.35)),
           ((1.7, -0.3, 1.1), (0.4, 0.2, 0.1)),
           ((0.6, 0.2, 1.9), (-0.2, 0.8, 0.3)))
FIELD_OF_VIEW = np.radians(70.0)  # horizontal
MAX_RANGE = 4.0                   # m; the scene's boxes are all closer


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World from camera (4x4) in the optical frame (z forward, x right, y down), world z up."""
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    pose[:3, 3] = eye
    return pose


def render_depth(triangles: np.ndarray, pose: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """A pinhole depth image (z along the optical axis, 0 where no triangle is hit) of
    ``triangles`` (m, 3, 3) and its intrinsics (fx, fy, cx, cy): Moller-Trumbore, every pixel's
    ray against every triangle."""
    f = 0.5 * width / np.tan(0.5 * FIELD_OF_VIEW)
    k = np.array([f, f, (width - 1) / 2, (height - 1) / 2])
    v, u = np.mgrid[0:height, 0:width]
    rays_cam = np.stack([(u.ravel() - k[2]) / f, (v.ravel() - k[3]) / f, np.ones(u.size)], axis=1)
    dirs = rays_cam @ pose[:3, :3].T  # z = 1 along the axis: the hit's t is its depth
    origin = pose[:3, 3]
    a, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    depth = np.full(len(dirs), np.inf)
    for lo in range(0, len(dirs), 4096):
        d = dirs[lo:lo + 4096, None, :]
        p = np.cross(d, e2)
        det = np.einsum("rtk,tk->rt", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = origin - a
            bu = np.einsum("rtk,tk->rt", p, s) * inv
            qv = np.cross(s, e1)
            bv = np.einsum("rk,tk->rt", d[:, 0], qv) * inv
            t = (qv * e2).sum(axis=1) * inv
        hit = (np.abs(det) > 1e-12) & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (t > 1e-6)
        depth[lo:lo + 4096] = np.where(hit, t, np.inf).min(axis=1)
    return np.where(np.isfinite(depth), depth, 0.0).reshape(height, width), k


def box_mesh(b: Box) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=2.0 * np.asarray(b.half_extents))
    t = np.eye(4)
    t[:3, :3] = b.pose.matrix()
    t[:3, 3] = b.pose.position
    return m.apply_transform(t)


def shelf_as_one_mesh(boxes: list[Box], folder: Path) -> Path:
    """The bookshelf (five boards between two side panels) as one non-convex OBJ: the boards cut
    back to the panels' inner faces so that the seven closed parts meet without overlapping (the
    same solid as the seven boxes)."""
    sides = [b for b in boxes if b.name.startswith("shelf_side")]
    inner = sorted(float(s.pose.position[0]) for s in sides)
    half = float(sides[0].half_extents[0])
    lo, hi = inner[0] + half, inner[1] - half
    parts = [box_mesh(s) for s in sides]
    for b in boxes:
        if b.name.startswith("shelf_board"):
            c = np.asarray(b.pose.position, dtype=float)
            h = np.asarray(b.half_extents, dtype=float)
            parts.append(box_mesh(Box(b.name, ((hi - lo) / 2, h[1], h[2]), Pose(((lo + hi) / 2, c[1], c[2])))))
    path = folder / "shelf.obj"
    trimesh.util.concatenate(parts).export(path)
    return path


def motion_samples(path: np.ndarray, step: float) -> np.ndarray:
    """The states every ``step`` (rad, largest joint) along each straight motion of ``path``."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        out.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.concatenate(out)


def draw(robot: genplan.Robot, path: np.ndarray, cloud: np.ndarray, out: Path) -> Path | None:
    """The plan and the camera points in one HTML view (None without viser)."""
    try:
        from genplan.viewer import export_html

        return export_html(robot, path, out, clouds={"camera": cloud}, halfspaces=[("floor", (0, 0, 1), -0.5)])
    except ImportError:
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--queries", type=int, default=5, help="shelf queries to plan in each world (default 5)")
    parser.add_argument("--width", type=int, default=320, help="depth image width (pixels; default 320)")
    parser.add_argument("--height", type=int, default=240, help="depth image height (pixels; default 240)")
    parser.add_argument("--voxel", type=float, default=0.01, help="voxel edge and ball radius (m; default 0.01)")
    parser.add_argument("--thin-radius", type=float, default=0.0045,
                        help="the ball radius of the second cloud (m; default 0.0045: below the queries' 5 mm)")
    parser.add_argument("--check-step", type=float, default=0.002,
                        help="rad between the states checked along each motion of a plan (default 0.002)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out-dir", type=Path, default=None,
                        help="write cloud.npz (the camera points) and, with viser installed, cloud_plan.html (the "
                             "first plan through the thin cloud, the cloud drawn) here")
    args = parser.parse_args()

    panda = genplan.load("panda")
    env = environment("panda_shelf")
    boxes = [o for o in env.scene.obstacles if isinstance(o, Box)]
    floor = next(o for o in env.scene.obstacles if isinstance(o, HalfSpace))
    truth = env.world(panda)

    # the cameras: depth images of the boxes, their points in the world frame
    triangles = np.concatenate([box_mesh(b).triangles for b in boxes])
    t0 = time.perf_counter()
    clouds = []
    for eye, target in CAMERAS:
        pose = look_at(np.asarray(eye, dtype=float), np.asarray(target, dtype=float))
        depth, intrinsics = render_depth(triangles, pose, args.width, args.height)
        clouds.append(points_from_depth(depth, intrinsics, pose, max_range=MAX_RANGE))
    cloud = np.concatenate(clouds)
    render_s = time.perf_counter() - t0
    if args.out_dir is not None:
        args.out_dir.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.out_dir / "cloud.npz", points=cloud)

    # the cloud as the obstacle, the floor a known plane; each voxel's centroid a ball of radius r:
    # r = the voxel's edge covers the surface points of its voxel (a conservative cloud), but then a
    # state closer to a surface than r collides: the shelf queries start 5 mm above the table, so a
    # cloud of balls below 5 mm keeps them (and no longer covers everything the camera saw)
    clouds_by_radius = {}
    for radius in (args.thin_radius, args.voxel):
        seen = panda.collision_world()
        seen.add_halfspace(floor.name, floor.normal, floor.offset)
        balls = seen.add_points("camera", cloud, radius=radius, voxel=args.voxel)
        clouds_by_radius[radius] = (seen, balls)

    with tempfile.TemporaryDirectory() as tmp:
        shelf = shelf_as_one_mesh(boxes, Path(tmp))
        faces = len(trimesh.load_mesh(shelf).faces)
        kept = tuple(o for o in env.scene.obstacles if not o.name.startswith("shelf_"))
        mesh_world = panda.collision_world()
        mesh_world.add_scene(Scene("panda_shelf_mesh", (*kept, Mesh("shelf", shelf, shape="mesh"))))

    print(f"cameras: {len(CAMERAS)} of {args.width}x{args.height} pixels, {len(cloud)} points in "
          f"{render_s:.1f} s; voxel {100 * args.voxel:g} cm: {balls} balls")
    worlds = {"primitives (the truth)": (truth, f"{len(boxes)} boxes + floor")}
    for radius, (seen, balls) in clouds_by_radius.items():
        worlds[f"cloud, r {1000 * radius:g} mm"] = (seen, f"{balls} balls + floor")
    worlds |= {
              "shelf as one mesh": (mesh_world, f"table + {faces} triangles + floor")}
    # edges checked at the planner's resolution (certified edges refuse the thin cloud's plans: its
    # balls reach within 0.1 mm of the starts, too little clearance to certify a motion from there)
    settings = PlannerSettings(simplify=True)
    queries = env.queries(panda, n=args.queries, seed=args.seed)
    html = None
    print(f"{'world':<24} {'obstacles':<30} {'planned':>8} {'refused':>7} {'states':>7} {'touching':>9} "
          f"{'motion samples':>15} {'touching':>9} {'s/plan':>7}")
    for label, (world, what) in worlds.items():
        planner = Planner(panda, world=world, sampler="gan", settings=settings, seed=args.seed)
        ok = refused = states = touching = samples = touching_samples = 0
        first = None
        t0 = time.perf_counter()
        for query in queries:
            try:
                result = planner.plan(query.start, query.goals)
            except (genplan.errors.InvalidStartError, genplan.errors.InvalidGoalError):
                refused += 1  # the start, or every goal, touches this world's obstacles
                continue
            if not result.success:
                continue
            ok += 1
            path = np.asarray(result.path)
            first = path if first is None else first
            dense = motion_samples(path, args.check_step)
            states += len(path)
            samples += len(dense)
            touching += int(np.sum(truth.in_collision(path)))
            touching_samples += int(np.sum(truth.in_collision(dense)))
        per_plan = (time.perf_counter() - t0) / max(1, len(queries))
        print(f"{label:<24} {what:<30} {ok:>4} of {len(queries):<2} {refused:>7} {states:>7} {touching:>9} "
              f"{samples:>15} {touching_samples:>9} {per_plan:>7.2f}")
        if args.out_dir is not None and label.startswith("cloud, r") and first is not None and html is None:
            html = draw(panda, first, cloud, args.out_dir / "cloud_plan.html")
    if html is not None:
        print(f"the first plan through the cloud, the cloud drawn: {html}")
    print(f"(refused: the start or every goal in contact with that world's obstacles; touching: states in contact "
          f"with the true scene, the plans' own and those every {args.check_step} rad along their motions)")


if __name__ == "__main__":
    main()
