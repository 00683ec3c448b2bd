"""genplan.spheres: every point of each link's collision solid inside a sphere of that link
(points sampled independently of the generator, placed with Pinocchio's geometry placements);
conservative against coal on the raw geometry; float32 kinematics within the padding; the file
form, the cache and what the generator refuses.

The samplers and the coal comparison are benches/spheres.py's (one definition, used by the
benchmark and here). The mesh robots are covered at a coarser ``max_error`` than the default to
keep the suite's time down: the cover is by construction at every ``max_error``, and
`python benches/spheres.py` checks the default (docs/ROBOTS.md has its table)."""

from __future__ import annotations

import json
import math
import runpy
from pathlib import Path

import numpy as np
import pytest

import genplan
from genplan import spheres as sph
from genplan.errors import RobotFileError, SettingsError

BENCH = runpy.run_path(str(Path(__file__).resolve().parents[1] / "benches" / "spheres.py"))


def _stl(path: Path, triangles: np.ndarray) -> None:
    lines = ["solid s"]
    for t in triangles:
        n = np.cross(t[1] - t[0], t[2] - t[0])
        n /= np.linalg.norm(n)
        lines += [f" facet normal {n[0]} {n[1]} {n[2]}", "  outer loop",
                  *(f"   vertex {v[0]} {v[1]} {v[2]}" for v in t), "  endloop", " endfacet"]
    path.write_text("\n".join([*lines, "endsolid s", ""]))


@pytest.fixture(scope="module")
def small_urdf(tmp_path_factory) -> Path:
    """A three-link arm with every kind of geometry: a box; a tilted cylinder and a sphere on one
    link; a closed mesh (an octahedron, scaled) and an open one (a flat plate) on another; a
    link without geometry."""
    folder = tmp_path_factory.mktemp("small")
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]]) * 0.05
    faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    _stl(folder / "octa.stl", np.array([v[list(f)] for f in faces]))
    plate = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.06, 0], [0, 0.06, 0.0]])
    _stl(folder / "plate.stl", np.array([plate[[0, 1, 2]], plate[[0, 2, 3]]]))
    urdf = folder / "small.urdf"
    urdf.write_text(f"""<robot name="small">
 <link name="base"><collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.1 0.1"/></geometry></collision></link>
 <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
  <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
 <link name="l1"><collision><origin xyz="0 0 0.1" rpy="0.3 0 0"/><geometry><cylinder radius="0.04" length="0.2"/></geometry></collision>
  <collision><origin xyz="0 0 0.2"/><geometry><sphere radius="0.05"/></geometry></collision></link>
 <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.25"/><axis xyz="0 1 0"/>
  <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
 <link name="l2"><collision><origin xyz="0.05 0 0"/><geometry><mesh filename="{folder / 'octa.stl'}" scale="1 1 2"/></geometry></collision>
  <collision><origin xyz="0.1 0 0.05"/><geometry><mesh filename="{folder / 'plate.stl'}"/></geometry></collision></link>
 <joint name="j3" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.2 0 0"/></joint>
 <link name="tip"/>
</robot>
""")
    return urdf


@pytest.fixture(scope="module")
def small(small_urdf: Path) -> genplan.Robot:
    return genplan.load(urdf=small_urdf)


@pytest.fixture(scope="module")
def panda_spheres(panda: genplan.Robot) -> sph.RobotSpheres:
    return sph.robot_spheres(panda)


# --- the cover -----------------------------------------------------------------------------------


def _assert_covered(robot: genplan.Robot, spheres: sph.RobotSpheres, points: int, seed: int = 0) -> dict:
    found = BENCH["cover_check"](robot, spheres, points, np.random.default_rng(seed))
    assert found["covered"], found  # every point within r - padding of a centre of its link
    assert found["points"] >= points * robot.collision_model.ngeoms  # >= 20k per geometry (on and in it)
    return found


