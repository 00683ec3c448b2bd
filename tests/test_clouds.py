"""genplan.clouds: point-cloud files (.npz, .ply ASCII and binary, .pcd ASCII and binary), depth
images to world points, a camera on a robot link, and the checks every cloud goes through; the
clouds as obstacles of a world (CollisionWorld.add_points / replace_points / robot_points) and
as [[points]] in scene files."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan.clouds import camera_pose, check_points, points_from_depth, read_points
from genplan.errors import NonFiniteError, SceneFileError, SettingsError, ShapeError
from genplan.scene import Points, Scene


@pytest.fixture(scope="module")
def panda() -> genplan.Robot:
    return genplan.load("panda")


def _cloud(n: int = 50, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1, 1, (n, 3))


def _ply(path, pts: np.ndarray, fmt: str) -> None:
    head = (f"ply\nformat {fmt} 1.0\ncomment made by a test\nelement vertex {len(pts)}\n"
            "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "element face 0\nproperty list uchar int vertex_indices\nend_header\n")
    if fmt == "ascii":
        body = "".join(f"{x} {y} {z} 7\n" for x, y, z in pts).encode()
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        rec = np.zeros(len(pts), dtype=[("x", order + "f4"), ("y", order + "f4"), ("z", order + "f4"), ("r", "u1")])
        rec["x"], rec["y"], rec["z"] = pts.T
        body = rec.tobytes()
    path.write_bytes(head.encode() + body)


def _pcd(path, pts: np.ndarray, data: str) -> None:
    head = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
            f"WIDTH {len(pts)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA {data}\n")
    if data == "ascii":
        body = "".join(f"{x} {y} {z} 0\n" for x, y, z in pts).encode()
    else:
        full = np.zeros((len(pts), 4), dtype="<f4")
        full[:, :3] = pts
        body = full.tobytes()
    path.write_bytes(head.encode() + body)


@pytest.mark.parametrize("kind", ["npz", "ply-ascii", "ply-le", "ply-be", "pcd-ascii", "pcd-binary"])
def test_every_file_format_reads_back_its_points(tmp_path, kind: str) -> None:
    pts = _cloud(40).astype(np.float32).astype(np.float64)
    if kind == "npz":
        path = tmp_path / "c.npz"
        np.savez(path, points=pts)
    elif kind.startswith("ply"):
        path = tmp_path / "c.ply"
        _ply(path, pts, {"ply-ascii": "ascii", "ply-le": "binary_little_endian", "ply-be": "binary_big_endian"}[kind])
    else:
        path = tmp_path / "c.pcd"
        _pcd(path, pts, kind.split("-")[1])
    got = read_points(path)
    np.testing.assert_allclose(got, pts, atol=1e-6)


def test_bad_files_name_the_file(tmp_path) -> None:
    with pytest.raises(FileNotFoundError):
        read_points(tmp_path / "none.ply")
    (tmp_path / "a.xyz").write_text("1 2 3\n")
    with pytest.raises(SceneFileError, match="a.xyz"):
        read_points(tmp_path / "a.xyz")
    np.savez(tmp_path / "b.npz", other=np.zeros((3, 3)))
    with pytest.raises(SceneFileError, match="no array named 'points'"):
        read_points(tmp_path / "b.npz")
    (tmp_path / "c.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\n"
                                     b"property float y\nproperty float z\nend_header\n" + b"\0" * 12)
    with pytest.raises(SceneFileError, match="c.ply.*10 vertices declared"):
        read_points(tmp_path / "c.ply")
    (tmp_path / "d.pcd").write_text("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n")
    with pytest.raises(SceneFileError, match="binary_compressed"):
        read_points(tmp_path / "d.pcd")
    np.savez(tmp_path / "e.npz", points=np.zeros((0, 3)))
    with pytest.raises(SceneFileError, match="empty"):
        read_points(tmp_path / "e.npz")


def test_points_are_checked_naming_the_field_and_row() -> None:
    with pytest.raises(ShapeError, match="cloud.*shape \\(n, 3\\)"):
        check_points(np.zeros((4, 2)), "cloud")
    with pytest.raises(ShapeError, match="empty"):
        check_points(np.zeros((0, 3)), "cloud")
    bad = _cloud(5)
    bad[3, 1] = np.nan
    with pytest.raises(NonFiniteError, match="row 3 \\(column 1\\)"):
        check_points(bad, "cloud")


def test_a_depth_image_gives_the_points_it_saw() -> None:
    # a camera 1 m above the origin looking down (optical z = world -z, x right = world x)
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = [0.0, 0.0, 1.0]
    k = (100.0, 100.0, 2.0, 1.0)
    depth = np.full((3, 5), 0.8)
    depth[0, 0] = 0.0
    depth[1, 1] = np.nan
    depth[2, 4] = 5.0  # beyond the range
    pts = points_from_depth(depth, k, pose, max_range=2.0)
    assert pts.shape == (12, 3)
    np.testing.assert_allclose(pts[:, 2], 0.2)
    # the principal point (u=2, v=1) lies on the optical axis: straight below the camera
    centre = pts[np.argmin(np.linalg.norm(pts[:, :2], axis=1))]
    np.testing.assert_allclose(centre, [0.0, 0.0, 0.2], atol=1e-12)
    # u to the right is +x; v down (image row) is world -y under this pose
    right = points_from_depth(np.pad([[0.8]], ((1, 1), (3, 1))), k, pose)
    np.testing.assert_allclose(right[0], [0.008, 0.0, 0.2], atol=1e-12)
    # 16-bit millimetres
    mm = points_from_depth(np.full((3, 5), 800, dtype=np.uint16), k, pose, depth_scale=0.001)
    np.testing.assert_allclose(mm[:, 2], 0.2)


def test_bad_depth_input_is_refused_before_any_work() -> None:
    k, pose = (100.0, 100.0, 2.0, 1.0), np.eye(4)
    with pytest.raises(ShapeError, match="depth.*\\(h, w\\)"):
        points_from_depth(np.ones((3, 5, 1)), k, pose)
    with pytest.raises(ShapeError, match="depth.*dtype"):
        points_from_depth(np.ones((3, 5), dtype=complex), k, pose)
    with pytest.raises(ShapeError, match="intrinsics"):
        points_from_depth(np.ones((3, 5)), (1.0, 2.0, 3.0), pose)
    with pytest.raises(SettingsError, match="intrinsics"):
        points_from_depth(np.ones((3, 5)), (0.0, 100.0, 2.0, 1.0), pose)
    with pytest.raises(ShapeError, match="camera_pose"):
        points_from_depth(np.ones((3, 5)), k, np.eye(3))
    with pytest.raises(SettingsError, match="camera_pose"):
        points_from_depth(np.ones((3, 5)), k, 2 * np.eye(4))
    with pytest.raises(SettingsError, match="max_range"):
        points_from_depth(np.ones((3, 5)), k, pose, max_range=-1.0)


def test_a_camera_on_a_link_follows_the_link(panda) -> None:
    q = panda.random_configurations(1, 3)[0]
    mount = np.eye(4)
    mount[:3, 3] = [0.0, 0.0, 0.05]
    link = panda.kinematics.link_names[-1]
    pose = camera_pose(panda, q, link, mount)
    np.testing.assert_allclose(pose, panda.link_poses(q, [link])[0] @ mount)


def test_a_cloud_is_an_obstacle_and_a_new_frame_replaces_it(panda) -> None:
    w = panda.collision_world()
    w.check_self = False
    q = panda.random_configurations(1, 5)[0]
    # a point on the robot: the first link origin that lies in its geometry
    origins = panda.link_poses(q)[:, :3, 3]
    on = origins[w.robot_points(origins, q, 0.0)]
    assert len(on) > 0
    far = _cloud(100) + [3.0, 3.0, 3.0]
    assert w.add_points("cam", far, 0.01) == 100
    assert not w.in_collision(q)
    d_far = w.min_distance(q)
    frame = np.vstack([far, on[:1]])
    w.replace_points("cam", frame)
    assert w.in_collision(q) and w.min_distance(q) < 0 < d_far
    assert w.obstacle_names == ["cam"] and w.clouds["cam"] == (0.01, None, 101)
    # the robot's own points dropped: the robot's point goes, the far ones stay
    assert w.replace_points("cam", frame, robot_q=q) == 100
    assert not w.in_collision(q)
    mask = w.robot_points(frame, q, 0.0)
    assert mask[-1] and not mask[:-1].any()
    # a bad frame leaves the old one
    with pytest.raises(NonFiniteError):
        w.replace_points("cam", np.array([[0.0, np.nan, 0.0]]))
    assert w.clouds["cam"][2] == 100
    with pytest.raises(genplan.errors.UnknownNameError):
        w.replace_points("nope", far)


def test_bad_clouds_are_refused_naming_the_field(panda) -> None:
    w = panda.collision_world()
    with pytest.raises(ShapeError, match="points 'c' points.*empty"):
        w.add_points("c", np.zeros((0, 3)), 0.01)
    with pytest.raises(ShapeError, match="points 'c' points.*\\(n, 3\\)"):
        w.add_points("c", np.zeros((5, 2)), 0.01)
    with pytest.raises(NonFiniteError, match="row 1"):
        w.add_points("c", [[0, 0, 0], [np.nan, 0, 0]], 0.01)
    with pytest.raises(SettingsError, match="radius"):
        w.add_points("c", _cloud(), -0.01)
    with pytest.raises(SettingsError, match="voxel"):
        w.add_points("c", _cloud(), 0.01, voxel=0.0)
    assert w.obstacle_names == []


def test_voxels_down_sample_the_cloud(panda) -> None:
    w = panda.collision_world()
    pts = np.random.default_rng(1).uniform(0, 0.1, (5000, 3))
    n = w.add_points("c", pts, 0.01, voxel=0.05)
    assert n == len(np.unique(np.floor(pts / 0.05), axis=0)) == 8


def test_points_in_scene_files_round_trip_and_reach_the_world(tmp_path, panda) -> None:
    np.savez(tmp_path / "cam.npz", points=np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]))
    (tmp_path / "s.toml").write_text(
        'name = "s"\n\n[[points]]\nname = "cam"\npath = "cam.npz"\nradius = 0.02\nvoxel = 0.01\nposition = [5.0, 0.0, 0.0]\n\n'
        '[[points]]\nname = "few"\npoints = [[0.0, 5.0, 0.0]]\nradius = 0.05\n')
    s = Scene.from_file(tmp_path / "s.toml")
    assert [o.name for o in s.obstacles] == ["cam", "few"]
    np.testing.assert_allclose(s.obstacles[0].world_points(), [[5.0, 0.0, 0.0], [5.1, 0.0, 0.0]])
    s.to_file(tmp_path / "t.toml")
    assert Scene.from_file(tmp_path / "t.toml") == s
    w = panda.collision_world()
    assert w.add_scene(s) == ["cam", "few"]
    assert w.clouds == {"cam": (0.02, 0.01, 2), "few": (0.05, None, 1)}


@pytest.mark.parametrize("row, match", [
    ('path = "cam.npz"\npoints = [[0.0, 0.0, 0.0]]\nradius = 0.1', "exactly one of path and points"),
    ('radius = 0.1', "exactly one of path and points"),
    ('points = []\nradius = 0.1', "empty"),
    ('points = [[0.0, "x", 0.0]]\nradius = 0.1', "points\\[0\\]\\[1\\]"),
    ('points = [[0.0, 0.0, 0.0]]\nradius = -0.1', "radius"),
    ('points = [[0.0, 0.0, 0.0]]\nradius = 0.1\nvoxel = 0.0', "voxel"),
    ('path = "missing.ply"\nradius = 0.1', "does not exist"),
    ('path = "cam.txt"\nradius = 0.1', "not a point-cloud file"),
])
def test_bad_points_tables_name_the_file_and_field(tmp_path, row: str, match: str) -> None:
    np.savez(tmp_path / "cam.npz", points=np.zeros((1, 3)))
    (tmp_path / "s.toml").write_text(f'name = "s"\n\n[[points]]\nname = "cam"\n{row}\n')
    with pytest.raises(SceneFileError, match=match) as info:
        Scene.from_file(tmp_path / "s.toml")
    assert "s.toml" in str(info.value)


def test_a_bad_points_file_fails_add_scene_all_or_nothing(tmp_path, panda) -> None:
    (tmp_path / "bad.ply").write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n2\n")
    s = Scene("s", (genplan.scene.Sphere("ball", 0.1), Points("cam", radius=0.01, path=tmp_path / "bad.ply")))
    w = panda.collision_world()
    with pytest.raises(SceneFileError, match="points 'cam'.*bad.ply.*'y'"):
        w.add_scene(s)
    assert w.obstacle_names == []


def test_the_sphere_checker_meets_a_cloud_as_its_balls(panda) -> None:
    from genplan.planning import Planner, sphere_checker

    rng = np.random.default_rng(4)
    # a wall in front of the arm and a few points in the air
    pts = np.column_stack([np.full(300, 0.6), rng.uniform(-0.4, 0.4, 300), rng.uniform(0.1, 0.9, 300)])
    pts[::30] = rng.uniform([-0.8, -0.8, 0.0], [0.8, 0.8, 1.0], (10, 3))
    cloud = panda.collision_world()
    cloud.add_points("cam", pts, 0.02)
    balls = panda.collision_world()
    for k, p in enumerate(pts):
        balls.add_sphere(f"p{k}", 0.02, p)
    qs = panda.random_configurations(400, 6)
    by_cloud = np.asarray(sphere_checker(panda, cloud).in_collision(qs))
    np.testing.assert_array_equal(by_cloud, sphere_checker(panda, balls).in_collision(qs))
    assert 0 < by_cloud.sum() < len(qs)
    # the spheres cover the links: free by them is free by the exact geometry
    exact = np.asarray(cloud.in_collision(qs))
    assert not (exact & ~by_cloud).any()
    # a planner takes the cloud world with the sphere checker
    Planner(panda, world=cloud, task="free", checker="spheres")
