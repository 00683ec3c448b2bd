"""Rust collision (parry) against Pinocchio + coal on the same geometry, obstacles, errors."""

import coal
import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan.errors import GenplanError, NonFiniteError, RobotFileError, ShapeError, UnknownNameError
from genplan.planning import environment
from tests.conftest import random_configurations
from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency


def _pair_set(pairs):
    return {tuple(sorted(p)) for p in pairs}


def _coal_pairs(robot: genplan.Robot, geom: pin.GeometryModel):
    return _pair_set(
        (geom.geometryObjects[p.first].name, geom.geometryObjects[p.second].name) for p in geom.collisionPairs
    )


def _srdf_disabled_pairs(path) -> list[tuple[str, str]]:
    """The SRDF's disabled collision pairs, read independently of the Rust reader (the oracle)."""
    import xml.etree.ElementTree as ET

    return [(e.attrib["link1"], e.attrib["link2"]) for e in ET.parse(path).getroot().iter("disable_collisions")]


def test_panda_geometry_and_pairs_match_pinocchio(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    geom = panda.collision_model
    assert sorted(world.geometry_names) == sorted(g.name for g in geom.geometryObjects)
    assert _pair_set(world.self_pairs) == _coal_pairs(panda, geom)
    # SRDF-disabled link pairs never appear
    links = dict(zip(world.geometry_names, world.native.geometry_links))
    disabled = {tuple(sorted(p)) for p in _srdf_disabled_pairs(panda.srdf_path)}
    assert not any(tuple(sorted((links[a], links[b]))) in disabled for a, b in world.self_pairs)


@pytest.mark.parametrize("name", ["talos", "ur5", "ur10", "kinova"])  # ur10, kinova: no SRDF, pairs computed
def test_mesh_robot_pairs_match_pinocchio(name: str) -> None:
    robot = genplan.load(name)
    assert _pair_set(robot.collision_world().self_pairs) == _coal_pairs(robot, robot.collision_model)


def _coal_collides(robot, geom, gdata, q) -> bool:
    return bool(pin.computeCollisions(robot.model, robot.data, geom, gdata, q, True))


def test_panda_self_collision_agrees_with_coal_on_10000_configurations(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    geom = panda.collision_model
    gdata = pin.GeometryData(geom)
    qs = random_configurations(panda, 10_000, seed=11)
    ours = world.in_collision(qs)
    ref = np.array([_coal_collides(panda, geom, gdata, q) for q in qs])
    assert 0.05 < ref.mean() < 0.5  # the sample really exercises both answers
    disagree = ours != ref
    assert 1.0 - disagree.mean() >= 0.999
    dist = world.min_distance(qs)
    assert np.all(np.abs(dist[disagree]) <= 1e-3), dist[disagree]
    # the signed distance is consistent with the boolean answer
    assert np.all((dist <= 1e-9) | ~ours) and np.all((dist >= -1e-9) | ours)


def test_panda_distance_agrees_with_coal(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    geom = panda.collision_model
    gdata = pin.GeometryData(geom)
    qs = random_configurations(panda, 300, seed=5)
    qs = qs[~world.in_collision(qs)]
    ours = world.min_distance(qs)
    for q, d in zip(qs, ours):
        pin.computeDistances(panda.model, panda.data, geom, gdata, q)
        ref = min(r.min_distance for r in gdata.distanceResults)
        assert d == pytest.approx(ref, abs=1e-6)


def test_panda_obstacles_agree_with_coal(panda: genplan.Robot) -> None:
    """Random boxes near the arm, in Rust and as coal boxes attached to the world."""
    rng = np.random.default_rng(2)
    geom = panda.collision_model.copy()
    n_robot = geom.ngeoms
    world = panda.collision_world(self_collision=False)
    for k in range(4):
        half = rng.uniform(0.02, 0.1, size=3)
        radius, angle = rng.uniform(0.35, 0.7), rng.uniform(-np.pi, np.pi)
        center = np.array([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(0.1, 0.9)])
        rot = pin.exp3(rng.normal(size=3))
        world.add_box(f"box{k}", half, center, rot)
        obj = pin.GeometryObject(f"box{k}", 0, 0, pin.SE3(rot, center), coal.Box(*(2 * half)))
        geom.addGeometryObject(obj)
    geom.removeAllCollisionPairs()
    for i in range(n_robot):
        for j in range(n_robot, geom.ngeoms):
            geom.addCollisionPair(pin.CollisionPair(i, j))
    gdata = pin.GeometryData(geom)
    qs = random_configurations(panda, 3000, seed=9)
    ours = world.in_collision(qs)
    ref = np.array([_coal_collides(panda, geom, gdata, q) for q in qs])
    assert 0.05 < ref.mean() < 0.95
    disagree = ours != ref
    assert 1.0 - disagree.mean() >= 0.999
    assert np.all(np.abs(world.min_distance(qs)[disagree]) <= 1e-3)


@pytest.mark.parametrize("name", ["talos", "ur5"])
def test_mesh_hulls_agree_with_coal_convex_hulls(name: str) -> None:
    """Talos and UR5 collide as convex hulls of their STL meshes: coal's hulls of the same meshes
    must give the same answers (disagreements only within 1 mm of contact)."""
    robot = genplan.load(name)
    geom = robot.collision_model.copy()
    for g in geom.geometryObjects:
        if isinstance(g.geometry, coal.BVHModelBase):
            g.geometry.buildConvexHull(True, "Qt")
            g.geometry = g.geometry.convex
    gdata = pin.GeometryData(geom)
    world = robot.collision_world()
    qs = robot.random_configurations(1500, 4)
    ours = world.in_collision(qs)
    ref = np.array([_coal_collides(robot, geom, gdata, q) for q in qs])
    assert 0.05 < ref.mean() < 0.95
    disagree = ours != ref
    assert 1.0 - disagree.mean() >= 0.995, disagree.sum()
    assert np.all(np.abs(world.min_distance(qs)[disagree]) <= 1e-3)


def test_default_postures_are_collision_free() -> None:
    for name in ("panda", "talos", "ur5"):
        robot = genplan.load(name)
        assert not robot.collision_world().in_collision(robot.q_default), name


def test_obstacle_management_and_queries(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    q = panda.q_default
    base = world.min_distance(q)
    world.add_halfspace("floor", [0, 0, 1], -0.5)
    assert world.obstacle_names == ["floor"]
    assert not world.in_collision(q)
    world.add_box("on_hand", [0.05, 0.05, 0.05], panda.frame_placement(q, "hand").translation)
    assert world.in_collision(q)
    pairs = world.close_pairs(q)
    assert pairs and all(b == "on_hand" and d <= 0 for _, b, d in pairs)
    world.remove_obstacle("on_hand")
    assert world.min_distance(q) == pytest.approx(base)
    world.clear_obstacles()
    assert world.obstacle_names == []
    qs = np.repeat(q[None], 4, axis=0)
    assert world.in_collision(qs).shape == (4,) and world.in_collision(qs).dtype == bool
    assert isinstance(world.in_collision(q), bool) and isinstance(world.min_distance(q), float)


def test_collision_bad_input(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    with pytest.raises(ShapeError, match=r"expected shape \(7,\)"):
        world.in_collision(np.zeros(8))
    with pytest.raises(NonFiniteError, match="not finite"):
        world.min_distance(np.full(7, np.nan))
    world.add_box("b", [0.1, 0.1, 0.1], [1, 1, 1])
    with pytest.raises(GenplanError, match="already exists"):
        world.add_box("b", [0.1, 0.1, 0.1], [1, 1, 1])
    with pytest.raises(GenplanError, match="half extents must be positive"):
        world.add_box("c", [0.1, -0.1, 0.1], [1, 1, 1])
    with pytest.raises(GenplanError, match="not a proper rotation"):
        world.add_box("c", [0.1, 0.1, 0.1], [1, 1, 1], rotation=2 * np.eye(3))
    with pytest.raises(ShapeError, match="expected 3 numbers"):
        world.add_sphere("s", 0.1, [0, 0])
    with pytest.raises(GenplanError, match="normal is zero"):
        world.add_halfspace("p", [0, 0, 0], 0.0)
    with pytest.raises(UnknownNameError, match="unknown obstacle 'zz'.*known: b"):
        world.remove_obstacle("zz")


@pytest.mark.parametrize("call, match", [
    (lambda w: w.add_sphere("s", "x", [0, 0, 0]), "^sphere 's' radius: cannot be read as a real number"),
    (lambda w: w.add_sphere("s", [0.1, 0.2], [0, 0, 0]), r"^sphere 's' radius: expected one number"),
    (lambda w: w.add_sphere("s", 0.1, "abc"), "^sphere 's' center: cannot be read"),
    (lambda w: w.add_sphere("s", 0.1 + 0j, [0, 0, 0]), "^sphere 's' radius: complex numbers"),
    (lambda w: w.add_box("b", "abc", [0, 0, 0]), "^box 'b' half_extents: cannot be read"),
    (lambda w: w.add_box("b", [0.1] * 3, [0, 0, 1j]), "^box 'b' center: complex numbers"),
    (lambda w: w.add_box("b", [0.1] * 3, [0, 0, 0], np.eye(3) + 0j), "^box 'b' rotation: complex numbers"),
    (lambda w: w.add_halfspace("p", [0, 0, 1], "x"), "^plane 'p' offset: cannot be read"),
    (lambda w: w.add_halfspace("p", {"z": 1}, 0.0), "^plane 'p' normal: cannot be read"),
    (lambda w: w.close_pairs(np.zeros(7), "x"), "^margin: cannot be read"),
    (lambda w: w.close_pairs(np.zeros(7) + 0j, 0.1), "^q: complex numbers"),
    (lambda w: w.in_collision(np.zeros((2, 7)) + 1j), "^q: complex numbers"),
    (lambda w: w.min_distance([None] * 7), "^q: cannot be read"),
])
def test_values_that_are_not_real_numbers_name_the_argument(panda: genplan.Robot, call, match) -> None:
    """Findings PY-2 / PY-4 of tests/test_fuzz_inputs.py: strings leaked numpy's or float()'s
    ValueError, complex numbers lost their imaginary part, None was read as NaN."""
    world = panda.collision_world()
    with pytest.raises(ShapeError, match=match):
        call(world)
    assert world.obstacle_names == []


def test_collision_world_file_errors(panda: genplan.Robot, tmp_path) -> None:
    from genplan import _core

    with pytest.raises(FileNotFoundError, match="nope.urdf"):
        _core.CollisionWorld(panda.kinematics, tmp_path / "nope.urdf")
    broken = tmp_path / "broken.srdf"
    broken.write_text("<robot><disable_collisions link1='a'/></robot>")
    with pytest.raises(RobotFileError, match="lacks link1 or link2"):
        _core.CollisionWorld(panda.kinematics, panda.collision_urdf_path, [], broken)
    mesh_urdf = tmp_path / "mesh.urdf"
    mesh_urdf.write_text(
        "<robot name='r'><link name='panda_link0'><collision><geometry>"
        "<mesh filename='package://nowhere/x.stl'/></geometry></collision></link></robot>"
    )
    with pytest.raises(RobotFileError, match="not found in package dirs"):
        _core.CollisionWorld(panda.kinematics, mesh_urdf, [tmp_path])


def test_large_batches_are_answered_row_by_row_in_order(panda: genplan.Robot) -> None:
    """Batches run in chunks (Ctrl-C is checked between them): the answers stay in row order."""
    world = panda.collision_world()
    qs = random_configurations(panda, 3000, seed=5)
    hits = world.in_collision(qs)
    dist = world.min_distance(qs)
    rows = range(0, 3000, 97)
    assert [world.in_collision(qs[i]) for i in rows] == list(hits[rows])
    assert [world.min_distance(qs[i]) for i in rows] == list(dist[rows])


@pytest.mark.parametrize("query", ["min_distance", "in_collision"])
def test_ctrl_c_interrupts_a_long_collision_query(panda: genplan.Robot, query: str) -> None:
    """Ctrl-C arrives within 0.5 s of the signal (uninterrupted, the call would take about 5 s on
    an idle 2-core machine)."""
    world = environment("panda_shelf").world(panda)
    n = {"min_distance": 250_000, "in_collision": 800_000}[query]
    qs = random_configurations(panda, n, seed=6)
    assert ctrl_c_latency(lambda: getattr(world, query)(qs)) < MAX_LATENCY_S


# --- the boundary: configurations read in Rust (issue 18) -------------------------------------


@pytest.mark.parametrize("form", ["list", "tuple", "float32", "strided", "numeric strings"])
def test_queries_read_any_form_of_a_configuration_as_float64(panda: genplan.Robot, form: str) -> None:
    world = panda.collision_world()
    world.add_box("table", [0.5, 0.5, 0.02], [0.5, 0.0, -0.03])
    for q in random_configurations(panda, 5, seed=21):
        given = {"list": list(q), "tuple": tuple(q), "float32": q.astype(np.float32),
                 "strided": np.repeat(q, 3)[::3], "numeric strings": [repr(float(x)) for x in q]}[form]
        exact = q.astype(np.float32).astype(np.float64) if form == "float32" else q
        hit, dist = world.in_collision(given), world.min_distance(given)
        assert type(hit) is bool and type(dist) is float
        assert hit == world.in_collision(exact) and dist == world.min_distance(exact)


def test_batches_of_any_layout_answer_as_their_rows(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    qs = random_configurations(panda, 50, seed=22)
    hits, dist = world.in_collision(qs), world.min_distance(qs)
    for given in (np.asfortranarray(qs), np.repeat(qs, 2, axis=0)[::2], qs.tolist()):
        np.testing.assert_array_equal(world.in_collision(given), hits)
        np.testing.assert_array_equal(world.min_distance(given), dist)
    assert [world.in_collision(q) for q in qs] == list(hits)


@pytest.mark.parametrize("bad, error, match", [
    ([0.0] * 6, ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(6,\)$"),
    (np.zeros((3, 8), dtype=np.float32), ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(3, 8\)$"),
    ([0.0, np.nan] + [0.0] * 5, NonFiniteError, r"^q: element \(1,\) is not finite \(nan\)$"),
    (np.array([[0.0] * 7, [0.0] * 6 + [np.inf]])[:, ::1], NonFiniteError, r"^q: element \(1, 6\) is not finite \(inf\)$"),
    ([None] * 7, ShapeError, r"^q: cannot be read"),
])
def test_bad_configurations_name_the_argument(panda: genplan.Robot, bad, error, match) -> None:
    world = panda.collision_world()
    for query in (world.in_collision, world.min_distance, world.native.in_collision, world.native.min_distance):
        with pytest.raises(error, match=match):
            query(bad)