def test_panda_every_point_of_its_capsules_is_covered(panda: genplan.Robot, panda_spheres: sph.RobotSpheres) -> None:
    _assert_covered(panda, panda_spheres, 20_000)
    # links with geometry have spheres, links without none; the locked fingers keep theirs
    assert set(panda_spheres.link_names) == {g.link for g in sph.link_geometries(panda)}
    assert {"panda_leftfinger", "panda_rightfinger"} <= set(panda_spheres.link_names)
    assert "panda_link8" not in panda_spheres.link_names and "panda_hand_tcp" not in panda_spheres.link_names
    # the count of VAMP's Panda (59) or fewer, each reaching at most max_error (+ padding) out
    assert 20 <= len(panda_spheres) <= 60
    assert panda_spheres.excess.max() <= panda_spheres.max_error + panda_spheres.padding + 1e-9


@pytest.mark.parametrize(("name", "max_error"), [("ur5", 0.02), ("kinova", 0.03)])
def test_mesh_robots_every_point_of_the_raw_meshes_is_covered(name: str, max_error: float) -> None:
    robot = genplan.load(name)
    spheres = sph.robot_spheres(robot, max_error=max_error)
    assert any(g.kind == "mesh" for g in sph.link_geometries(robot))
    _assert_covered(robot, spheres, 20_000)


def test_every_kind_of_geometry_is_covered_a_closed_mesh_with_its_inside(small: genplan.Robot) -> None:
    kinds = {g.kind for g in sph.link_geometries(small)}
    assert kinds == {"box", "cylinder", "sphere", "mesh"}
    spheres = sph.robot_spheres(small, max_error=0.03, cache=False)
    _assert_covered(small, spheres, 20_000)
    assert set(spheres.link_names) == {"base", "l1", "l2"}  # "tip" has no geometry
    # the octahedron's inside (scaled: 5 cm by 5 cm by 10 cm) is covered, not only its surface
    octa = next(g for g in sph.link_geometries(small) if g.name == "l2_0")
    rng = np.random.default_rng(1)
    p = rng.uniform(-0.05, 0.05, (20_000, 3)) * [1, 1, 2] + [0.05, 0, 0]
    inside = p[octa.contains(p)]
    assert len(inside) > 2000
    mine = np.array([x == "l2" for x in spheres.links])
    d = np.linalg.norm(inside[:, None] - spheres.centers[mine][None], axis=2) - (spheres.radii[mine] - spheres.padding)
    assert d.min(axis=1).max() <= 0


def test_a_link_of_spheres_alone_is_covered_by_those_spheres() -> None:
    place = np.eye(4)
    place[:3, 3] = [0.1, -0.2, 0.3]
    geoms = [sph.LinkGeometry("a_0", "a", "sphere", (0.22,), place), sph.LinkGeometry("a_1", "a", "sphere", (0.01,), np.eye(4))]
    centers, radii, excess = sph._cover_link("a", geoms, 0.01, 0.005)
    np.testing.assert_array_equal(centers, [[0.1, -0.2, 0.3], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(radii, [0.22, 0.01])
    np.testing.assert_array_equal(excess, [0.0, 0.0])


def test_triangles_are_cut_along_their_long_edges_into_short_pieces_that_tile_them() -> None:
    """A long thin triangle (a cylinder cap's, 12 cm by 8 mm) and a wide one become pieces
    whose edges are at most the length asked, of the same area and orientation; the thin one a
    row of pieces along it."""
    v = np.array([[0.0, 0.0, 0.0], [0.12, 0.0, 0.0], [0.06, 0.008, 0.0], [0.0, 0.05, 0.03]])
    for tri, most in (([0, 1, 2], 200), ([0, 3, 1], 2000)):
        pv, pt = sph._subdivide(v, np.array([tri]), 0.005)
        a, b, c = pv[pt[:, 0]], pv[pt[:, 1]], pv[pt[:, 2]]
        edges = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)])
        assert edges.max() <= 0.005 * (1 + 1e-9)
        normals = np.cross(b - a, c - a)
        whole = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]])
        assert np.isclose(np.linalg.norm(normals, axis=1).sum(), np.linalg.norm(whole), rtol=1e-12)
        assert np.all(normals @ whole > 0)
        assert len(pt) <= most  # the thin one: k^2 similar pieces (k = 24) would be 576


