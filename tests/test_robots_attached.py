"""Attached objects (genplan.robots.Robot.with_attached, a robot file's [[attached]]): checked
against coal on the same geometry, the holding link and touch links excluded, the payload, the
robot file, the errors."""

from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

import genplan
import genplan.planning
from genplan.errors import GenplanError, RobotFileError, SettingsError, UnknownNameError
from genplan.scene import Box, Capsule, HalfSpace, Pose, Sphere
from tests.conftest import random_configurations

#: A rod held by the Panda's hand along its z axis, from 0.15 to 0.35 m: beyond the fingers.
ROD = Box("rod", half_extents=(0.015, 0.015, 0.1))
ROD_POSE = Pose(position=(0.0, 0.0, 0.25))


def _rod(panda: genplan.Robot) -> genplan.Robot:
    return panda.with_attached("rod", ROD, "panda_hand", ROD_POSE)


def test_with_attached_returns_a_new_robot_and_leaves_the_shared_one() -> None:
    panda = genplan.load("panda")  # the shared, cached robot (not the session fixture: a test may clear the cache)
    held = _rod(panda)
    assert held is not panda and genplan.load("panda") is panda
    assert panda.attached == {} and list(held.attached) == ["rod"]
    assert "rod" not in panda.collision_world().geometry_names
    assert "rod" in held.collision_world().geometry_names
    assert "attached" not in panda.description and held.description["attached"][0]["link"] == "panda_hand"
    # a frame role names the link too
    assert panda.with_attached("rod", ROD, "hand", ROD_POSE).attached["rod"].link == "panda_hand"


def _coal_model(robot: genplan.Robot, held: genplan.Robot, boxes) -> tuple[pin.GeometryModel, int]:
    """The robot's coal model with the rod on its link's joint and the boxes in the world: the
    robot's own self pairs, every robot shape and the rod against every box, and the rod against
    every robot shape outside its touch links (read from the world: which links is tested apart)."""
    geom = robot.collision_model.copy()
    n = geom.ngeoms
    a = held.attached["rod"]
    frame = robot.model.frames[robot.model.getFrameId(a.link)]
    rod = pin.GeometryObject("rod", 0, 0, frame.placement * pin.SE3(a.pose.matrix(), np.asarray(a.pose.position)),
                             coal.Box(*(2 * np.asarray(ROD.half_extents))))
    rod.parentJoint, rod.parentFrame = frame.parentJoint, robot.model.getFrameId(a.link)
    geom.addGeometryObject(rod)
    for k, (half, center) in enumerate(boxes):
        geom.addGeometryObject(pin.GeometryObject(f"box{k}", 0, 0, pin.SE3(np.eye(3), center), coal.Box(*(2 * half))))
    (_, _, touch), = held.collision_world().attached
    for i in range(n):
        if robot.model.frames[geom.geometryObjects[i].parentFrame].name not in touch:
            geom.addCollisionPair(pin.CollisionPair(i, n))
        for j in range(n + 1, geom.ngeoms):
            geom.addCollisionPair(pin.CollisionPair(i, j))
    for j in range(n + 1, geom.ngeoms):
        geom.addCollisionPair(pin.CollisionPair(n, j))
    return geom, n


def test_an_attached_object_collides_where_coal_says(panda: genplan.Robot) -> None:
    held = _rod(panda)
    rng = np.random.default_rng(3)
    boxes = []
    for _ in range(3):
        radius, angle = rng.uniform(0.4, 0.7), rng.uniform(-np.pi, np.pi)
        boxes.append((rng.uniform(0.03, 0.08, size=3), np.array([radius * np.cos(angle), radius * np.sin(angle),
                                                                   rng.uniform(0.2, 0.8)])))
    world = held.collision_world()
    for k, (half, center) in enumerate(boxes):
        world.add_box(f"box{k}", half, center)
    geom, _ = _coal_model(panda, held, boxes)
    gdata = pin.GeometryData(geom)
    qs = random_configurations(panda, 3000, seed=4)
    ref = np.array([pin.computeCollisions(panda.model, panda.data, geom, gdata, q, True) for q in qs])
    ours = world.in_collision(qs)
    plain = panda.collision_world()
    for k, (half, center) in enumerate(boxes):
        plain.add_box(f"box{k}", half, center)
    # the rod changes the answer on a real share of the sample
    assert (ours & ~plain.in_collision(qs)).mean() > 0.02
    disagree = ours != ref
    assert 1.0 - disagree.mean() >= 0.999
    assert np.all(np.abs(world.min_distance(qs)[disagree]) <= 1e-3)


def test_the_holding_link_and_touch_links_are_not_checked(panda: genplan.Robot) -> None:
    # a ball around the hand's origin: inside the hand and touching link 7 at the default state
    held = panda.with_attached("ball", Sphere("ball", 0.06), "panda_hand", touch_links=["panda_link5"])
    world = held.collision_world()
    (name, link, touch), = world.attached
    assert (name, link) == ("ball", "panda_hand")
    assert {"panda_hand", "panda_link5"} <= set(touch)
    assert not world.in_collision(held.q_default)
    links = dict(zip(world.geometry_names, world.native.geometry_links))
    partners = {links[b if a == "ball" else a] for a, b in world.self_pairs if "ball" in (a, b)}
    assert partners and not partners & set(touch)
    assert {"panda_link1", "panda_link2"} <= partners


