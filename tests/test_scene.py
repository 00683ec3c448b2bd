"""genplan.scene: scene files (docs/SCENES.md) read, written and checked, and
CollisionWorld.add_scene / add_cylinder / add_capsule / add_mesh: obstacles where the file puts
them, all or nothing."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import scene as S
from genplan.errors import NonFiniteError, RobotFileError, SceneFileError, ShapeError, UnknownNameError
from genplan.scene import Box, Capsule, Cylinder, HalfSpace, Mesh, Pose, Scene, Sphere

#: an OBJ cube of side 1 centred at the origin
CUBE_OBJ = """v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""

#: a Panda configuration with the hand in front of the robot, away from its base
Q_READY = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


@pytest.fixture
def cube(tmp_path: Path) -> Path:
    p = tmp_path / "meshes" / "cube.obj"
    p.parent.mkdir()
    p.write_text(CUBE_OBJ)
    return p


def every_shape(cube: Path) -> Scene:
    return Scene(
        name="bench",
        description="one of each",
        obstacles=(
            HalfSpace("floor", (0.0, 0.0, 1.0), -0.3),
            Mesh("crate", cube, (0.4, 0.2, 0.2), Pose((0.6, -0.4, 0.3), quaternion=(0.0, 0.0, math.sin(0.3), math.cos(0.3)))),
            Box("table", (0.3, 0.4, 0.02), Pose((0.6, 0.0, 0.1))),
            Sphere("ball", 0.05, Pose((0.4, 0.4, 0.6))),
            Cylinder("post", 0.03, 0.8, Pose((0.3, -0.5, 0.4), rpy=(0.1, 0.2, 0.3))),
            Capsule("rail", 0.02, 0.5, Pose((-0.3, 0.3, 0.5), rotation=pin.rpy.rpyToMatrix(0.0, math.pi / 2, 0.0).tolist())),
            Box("shelf", (0.2, 0.1, 0.01), Pose((-0.4, 0.0, 0.8), rpy=(0.0, 0.0, 0.7))),
        ),
    )


# --- data and files


def test_scenes_round_trip_through_dicts_and_files(tmp_path: Path, cube: Path) -> None:
    scene = every_shape(cube)
    # kept grouped by shape, in the order of SHAPES, each group in the order given
    assert scene.obstacle_names == ["table", "shelf", "ball", "post", "rail", "crate", "floor"]
    assert Scene.from_dict(scene.to_dict()) == scene
    path = scene.to_file(tmp_path / "out" / "bench.toml")
    assert Scene.from_file(path) == scene
    text = path.read_text()
    assert tomllib.loads(text)["mesh"][0]["path"] == "../meshes/cube.obj", "mesh paths are relative to the file"
    assert 'rpy = [0.1, 0.2, 0.3]' in text and "quaternion = " in text and "rotation = [[" in text
    assert not [p for p in path.parent.iterdir() if p != path], "the atomic write leaves no temporary file"
    # written again from what was read: the same text
    again = Scene.from_file(path).to_file(tmp_path / "out" / "again.toml")
    assert again.read_text() == text
    # the source is remembered but is not part of equality
    assert Scene.from_file(path).source == path and scene.source is None


def test_file_forms_size_scale_and_rotations(tmp_path: Path, cube: Path) -> None:
    (tmp_path / "s.toml").write_text(f"""
description = "forms"
[[box]]
name = "b"
size = [0.2, 0.4, 0.6]
position = [1, 2, 3]
[[mesh]]
name = "m"
path = "{cube.relative_to(tmp_path).as_posix()}"
scale = 0.5
[[cylinder]]
name = "c"
radius = 0.1
length = 1
position = [0, 0, 0]
rpy = [0.3, -0.2, 1.0]
""")
    s = Scene.from_file(tmp_path / "s.toml")
    assert s.name == "s", "the name defaults to the file's stem"
    b, c, m = s.obstacles
    assert b.half_extents == (0.1, 0.2, 0.3) and b.pose.position == (1.0, 2.0, 3.0) and not b.pose.rotated
    assert m.path == cube and m.scale == (0.5, 0.5, 0.5)
    assert c.length == 1.0 and isinstance(c.radius, float)
    # rpy is URDF's convention (Pinocchio's rpyToMatrix), quaternions (x, y, z, w) as Pinocchio's
    assert np.allclose(c.pose.matrix(), pin.rpy.rpyToMatrix(0.3, -0.2, 1.0), atol=1e-15)
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.3, -0.2, 1.0))
    q = Pose(quaternion=(quat.x, quat.y, quat.z, quat.w))
    assert np.allclose(q.matrix(), c.pose.matrix(), atol=1e-12)
    assert np.array_equal(Pose().matrix(), np.eye(3))