def test_the_geometry_is_read_in_each_links_frame(small: genplan.Robot) -> None:
    """link_geometries' placements against Pinocchio's world placements and genplan's FK."""
    import pinocchio as pin

    geom = small.collision_model
    data = pin.GeometryData(geom)
    q = small.random_configurations(1, 3)[0]
    pin.framesForwardKinematics(small.model, small.data, q)
    pin.updateGeometryPlacements(small.model, small.data, geom, data, q)
    for i, g in enumerate(sph.link_geometries(small)):
        world = small.link_poses(q, [g.link])[0] @ g.placement
        np.testing.assert_allclose(world, data.oMg[i].homogeneous, atol=1e-12)
    with pytest.raises(SettingsError, match="robot: expected a genplan Robot"):
        sph.robot_spheres("panda")  # type: ignore[arg-type]


# --- conservative against coal ----------------------------------------------------------------------


def test_panda_spheres_are_conservative_against_coal_on_boxes(panda: genplan.Robot,
                                                               panda_spheres: sph.RobotSpheres) -> None:
    found = BENCH["against_coal"](panda, panda_spheres, 3000, np.random.default_rng(5), scenes=6)
    print(f"\nPanda, {found['configurations']} configurations among boxes: coal {found['coal_contacts']} in contact, "
          f"spheres {found['sphere_contacts']}, false-positive rate {found['false_positive_rate']:.2%}")
    assert found["missed"] == 0  # no contact coal finds is free by the spheres
    assert 300 < found["coal_contacts"] < found["configurations"] - 300  # both answers are exercised
    assert found["false_positive_rate"] < 0.1


# --- float32 kinematics within the padding ---------------------------------------------------------


