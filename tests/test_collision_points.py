"""CollisionWorld.point_distances: signed distances from points to a world's obstacles and their
gradients (the clearance objectives' fast path), against coal and distances written out by hand."""

from __future__ import annotations

import coal
import numpy as np
import pytest

import genplan
from genplan.errors import NonFiniteError, SettingsError, ShapeError
from genplan.scene import Box, Capsule, Cylinder, HalfSpace, Pose, Scene, Sphere

_POINT = coal.Sphere(0.0)


def _coal_distance(shape: coal.CollisionGeometry, rotation: np.ndarray, position: np.ndarray, p: np.ndarray) -> float:
    """coal's signed distance from the point p to the shape placed at (rotation, position)."""
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    return float(coal.distance(_POINT, coal.Transform3s(np.eye(3), p), shape, coal.Transform3s(rotation, position),
                               req, res))


def _random_pose(rng: np.random.Generator) -> Pose:
    return Pose(position=tuple(rng.uniform(-1, 1, 3)), rpy=tuple(rng.uniform(-np.pi, np.pi, 3)))


def _obstacle(kind: str, rng: np.random.Generator, name: str):
    if kind == "box":
        return Box(name, half_extents=tuple(rng.uniform(0.05, 0.4, 3)), pose=_random_pose(rng))
    if kind == "sphere":
        return Sphere(name, radius=float(rng.uniform(0.05, 0.4)), pose=_random_pose(rng))
    if kind == "cylinder":
        return Cylinder(name, radius=float(rng.uniform(0.05, 0.3)), length=float(rng.uniform(0.1, 0.8)), pose=_random_pose(rng))
    if kind == "capsule":
        return Capsule(name, radius=float(rng.uniform(0.05, 0.3)), length=float(rng.uniform(0.1, 0.8)), pose=_random_pose(rng))
    n = rng.normal(size=3)
    return HalfSpace(name, normal=tuple(n * rng.uniform(0.5, 2.0) / np.linalg.norm(n)), offset=float(rng.uniform(-0.5, 0.5)))


def _coal_shape(o):
    if isinstance(o, Box):
        return coal.Box(*(2 * np.array(o.half_extents)))
    if isinstance(o, Sphere):
        return coal.Sphere(o.radius)
    if isinstance(o, Cylinder):
        return coal.Cylinder(o.radius, o.length)
    if isinstance(o, Capsule):
        return coal.Capsule(o.radius, o.length)
    n = np.array(o.normal) / np.linalg.norm(o.normal)
    return coal.Halfspace(n, o.offset)


def _analytic(o, p: np.ndarray) -> float:
    """The signed distance written out independently (numpy, one point)."""
    if isinstance(o, HalfSpace):
        n = np.array(o.normal) / np.linalg.norm(o.normal)
        return float(n @ p - o.offset)
    x = o.pose.matrix().T @ (p - np.array(o.pose.position))
    if isinstance(o, Box):
        q = np.abs(x) - np.array(o.half_extents)
        return float(np.linalg.norm(np.maximum(q, 0)) + min(q.max(), 0.0))
    if isinstance(o, Sphere):
        return float(np.linalg.norm(x) - o.radius)
    h = o.length / 2
    if isinstance(o, Cylinder):
        d = np.array([np.hypot(x[0], x[1]) - o.radius, abs(x[2]) - h])
        return float(np.linalg.norm(np.maximum(d, 0)) + min(d.max(), 0.0))
    return float(np.linalg.norm(x - [0, 0, np.clip(x[2], -h, h)]) - o.radius)


def _points_near(o, rng: np.random.Generator, n: int) -> np.ndarray:
    """Points in and around an obstacle (about half inside)."""
    if isinstance(o, HalfSpace):
        return rng.uniform(-1.5, 1.5, (n, 3))
    size = {Box: lambda: np.array(o.half_extents), Sphere: lambda: np.full(3, o.radius),
            Cylinder: lambda: np.array([o.radius, o.radius, o.length / 2]),
            Capsule: lambda: np.array([o.radius, o.radius, o.length / 2 + o.radius])}[type(o)]()
    local = rng.uniform(-1.3, 1.3, (n, 3)) * size
    return local @ o.pose.matrix().T + np.array(o.pose.position)



@pytest.fixture(scope="module")
def panda() -> genplan.Robot:
    return genplan.load("panda")


def _world(robot: genplan.Robot, obstacles) -> genplan.CollisionWorld:
    w = robot.collision_world()
    w.add_scene(Scene("points", tuple(obstacles)))
    return w