def test_the_payload_is_the_objects_mass_com_and_inertia_on_its_link(panda: genplan.Robot) -> None:
    held = panda.with_attached("rod", ROD, "panda_hand", ROD_POSE, mass=0.6)
    p = held.attached["rod"].payload
    from genplan.control import Payload

    assert isinstance(p, Payload)
    assert p.link == "panda_hand" and p.mass == 0.6
    np.testing.assert_allclose(p.com, [0.0, 0.0, 0.25])
    x, y, z = 0.03, 0.03, 0.2
    np.testing.assert_allclose(p.inertia, np.diag([y * y + z * z, x * x + z * z, x * x + y * y]) * 0.6 / 12)
    # rotated: the inertia turns with the object, the centre of mass is placed in the link frame
    turned = panda.with_attached("rod", ROD, "panda_hand", Pose(position=(0.1, 0, 0), rpy=(0, np.pi / 2, 0)),
                                 mass=0.6, com=(0, 0, 0.05))
    q = turned.attached["rod"].payload
    np.testing.assert_allclose(q.com, [0.15, 0.0, 0.0], atol=1e-12)
    # Ry(90 deg) takes the object's z axis to the link's x axis, its x to the link's -z
    np.testing.assert_allclose(q.inertia, np.diag([x * x + y * y, x * x + z * z, y * y + z * z]) * 0.6 / 12, atol=1e-12)
    with pytest.raises(SettingsError, match="mass"):
        _rod(panda).attached["rod"].payload


def test_a_robot_file_attaches_what_with_attached_does(panda: genplan.Robot, tmp_path: Path) -> None:
    # the preset's package:// paths resolve from anywhere
    lines = (genplan.robots.PRESETS_DIR / "panda.toml").read_text().splitlines()
    lines += ["", "[[attached]]", 'name = "rod"', 'link = "panda_hand"', "position = [0.0, 0.0, 0.25]", "mass = 0.6",
              "box = { half_extents = [0.015, 0.015, 0.1] }"]
    path = tmp_path / "panda_rod.toml"
    path.write_text("\n".join(lines) + "\n")
    robot = genplan.load(path)
    a = robot.attached["rod"]
    assert a == panda.with_attached("rod", ROD, "panda_hand", ROD_POSE, mass=0.6).attached["rod"]
    assert "rod" in robot.collision_world().geometry_names
    bad = tmp_path / "bad.toml"
    bad.write_text(path.read_text().replace('link = "panda_hand"', 'link = "panda_wrist"'))
    with pytest.raises(RobotFileError, match=r"bad.toml.*\[\[attached\]\] 1.*panda_wrist.*known: .*panda_hand"):
        genplan.load(bad)


def test_bad_attachments_are_typed_errors_naming_the_field(panda: genplan.Robot) -> None:
    with pytest.raises(UnknownNameError, match=r"link: unknown link 'wrist' \(known: .*panda_hand"):
        panda.with_attached("rod", ROD, "wrist", ROD_POSE)
    with pytest.raises(UnknownNameError, match="touch_links: unknown link 'elbow'"):
        panda.with_attached("rod", ROD, "panda_hand", ROD_POSE, touch_links=["elbow"])
    nan = np.eye(4)
    nan[0, 3] = np.nan
    with pytest.raises(GenplanError, match="pose"):
        panda.with_attached("rod", ROD, "panda_hand", nan)
    with pytest.raises(GenplanError, match="position"):
        panda.with_attached("rod", ROD, "panda_hand", Pose(position=(np.nan, 0, 0)))
    with pytest.raises(SettingsError, match="shape"):
        panda.with_attached("floor", HalfSpace("floor", (0, 0, 1), 0.0), "panda_hand")
    with pytest.raises(SettingsError, match="mass"):
        panda.with_attached("rod", ROD, "panda_hand", mass=-1.0)
    with pytest.raises(SettingsError, match="name"):
        _rod(panda).with_attached("rod", Capsule("c", 0.01, 0.1), "panda_link3")
    # a geometry's name is taken
    taken = panda.collision_world().geometry_names[0]
    with pytest.raises(GenplanError, match="already has a geometry"):
        panda.with_attached(taken, ROD, "panda_hand", ROD_POSE)


def test_the_sphere_checker_covers_an_attached_object(panda: genplan.Robot) -> None:
    """The held rod gets spheres of its own (genplan.spheres.attached_spheres) and is one more
    entry of the sphere checker's self pairs; a world holding an object the robot does not is
    refused, naming it (test_sphere_checker checks the cover against the exact world)."""
    held = _rod(panda)
    sc = genplan.planning.sphere_checker(held, held.collision_world())
    assert sc.n_spheres > genplan.planning.sphere_checker(panda, panda.collision_world()).n_spheres
    assert any("rod" in pair for pair in sc.self_pairs)
    with pytest.raises(GenplanError, match="attached object 'rod'"):
        genplan.planning.sphere_checker(panda, held.collision_world())