def _float32_link_poses(robot: genplan.Robot, q: np.ndarray, links: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The links' world rotations and positions from Pinocchio's joint placements, every product
    in float32 (a chain of revolute joints about x, y or z): what a float32 kinematics computes."""
    m = robot.model
    f = np.float32
    n = len(q)
    rot = {0: np.broadcast_to(np.eye(3, dtype=f), (n, 3, 3))}
    pos = {0: np.zeros((n, 3), dtype=f)}
    for j in range(1, m.njoints):
        axis = "XYZ".index(m.joints[j].shortname()[-1])
        place = m.jointPlacements[j]
        pr, pp = rot[int(m.parents[j])], pos[int(m.parents[j])]
        angle = q[:, m.joints[j].idx_q].astype(f)
        c, s = np.cos(angle), np.sin(angle)
        r = np.zeros((n, 3, 3), dtype=f)
        a, b = [k for k in range(3) if k != axis]
        r[:, axis, axis] = 1
        r[:, a, a], r[:, a, b], r[:, b, a], r[:, b, b] = c, -s if axis != 1 else s, s if axis != 1 else -s, c
        rot[j] = pr @ place.rotation.astype(f) @ r
        pos[j] = pp + np.einsum("nij,j->ni", pr, place.translation.astype(f))
    out_r, out_p = [], []
    for link in links:
        fr = m.frames[m.getFrameId(link)]
        pr, pp = rot[int(fr.parentJoint)], pos[int(fr.parentJoint)]
        out_r.append(pr @ fr.placement.rotation.astype(f))
        out_p.append(pp + np.einsum("nij,j->ni", pr, fr.placement.translation.astype(f)))
    return np.stack(out_r, 1), np.stack(out_p, 1)


def test_float32_kinematics_stay_within_a_tenth_of_the_padding(panda: genplan.Robot,
                                                                panda_spheres: sph.RobotSpheres) -> None:
    s = panda_spheres
    q = panda.random_configurations(2000, 4)
    ref = s.world_centers(panda, q)
    assert ref.shape == (2000, len(s), 3) and s.world_centers(panda, q[0]).shape == (len(s), 3)
    names = list(s.link_names)
    which = np.array([names.index(x) for x in s.links])
    rot, pos = _float32_link_poses(panda, q, names)
    f32 = np.einsum("nsij,sj->nsi", rot[:, which], s.centers.astype(np.float32)) + pos[:, which]
    error = float(np.abs(f32.astype(np.float64) - ref).max())
    assert 0 < error <= s.padding / 10, error
    # genplan's float32 output, the same within its rounding
    np.testing.assert_allclose(s.world_centers(panda, q, dtype=np.float32), ref, atol=s.padding / 10)
    with pytest.raises(SettingsError, match="dtype"):
        s.world_centers(panda, q, dtype=np.int32)


# --- the file form and the cache ---------------------------------------------------------------------


def test_to_dict_from_dict_round_trip(panda_spheres: sph.RobotSpheres) -> None:
    d = panda_spheres.to_dict()
    back = sph.RobotSpheres.from_dict(json.loads(json.dumps(d)))
    assert back == panda_spheres
    np.testing.assert_array_equal(back.centers, panda_spheres.centers)
    np.testing.assert_array_equal(back.radii, panda_spheres.radii)
    assert (back.max_error, back.resolution, back.padding, back.geometry_hash) == (
        panda_spheres.max_error, panda_spheres.resolution, panda_spheres.padding, panda_spheres.geometry_hash)
    assert not back.centers.flags.writeable


@pytest.mark.parametrize(("change", "match"), [
    (lambda d: d.pop("radii"), "missing field 'radii'"),
    (lambda d: d.update(colour="red"), "unknown field 'colour'"),
    (lambda d: d.update(format="other"), "format: expected 'genplan-robot-spheres'"),
    (lambda d: d.update(radii=d["radii"][:-1]), r"radii: expected shape \(\d+,\)"),
    (lambda d: d["centers"][0].__setitem__(1, float("nan")), "centers: must be finite"),
    (lambda d: d["radii"].__setitem__(2, -0.1), r"radii\[2\]: must be positive"),
    (lambda d: d.update(links="panda_link0"), "links: expected a list of link names"),
    (lambda d: d.update(max_error="1 cm"), "max_error: expected a finite number"),
])
def test_from_dict_refuses_bad_data_naming_the_field(panda_spheres: sph.RobotSpheres, change, match) -> None:
    d = json.loads(json.dumps(panda_spheres.to_dict()))
    change(d)
    with pytest.raises(RobotFileError, match=f"^robot.toml: {match}"):
        sph.RobotSpheres.from_dict(d, origin="robot.toml")


def test_the_cache_is_used_validated_and_regenerated(small: genplan.Robot, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path))
    sph.clear_cache()
    first = sph.robot_spheres(small, max_error=0.04)
    assert first.generation_s > 0
    files = list((tmp_path / "spheres").glob("*.json"))
    assert len(files) == 1 and first.geometry_hash[:24] in files[0].name
    assert sph.robot_spheres(small, max_error=0.04) is first  # in memory
    sph.clear_cache()
    again = sph.robot_spheres(small, max_error=0.04)  # from the file
    assert again == first and again.generation_s == 0
    # other parameters: another file
    sph.clear_cache()
    other = sph.robot_spheres(small, max_error=0.05)
    assert other.geometry_hash != first.geometry_hash and len(list((tmp_path / "spheres").glob("*.json"))) == 2
    # a corrupt file (cut short; a number changed under its checksum) is generated again, replaced
    text = files[0].read_text()
    for bad in (text[: len(text) // 2], text.replace('"radii": [', '"radii": [1.0, ', 1)):
        files[0].write_text(bad)
        sph.clear_cache()
        regenerated = sph.robot_spheres(small, max_error=0.04)
        assert regenerated == first and regenerated.generation_s > 0
        assert json.loads(files[0].read_text())["spheres"] == first.to_dict()
    # cache=False neither reads nor writes
    files[0].unlink()
    sph.clear_cache()
    assert sph.robot_spheres(small, max_error=0.04, cache=False) == first
    assert not files[0].exists()
    sph.clear_cache()


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"max_error": 0.0}, "max_error: must be positive"),
    ({"max_error": -0.01}, "max_error: must be positive"),
    ({"max_error": math.nan}, "max_error: must be positive"),
    ({"max_error": "1cm"}, "max_error: expected a number"),
    ({"max_error": True}, "max_error: expected a number"),
    ({"resolution": 0.0}, "resolution: must be positive"),
    ({"padding": -1e-4}, r"padding: expected a number in \[0, 0.01\]"),
    ({"cache": "yes"}, "cache: expected True or False"),
    ({"resolution": 1e-5}, "resolution: 1e-05 m is too fine for link 'base'"),
    ({"link_max_error": 0.01}, "link_max_error: expected a table of link names"),
    ({"link_max_error": {"tip": 0.01}}, "link_max_error: 'tip' is no link with collision geometry of 'small' "
                                        r"\(those: base, l1, l2\)"),
    ({"link_max_error": {"l1": 0.0}}, r"link_max_error\['l1'\]: must be positive"),
    ({"link_max_error": {"l1": "5mm"}}, r"link_max_error\['l1'\]: expected a number"),
])
def test_bad_parameters_are_refused_naming_them(small: genplan.Robot, kwargs, match) -> None:
    with pytest.raises(SettingsError, match=match):
        sph.robot_spheres(small, **{"cache": False, **kwargs})


def test_a_link_gets_a_max_error_of_its_own(small: genplan.Robot) -> None:
    """``link_max_error``: that link covered tighter (its spheres reaching at most its own
    max_error out, the cover still whole), the others as without it; a cache key of its own, and
    the same key as before for a cover without one (``{}``)."""
    plain = sph.robot_spheres(small, max_error=0.04, cache=False)
    tight = sph.robot_spheres(small, max_error=0.04, cache=False, link_max_error={"l1": 0.01})
    _assert_covered(small, tight, 5_000)
    assert plain.link_max_error == {} and tight.link_max_error == {"l1": 0.01}
    l1 = np.array(tight.links) == "l1"
    assert tight.excess[l1].max() <= 0.01 + tight.padding + 1e-9 < plain.excess[np.array(plain.links) == "l1"].max()
    assert tight.counts()["l1"] > plain.counts()["l1"]
    for link in ("base", "l2"):  # the other links as they were
        m, n = np.array(tight.links) == link, np.array(plain.links) == link
        np.testing.assert_array_equal(tight.centers[m], plain.centers[n])
        np.testing.assert_array_equal(tight.radii[m], plain.radii[n])
    geoms = sph.link_geometries(small)
    assert plain.geometry_hash == sph.geometry_hash(geoms, 0.04, 0.02, plain.padding)
    assert sph.robot_spheres(small, max_error=0.04, cache=False, link_max_error={}) == plain
    assert tight.geometry_hash not in (plain.geometry_hash, sph.geometry_hash(geoms, 0.04, 0.02, plain.padding, {"l1": 0.02}))
    # an explicit resolution grids l1 at it, not at half l1's max_error: another cover, another key
    given = sph.robot_spheres(small, max_error=0.04, resolution=0.02, cache=False, link_max_error={"l1": 0.01})
    assert given.geometry_hash != tight.geometry_hash
    assert sph.robot_spheres(small, max_error=0.04, resolution=0.02, cache=False).geometry_hash == plain.geometry_hash
    back = sph.RobotSpheres.from_dict(json.loads(json.dumps(tight.to_dict())))
    assert back == tight and back.link_max_error == {"l1": 0.01}
    assert "link_max_error" not in plain.to_dict()
    bad = dict(tight.to_dict(), link_max_error={"l1": -1.0})
    with pytest.raises(RobotFileError, match="^spheres: link_max_error: expected a table"):
        sph.RobotSpheres.from_dict(bad)


def test_the_panda_covers_its_wrist_tighter_by_default(panda: genplan.Robot, panda_spheres: sph.RobotSpheres) -> None:
    """DEFAULT_LINK_MAX_ERROR: the Panda's link7 at 5 mm (the cage of the motion bench), the
    rest at max_error, all in the cache key."""
    assert panda_spheres.link_max_error == sph.DEFAULT_LINK_MAX_ERROR["panda"] == {"panda_link7": 0.005}
    link7 = np.array(panda_spheres.links) == "panda_link7"
    assert panda_spheres.excess[link7].max() <= 0.005 + panda_spheres.padding + 1e-9
    assert panda_spheres.excess[~link7].max() > 0.005 + panda_spheres.padding
    geoms = sph.link_geometries(panda)
    assert panda_spheres.geometry_hash == sph.geometry_hash(geoms, 0.01, 0.005, panda_spheres.padding,
                                                           {"panda_link7": 0.005})


def test_the_benchmark_script_writes_its_rows(small_urdf: Path, tmp_path, monkeypatch, capsys) -> None:
    import sys

    out = tmp_path / "spheres.json"
    monkeypatch.setattr(sys, "argv", ["spheres.py", "--robots", f"{small_urdf}:0.05", "--configurations", "40",
                                      "--points", "500", "--out", str(out)])
    BENCH["main"]()
    row = json.loads(out.read_text())["rows"][0]
    assert row["robot"] == "small" and row["spheres"] > 0 and row["cover"]["covered"]
    assert row["coal"]["missed"] == 0 and row["coal"]["configurations"] == 40 and row["volume_ratio"] > 1
    assert "cover ok" in capsys.readouterr().out


def test_the_benchmarks_mesh_solid_agrees_with_the_winding_number(small: genplan.Robot) -> None:
    """benches/spheres.py's MeshSolid (crossings of a vertical line, triangles binned by cell)
    finds the same solid as the winding number (LinkGeometry.contains) on a closed mesh, on lines
    through its vertices (decided by the winding number) and on the UR5's meshes; an open plate
    has no inside for either."""
    octa, plate = (next(g for g in sph.link_geometries(small) if g.name == n) for n in ("l2_0", "l2_1"))
    rng = np.random.default_rng(2)
    p = rng.uniform(-0.06, 0.06, (20_000, 3)) * [1, 1, 2] + [0.05, 0, 0]
    p[:200, :2] = [0.05, 0.0]  # on the line through the two apexes
    solid = BENCH["MeshSolid"](octa)
    np.testing.assert_array_equal(solid.contains(p), octa.contains(p))
    assert 2000 < solid.contains(p).sum() < len(p) - 2000
    q = rng.uniform(-0.02, 0.12, (5000, 3)) + [0.1, 0, 0.05]
    assert not BENCH["MeshSolid"](plate).contains(q).any() and not plate.contains(q).any()
    ur5 = [g for g in sph.link_geometries(genplan.load("ur5")) if g.kind == "mesh"]
    agree = total = 0
    for g in ur5:
        v = g.vertices @ g.placement[:3, :3].T + g.placement[:3, 3]
        x = rng.uniform(v.min(axis=0), v.max(axis=0), (2000, 3))
        agree += int((BENCH["MeshSolid"](g).contains(x) == g.contains(x)).sum())
        total += len(x)
    # the few others lie where shells of one mesh overlap with opposite orientations, which the
    # winding number sums to 0 and MeshSolid, with the generator, counts inside their union
    assert agree >= 0.999 * total


def test_attached_spheres_refuse_a_bad_padding_or_max_error(panda) -> None:
    """attached_spheres checks its parameters as robot_spheres does, naming them."""
    from genplan.scene import Box
    from genplan.spheres import attached_spheres

    held = panda.with_attached("block", Box("block", (0.02, 0.02, 0.02)), link="panda_hand")
    for bad in (float("nan"), -1e-3, 0.5, True):
        with pytest.raises(SettingsError, match="padding"):
            attached_spheres(held.attached["block"], padding=bad)
    with pytest.raises(SettingsError, match="max_error"):
        attached_spheres(held.attached["block"], max_error=0.0)
    centers, radii = attached_spheres(held.attached["block"])
    assert centers.shape == (len(radii), 3) and np.all(radii > 0)