@pytest.mark.parametrize("kind", ["box", "sphere", "cylinder", "capsule", "halfspace"])
def test_each_shape_matches_coal_and_the_analytic_distance(panda: genplan.Robot, kind: str) -> None:
    rng = np.random.default_rng(["box", "sphere", "cylinder", "capsule", "halfspace"].index(kind))
    inside_seen = 0
    for i in range(4):
        o = _obstacle(kind, rng, f"{kind}{i}")
        world = _world(panda, [o])
        pts = _points_near(o, rng, 300)
        ours, grad = world.point_distances(pts, cutoff=10.0)
        ref = np.array([_analytic(o, p) for p in pts])
        inside = ref < 0
        # outside: the distance (coal's too); inside: minus the depth to the nearest surface
        np.testing.assert_allclose(ours[~inside], ref[~inside], atol=1e-6, rtol=0)
        shape = _coal_shape(o)
        rot = np.eye(3) if isinstance(o, HalfSpace) else o.pose.matrix()
        pos = np.zeros(3) if isinstance(o, HalfSpace) else np.array(o.pose.position)
        via_coal = np.array([_coal_distance(shape, rot, pos, p) for p in pts[~inside]])
        np.testing.assert_allclose(ours[~inside], via_coal, atol=1e-6, rtol=0)
        assert np.all(ours[inside] < 0)
        np.testing.assert_allclose(ours[inside], ref[inside], atol=1e-6 if kind != "cylinder" else 1e-3)
        inside_seen += int(inside.sum())
        # the gradient: a unit vector, the distance's derivative (central differences off the medial axis)
        np.testing.assert_allclose(np.linalg.norm(grad, axis=1), 1.0, atol=1e-9)
        far = np.abs(ref) > 0.02
        h = 1e-6
        for axis in range(3):
            step = np.zeros(3)
            step[axis] = h
            fd = (world.point_distances(pts[far] + step, 10.0)[0] - world.point_distances(pts[far] - step, 10.0)[0]) / (2 * h)
            np.testing.assert_allclose(grad[far, axis], fd, atol=1e-4)
    assert inside_seen > 100


def test_the_nearest_obstacle_the_cutoff_and_any_leading_shape(panda: genplan.Robot) -> None:
    rng = np.random.default_rng(7)
    obstacles = [_obstacle(kind, rng, f"{kind}{i}") for i, kind in enumerate(["box", "sphere", "capsule", "box"])]
    world = _world(panda, obstacles)
    pts = rng.uniform(-1.5, 1.5, (500, 3))
    ref = np.array([[_analytic(o, p) for o in obstacles] for p in pts]).min(axis=1)
    d, _ = world.point_distances(pts, cutoff=10.0)
    outside = ref > 0
    np.testing.assert_allclose(d[outside], ref[outside], atol=1e-6)
    cut, g = world.point_distances(pts, cutoff=0.1)
    np.testing.assert_allclose(cut[ref < 0.1][ref[ref < 0.1] > 0], ref[(ref < 0.1) & (ref > 0)], atol=1e-6)
    assert np.all(cut[ref >= 0.1 + 1e-9] == 0.1) and np.all(g[ref >= 0.1 + 1e-9] == 0.0)
    d3, g3 = world.point_distances(pts.reshape(5, 10, 10, 3), cutoff=10.0)
    assert d3.shape == (5, 10, 10) and g3.shape == (5, 10, 10, 3)
    np.testing.assert_array_equal(d3.reshape(-1), d)
    empty = panda.collision_world()
    d0, g0 = empty.point_distances(pts[:3], cutoff=0.5)
    assert np.all(d0 == 0.5) and np.all(g0 == 0.0)


@pytest.mark.parametrize(("points", "cutoff", "error", "match"), [
    (np.zeros((4, 2)), 1.0, ShapeError, "points: expected a last axis of 3"),
    (np.array([[0.0, float("nan"), 0.0]]), 1.0, NonFiniteError, "points"),
    (np.zeros((1, 3)), 0.0, SettingsError, "cutoff must be a positive finite distance"),
    (np.zeros((1, 3)), float("inf"), SettingsError, "cutoff must be a positive finite distance"),
])
def test_bad_points_are_refused_naming_the_argument(panda: genplan.Robot, points, cutoff, error, match) -> None:
    with pytest.raises(error, match=match):
        _world(panda, [Sphere("s", radius=0.1)]).point_distances(points, cutoff)
