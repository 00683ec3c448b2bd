"""genplan.scene's meshes by shape (``Mesh(shape=...)``, ``[[mesh]] shape`` in a scene file,
``CollisionWorld.add_mesh(shape=...)``): a closed non-convex mesh kept as a mesh is a solid with
its cavity free, decomposed into convex parts it keeps the cavity, as a hull it fills it; bad
shapes and meshes are refused naming the field or file."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import genplan
from genplan import _core
from genplan.errors import RobotFileError, SceneFileError, UnknownNameError
from genplan.scene import MESH_SHAPES, Mesh, Pose, Scene

#: tests/data/cup.obj: 0.2 x 0.2 x 0.1 m, a 0.12 x 0.12 x 0.06 m cavity open at the top
CUP = Path(__file__).parent / "data" / "cup.obj"
#: where the cup is put: far from the Panda, so that only point distances are asked
AT = np.array([2.0, 0.0, 0.0])
#: points in the cavity's middle, inside a wall (0.02 m from its faces), inside the bottom
CAVITY, IN_WALL, IN_BOTTOM = AT + [0.0, 0.0, 0.07], AT + [0.08, 0.0, 0.07], AT + [0.0, 0.0, 0.02]


@pytest.fixture(scope="module")
def panda() -> genplan.Robot:
    return genplan.load("panda")


def cup_world(panda: genplan.Robot, shape: str) -> genplan.CollisionWorld:
    w = panda.collision_world()
    w.add_scene(Scene("cup", (Mesh("cup", CUP, pose=Pose(tuple(AT)), shape=shape),)))
    return w


def test_the_shapes_are_the_cores() -> None:
    assert MESH_SHAPES == tuple(_core.MESH_SHAPES) == ("hull", "mesh", "decomposed")
    assert Mesh("m", CUP).shape == "hull"


@pytest.mark.parametrize(("shape", "cavity_free"), [("hull", False), ("mesh", True), ("decomposed", True)])
def test_each_shape_in_the_worlds_queries(panda: genplan.Robot, shape: str, cavity_free: bool) -> None:
    w = cup_world(panda, shape)
    d, g = w.point_distances(np.stack([CAVITY, IN_WALL, IN_BOTTOM]), cutoff=1.0)
    assert (d[0] > 0) == cavity_free, (shape, d)
    assert d[1] < 0 and d[2] < 0, (shape, d)
    if shape == "mesh":
        # exact on the solid: the cavity's bottom 0.03 m below (its walls 0.06 m aside); 0.02 m
        # deep in the wall and in the bottom
        np.testing.assert_allclose(d, [0.03, -0.02, -0.02], atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-9)
    # the Panda is far from the cup: every shape leaves its answers as they are without it
    q = panda.q_default
    assert not w.in_collision(q)
    assert w.min_distance(q) == panda.collision_world().min_distance(q)


def test_the_shape_round_trips_through_files(tmp_path: Path) -> None:
    scene = Scene("cups", (Mesh("a", CUP), Mesh("b", CUP, shape="mesh"), Mesh("c", CUP, shape="decomposed")))
    rows = scene.to_dict()["mesh"]
    assert [r.get("shape") for r in rows] == [None, "mesh", "decomposed"], "the default is not written"
    path = scene.to_file(tmp_path / "cups.toml")
    assert Scene.from_file(path) == scene
    assert Scene.from_dict(scene.to_dict()) == scene


def test_unknown_shapes_name_the_field_and_list_the_known(tmp_path: Path, panda: genplan.Robot) -> None:
    with pytest.raises(SceneFileError, match=r"mesh 'm': shape: unknown mesh shape 'convex' \(known: hull, mesh, decomposed\)"):
        Mesh("m", CUP, shape="convex")
    f = tmp_path / "bad.toml"
    f.write_text(f'name = "bad"\n[[mesh]]\nname = "cup"\npath = "{CUP}"\nshape = "solid"\n')
    with pytest.raises(SceneFileError, match=r"bad.toml.*mesh.*'cup'.*shape.*'solid'.*known: hull, mesh, decomposed"):
        Scene.from_file(f)
    assert tomllib.loads(f.read_text())["mesh"][0]["shape"] == "solid"
    w = panda.collision_world()
    with pytest.raises(UnknownNameError, match=r"mesh 'm' shape: unknown mesh shape 'convex' \(known: hull, mesh, decomposed\)"):
        w.add_mesh("m", CUP, shape="convex")
    assert w.obstacle_names == []


def test_a_mesh_that_cannot_be_decomposed_names_the_file(tmp_path: Path, panda: genplan.Robot) -> None:
    plate = tmp_path / "plate.obj"
    plate.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    w = panda.collision_world()
    with pytest.raises(RobotFileError, match=r"plate\.obj.*mesh 'plate' \(shape \"decomposed\"\).*no part with volume"):
        w.add_mesh("plate", plate, shape="decomposed")
    # as a mesh, the plate is a surface
    w.add_mesh("plate", plate, center=(2.0, 0.0, 0.0), shape="mesh")
    d, _ = w.point_distances(np.array([[2.5, 0.5, 0.1], [2.5, 0.5, -0.1]]))
    np.testing.assert_allclose(d, [0.1, 0.1], atol=1e-9)
    # all or nothing: a scene whose mesh cannot be decomposed adds nothing, the native error the cause
    w2 = panda.collision_world()
    with pytest.raises(SceneFileError, match="plate") as info:
        w2.add_scene(Scene("s", (Mesh("cup", CUP, shape="mesh"), Mesh("plate", plate, shape="decomposed"))))
    assert isinstance(info.value.__cause__, RobotFileError) and "no part with volume" in str(info.value.__cause__)
    assert w2.obstacle_names == []


def test_a_robot_file_makes_its_meshes_the_shape_it_names(tmp_path: Path) -> None:
    urdf = tmp_path / "cup.urdf"
    urdf.write_text(f"""<robot name="cup">
  <link name="base"/>
  <link name="cup"><collision><geometry><mesh filename="{CUP}"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="cup"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>""")
    for shape, cavity_hit in [("hull", True), ("decomposed", False)]:
        f = tmp_path / f"cup_{shape}.toml"
        f.write_text(f'urdf = "cup.urdf"\nmesh_shape = "{shape}"\n')
        robot = genplan.load(f)
        assert robot.mesh_shape == shape
        w = robot.collision_world()
        w.add_sphere("ball", 0.02, (0.0, 0.0, 0.07))  # in the cup's cavity
        assert w.in_collision(np.zeros(1)) == cavity_hit, shape
    bad = tmp_path / "bad.toml"
    bad.write_text('urdf = "cup.urdf"\nmesh_shape = "convex"\n')
    with pytest.raises(RobotFileError, match=r"bad.toml.*'mesh_shape'.*known: hull, mesh, decomposed"):
        genplan.load(bad)