def _scene_file(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text(body)
    return p


@pytest.mark.parametrize(("body", "match"), [
    ('name = "x"\ncolour = "red"\n', r"bad.toml: unknown key 'colour' \(known: name, description, box, sphere"),
    ('name = "x"\n[[cone]]\nname = "c"\n', r"bad.toml: unknown shape table \[\[cone\]\] \(known shapes: box, sphere, cylinder, capsule, mesh, halfspace, points\)"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\ncolor = 1\n', r"bad.toml: \[\[box\]\] 1: unknown key 'color' \(known: name, half_extents, size, padding, position, rpy, quaternion, rotation\)"),
    ('[[sphere]]\nname = "s"\nposition = [0, 0, 0]\n', r"bad.toml: \[\[sphere\]\] 1: missing field 'radius'"),
    ('[[sphere]]\nradius = 1.0\n', r"bad.toml: \[\[sphere\]\] 1: missing field 'name'"),
    ('[[box]]\nname = "b"\nposition = [0, 0, 0]\n', r"missing field 'half_extents' \(or size\)"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1]\n', r"\[\[box\]\] 1 \('b'\): half_extents: expected 3 numbers, got 2"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\nposition = [0, 0]\n', r"\[\[box\]\] 1 \('b'\): position: expected 3 numbers, got 2"),
    ('[[sphere]]\nname = "s"\nradius = nan\n', r"\[\[sphere\]\] 1 \('s'\): radius: must be finite, got nan"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\nposition = [0, inf, 0]\n', r"position\[1\]: must be finite"),
    ('[[cylinder]]\nname = "c"\nradius = 0.1\nlength = -1.0\n', r"\[\[cylinder\]\] 1 \('c'\): length: must be positive"),
    ('[[capsule]]\nname = "c"\nradius = 0\nlength = 1.0\n', r"\[\[capsule\]\] 1 \('c'\): radius: must be positive"),
    ('[[box]]\nname = "b"\nsize = [1, -1, 1]\n', r"half_extents\[1\]: must be positive"),
    ('[[box]]\nname = "b"\nsize = [1, 1, 1]\nhalf_extents = [1, 1, 1]\n', "give size or half_extents, not both"),
    ('[[sphere]]\nname = "s"\nradius = 3e6\n', r"radius: must be positive and at most 1e\+06"),
    ('[[sphere]]\nname = "s"\nradius = "big"\n', r"radius: expected a number, got 'big'"),
    ('[[mesh]]\nname = "m"\npath = "missing.stl"\n', r"bad.toml: mesh 'm': path: mesh file .*missing.stl does not exist"),
    ('[[mesh]]\nname = "m"\npath = "cube.ply"\n', r"\[\[mesh\]\] 1 \('m'\): path: .*cube.ply is not a mesh file \(.stl, .obj, .dae\)"),
    ('[[box]]\nname = "a"\nhalf_extents = [1, 1, 1]\n[[sphere]]\nname = "a"\nradius = 1\n', r"bad.toml: scene 'bad': duplicate obstacle name 'a' \(box and sphere\)"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\nrpy = [0, 0, 0]\nquaternion = [0, 0, 0, 1]\n', "rpy and quaternion: give at most one"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\nquaternion = [0, 0, 0, 2]\n', "quaternion: must be a unit quaternion"),
    ('[[box]]\nname = "b"\nhalf_extents = [1, 1, 1]\nrotation = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\n', "rotation: not a proper rotation matrix"),
    ('[[halfspace]]\nname = "h"\nnormal = [0, 0, 0]\noffset = 0\n', r"\[\[halfspace\]\] 1 \('h'\): normal: must not be zero"),
    ('[[halfspace]]\nname = "h"\nnormal = [0, 0, 1]\noffset = 0\nposition = [0, 0, 0]\n', r"unknown key 'position' \(known: name, normal, offset, padding\)"),
    ('box = 3\n', r"'box' must be a list of \[\[box\]\] tables"),
    ('name = \n', r"bad.toml: Invalid value"),
])
def test_every_file_error_is_a_scene_file_error_naming_file_and_field(tmp_path: Path, body: str, match: str) -> None:
    with pytest.raises(SceneFileError, match=match):
        Scene.from_file(_scene_file(tmp_path, body))


def test_errors_in_python_built_scenes(cube: Path) -> None:
    with pytest.raises(SceneFileError, match=r"^box 'b': half_extents\[2\]: must be positive"):
        Box("b", (1.0, 1.0, 0.0))
    with pytest.raises(SceneFileError, match=r"^sphere '': name: expected a non-empty string"):
        Sphere("", 1.0)
    with pytest.raises(SceneFileError, match=r"^cylinder 'c': pose: expected a Pose"):
        Cylinder("c", 0.1, 1.0, (0, 0, 0))  # type: ignore[arg-type]
    with pytest.raises(SceneFileError, match=r"^mesh 'm': scale\[0\]: must be positive"):
        Mesh("m", cube, (-1.0, 1.0, 1.0))
    with pytest.raises(SceneFileError, match=r"^scene 's': duplicate obstacle name 'x'"):
        Scene("s", (Sphere("x", 1.0), Sphere("x", 2.0)))
    with pytest.raises(SceneFileError, match="is not an obstacle"):
        Scene("s", ("box",))  # type: ignore[arg-type]
    with pytest.raises(SceneFileError, match="position: each coordinate must be within 1e\\+06 m"):
        Pose((2e6, 0.0, 0.0))
    with pytest.raises(SceneFileError, match="missing field 'name'"):
        Scene.from_dict({"box": []})
    with pytest.raises(FileNotFoundError, match="scene file .*nowhere.toml does not exist"):
        Scene.from_file("nowhere.toml")


def test_shipped_scenes_by_name_or_path(tmp_path: Path) -> None:
    assert set(S.scene_names()) >= {"panda_shelf", "talos_task1", "talos_task2", "talos_task3"}
    shelf = S.load_scene("panda_shelf")
    assert shelf == Scene.from_file(S.SCENES_DIR / "panda_shelf.toml") == S.load_scene(S.SCENES_DIR / "panda_shelf.toml")
    assert S.load_scene(shelf) is shelf
    assert len(shelf.obstacles) == 9 and shelf.obstacles[-1] == HalfSpace("floor", (0.0, 0.0, 1.0), -0.5)
    with pytest.raises(UnknownNameError, match="unknown scene 'kitchen' \\(shipped: panda_shelf"):
        S.load_scene("kitchen")


# --- into a collision world


def _hand(robot: genplan.Robot, q: np.ndarray) -> np.ndarray:
    return np.asarray(robot.frame_placement(q, "hand").translation)


def test_add_scene_puts_every_shape_where_the_file_says(panda: genplan.Robot, cube: Path, tmp_path: Path) -> None:
    hand = _hand(panda, Q_READY)
    away = hand * np.array([-1.0, -1.0, 1.0])  # mirrored through the base's axis: nothing of the arm there
    shapes = {
        "box": lambda p: Box("o", (0.04, 0.04, 0.04), Pose(tuple(p))),
        "sphere": lambda p: Sphere("o", 0.04, Pose(tuple(p))),
        "cylinder": lambda p: Cylinder("o", 0.03, 0.1, Pose(tuple(p), rpy=(0.4, 0.0, 0.0))),
        "capsule": lambda p: Capsule("o", 0.03, 0.1, Pose(tuple(p), quaternion=(0.0, 0.0, 0.0, 1.0))),
        "mesh": lambda p: Mesh("o", cube, 0.08, Pose(tuple(p))),
    }
    for kind, make in shapes.items():
        for at, hit in ((hand, True), (away, False)):
            world = panda.collision_world(self_collision=False)
            path = Scene(kind, (make(at),)).to_file(tmp_path / f"{kind}.toml")
            assert world.add_scene(path) == ["o"]
            assert world.in_collision(Q_READY) is hit, (kind, hit)
            assert (world.min_distance(Q_READY) < 0) is hit, kind


def test_scene_obstacles_equal_the_native_calls(panda: genplan.Robot, cube: Path) -> None:
    """A scene's shapes are exactly the native shapes with the documented conversions (full
    length -> half length, rpy -> matrix), and a scaled cube mesh is the box of the same size."""
    qs = panda.random_configurations(300, np.random.default_rng(3))
    rot = pin.rpy.rpyToMatrix(0.2, 0.5, -0.4)

    def pair(obstacle, native) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
        a = panda.collision_world(self_collision=False)
        a.add_scene(Scene("s", (obstacle,)))
        b = panda.collision_world(self_collision=False)
        native(b)
        return np.asarray(a.min_distance(qs)), np.asarray(b.min_distance(qs))

    pose = Pose((0.4, 0.1, 0.4), rpy=(0.2, 0.5, -0.4))
    for obstacle, native in [
        (Cylinder("o", 0.1, 0.6, pose), lambda w: w.add_cylinder("o", 0.1, 0.3, (0.4, 0.1, 0.4), rot)),
        (Capsule("o", 0.1, 0.6, pose), lambda w: w.add_capsule("o", 0.1, 0.3, (0.4, 0.1, 0.4), rot)),
        (Box("o", (0.1, 0.2, 0.3), pose), lambda w: w.add_box("o", (0.1, 0.2, 0.3), (0.4, 0.1, 0.4), rot)),
        (Mesh("o", cube, (0.2, 0.4, 0.6), pose), lambda w: w.add_box("o", (0.1, 0.2, 0.3), (0.4, 0.1, 0.4), rot)),
    ]:
        got, want = pair(obstacle, native)
        assert np.allclose(got, want, atol=1e-7), (obstacle, np.abs(got - want).max())
        assert (got < 0).any() and (got > 0).any(), "the sample straddles the obstacle"


def test_add_scene_is_all_or_nothing(panda: genplan.Robot, cube: Path, tmp_path: Path) -> None:
    world = panda.collision_world()
    world.add_sphere("ball", 0.1, (2.0, 0.0, 0.0))
    # a malformed mesh is found only by the native reader: what was added before it is removed
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nf 1 2 3\n")
    scene = Scene("s", (Box("b", (0.1, 0.1, 0.1), Pose((1.0, 1.0, 1.0))), Mesh("m", broken)))
    with pytest.raises(SceneFileError, match=r"scene 's': mesh 'm': .*broken.obj") as info:
        world.add_scene(scene)
    assert isinstance(info.value.__cause__, RobotFileError)
    assert world.obstacle_names == ["ball"]
    # a name already in the world, a mesh file gone since the scene was read: refused up front
    with pytest.raises(SceneFileError, match=r"sphere 'ball': an obstacle of that name is already in the world"):
        world.add_scene(Scene("t", (Box("b", (0.1, 0.1, 0.1)), Sphere("ball", 0.1))))
    gone = tmp_path / "gone.obj"
    gone.write_text(CUBE_OBJ)
    scene = Scene("u", (Box("b", (0.1, 0.1, 0.1)), Mesh("m", gone)))
    gone.unlink()
    with pytest.raises(SceneFileError, match=r"scene 'u': mesh 'm': path: mesh file .*gone.obj does not exist"):
        world.add_scene(scene)
    assert world.obstacle_names == ["ball"]
    # shipped names work wherever a scene is asked for
    assert world.add_scene("talos_task3") == S.load_scene("talos_task3").obstacle_names
    with pytest.raises(UnknownNameError, match="unknown scene 'kitchen'"):
        world.add_scene("kitchen")


def test_shape_wrappers_check_their_arguments(panda: genplan.Robot, cube: Path, tmp_path: Path) -> None:
    world = panda.collision_world()
    with pytest.raises(ShapeError, match=r"cylinder 'c' center: expected 3 numbers"):
        world.add_cylinder("c", 0.1, 0.2, (0.0, 0.0))
    with pytest.raises(NonFiniteError, match="cylinder 'c' radius"):
        world.add_cylinder("c", float("nan"), 0.2, (0.0, 0.0, 0.0))
    with pytest.raises(ShapeError, match=r"capsule 'c' rotation: expected a 3x3 matrix"):
        world.add_capsule("c", 0.1, 0.2, (0.0, 0.0, 0.0), np.eye(2))
    with pytest.raises(ValueError, match="capsule 'c': half length must be positive"):
        world.add_capsule("c", 0.1, -0.2, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="mesh 'm': rotation is not a proper rotation matrix"):
        world.add_mesh("m", cube, 1.0, (0.0, 0.0, 0.0), 2 * np.eye(3))
    with pytest.raises(ShapeError, match=r"mesh 'm' scale: expected 3 numbers"):
        world.add_mesh("m", cube, (1.0, 1.0), (0.0, 0.0, 0.0))
    with pytest.raises(FileNotFoundError, match="nothing.stl"):
        world.add_mesh("m", tmp_path / "nothing.stl")
    (tmp_path / "bad.stl").write_text("solid nothing here")
    with pytest.raises(RobotFileError, match="bad.stl"):
        world.add_mesh("m", tmp_path / "bad.stl")
    assert world.obstacle_names == []
    world.add_mesh("m", cube, 0.1, (2.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="an obstacle named 'm' already exists"):
        world.add_cylinder("m", 0.1, 0.1, (0.0, 0.0, 0.0))
    assert world.obstacle_names == ["m"]
