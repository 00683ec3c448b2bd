"""Property tests (hypothesis) over genplan's public entry points: any input -- shapes, dtypes,
NaN/inf, extreme magnitudes, empty batches, lists, objects, strings -- either gives finite output
of the documented shape, or raises a :mod:`genplan.errors` class (a ``GenplanError``); never
another exception type, never a Rust panic (``pyo3_runtime.PanicException``, a BaseException),
never NaN out without an error (issue 15, "Also").

Exceptions to "a GenplanError", where they are the documented or the Python-conventional answer:
an argument of the wrong Python *type* (``None``, a string or a list where a number or a name is
expected) may raise TypeError; ``adjust`` raises FloatingPointError when an update diverges
(documented); the planner's per-call callbacks are not fuzzed here.

Known gaps are findings: each has its own narrow test below, marked ``xfail(strict=True)`` with
the finding in its reason, and the general properties leave exactly that input out (a comment
naming the finding marks the exemption). When a gap is closed its test passes, strict xfail turns
that into a failure, and the test's mark and the exemption go; a fixed finding's test stays, as a
plain test. "Valid" input follows the documented bounds (e.g. 1e6 on lengths, obstacle sizes and
projection targets), cited where they are used. The Rust twins of some findings are in
``rust/core/tests/fuzz_*.rs``.

Runs are deterministic (hypothesis ``derandomize``) with small example counts; to search harder:
``GENPLAN_FUZZ_PROFILE=explore .venv/bin/python -m pytest tests/test_fuzz_inputs.py`` (random,
20x the examples).
"""

from __future__ import annotations

import math
import os
import pickle
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import genplan
from genplan import pancake
from genplan import projection as P
from genplan.errors import (GenplanError, InvalidGoalError, InvalidStartError, ModelFileError, NonFiniteError,
                            SettingsError, ShapeError, UnknownNameError)

# --------------------------------------------------------------------------------------------
# Settings profiles, the call wrapper, strategies
# --------------------------------------------------------------------------------------------

_QUIET = [HealthCheck.function_scoped_fixture, HealthCheck.too_slow, HealthCheck.data_too_large,
          HealthCheck.filter_too_much]
settings.register_profile("genplan-fuzz-ci", deadline=None, database=None, derandomize=True,
                          suppress_health_check=_QUIET, print_blob=True)
settings.register_profile("genplan-fuzz-explore", deadline=None, database=None, derandomize=False,
                          suppress_health_check=_QUIET, print_blob=True)
_EXPLORE = os.environ.get("GENPLAN_FUZZ_PROFILE") == "explore"
_PROFILE = settings.get_profile("genplan-fuzz-explore" if _EXPLORE else "genplan-fuzz-ci")


def fuzz(max_examples: int) -> settings:
    """The profile's settings with ``max_examples`` (20x when exploring)."""
    return settings(_PROFILE, max_examples=max_examples * (20 if _EXPLORE else 1))


def call(f: Callable[..., Any], *args: Any, errors: tuple[type[BaseException], ...] = (GenplanError,),
         **kwargs: Any) -> tuple[Any, BaseException | None]:
    """``(result, None)``, or ``(None, error)`` for an error of an allowed type; a panic or any
    other exception fails the test."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # LimitWarning and the like are part of an answer
            return f(*args, **kwargs), None
    except BaseException as exc:  # noqa: BLE001 -- a PanicException is a BaseException
        if type(exc).__name__ == "PanicException":
            pytest.fail(f"a Rust panic crossed into Python from {getattr(f, '__qualname__', f)}: {exc}")
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        if not isinstance(exc, errors):
            pytest.fail(f"{getattr(f, '__qualname__', f)} raised {type(exc).__module__}.{type(exc).__qualname__} "
                        f"(allowed: {[e.__name__ for e in errors]}): {exc}")
        return None, exc


def finite(x: Any) -> bool:
    a = np.asarray(x)
    return a.dtype == bool or bool(np.all(np.isfinite(a)))


#: numbers of every kind: ordinary, extreme, not finite
SPECIAL = [0.0, -0.0, 1e300, -1e300, 1.7976931348623157e308, 5e-324, np.nan, np.inf, -np.inf]
NUMBERS = st.one_of(st.floats(-4, 4), st.sampled_from(SPECIAL), st.floats())
SANE = st.floats(-3, 3)
DTYPES = [np.float64, np.float32, np.float16, np.int64, np.int8, np.uint8, np.bool_, object, np.complex128]


def numeric_arrays(shape: Any, elements: Any = NUMBERS) -> Any:
    """float64 arrays of ``shape`` cast to a random dtype (ints, bools, objects, float16,
    complex...)."""
    def cast(a_dt: tuple[np.ndarray, Any]) -> np.ndarray:
        a, dt = a_dt
        with np.errstate(all="ignore"):
            return a.astype(dt)
    return st.tuples(hnp.arrays(np.float64, shape, elements=elements), st.sampled_from(DTYPES)).map(cast)


def configurations(nq: int) -> Any:
    """Anything a caller might pass as configurations for a robot with ``nq`` joints."""
    good_shapes = st.one_of(st.just((nq,)), st.tuples(st.integers(0, 3), st.just(nq)))
    any_shape = hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=nq + 2)
    return st.one_of(
        hnp.arrays(np.float64, good_shapes, elements=SANE),  # valid
        numeric_arrays(st.one_of(good_shapes, any_shape)),
        hnp.arrays(np.float64, good_shapes, elements=NUMBERS).map(lambda a: a.tolist()),  # lists
        st.lists(st.lists(SANE, max_size=nq + 1), max_size=3),  # ragged lists
        hnp.arrays("U4", good_shapes, elements=st.text(alphabet="ab1.e-n ", max_size=4)),  # strings
        hnp.arrays(np.complex128, good_shapes, elements=st.complex_numbers(max_magnitude=3)),  # finding PY-4
        st.sampled_from([None, "q", 3.0, {"q": 1}, object()]),
    )


def reals(x: Any) -> np.ndarray | None:
    """The oracle for numbers: ``x`` as float64 as numpy reads it (strings that parse included),
    or None where it is not real numbers: unreadable, or complex even with a zero imaginary part
    (finding PY-4: numpy would drop the imaginary part)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            a = np.asarray(x)
            if a.dtype.kind == "c":
                return None
            return np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError, Warning):
        return None


#: rust/core/src/urdf.rs: the bound on a revolute or prismatic joint's value (finding URDF-7)
MAX_JOINT_POSITION = 1e16


def read_configurations(x: Any, nq: int, floating_base: bool = False) -> np.ndarray | None:
    """The oracle: ``x`` as valid configurations, (nq,) or (n, nq) finite floats (a free-flyer
    quaternion not zero; each joint value at most 1e16 in magnitude, the robots fuzzed here
    having only revolute joints besides the base: finding URDF-7), or None."""
    a = reals(x)
    if a is None:
        return None
    if a.ndim not in (1, 2) or a.shape[-1] != nq or not np.all(np.isfinite(a)):
        return None
    if np.any(np.abs(a[..., 7:] if floating_base else a) > MAX_JOINT_POSITION):
        return None
    with np.errstate(over="ignore"):
        if floating_base and np.any(np.linalg.norm(a[..., 3:7], axis=-1) < 1e-9):
            return None
    return a


def expect_refused(x: Any, exc: BaseException | None, what: str) -> None:
    assert exc is not None, f"{what}: accepted an invalid input {x!r}"
    assert isinstance(exc, GenplanError), f"{what}: {type(exc).__name__} for a malformed input: {exc}"


def rigid(poses: np.ndarray) -> bool:
    r = poses[..., :3, :3]
    eye = np.eye(3)
    return bool(np.all(np.abs(np.swapaxes(r, -1, -2) @ r - eye) < 1e-6)) and bool(np.all(poses[..., 3, :] == [0, 0, 0, 1]))


# --------------------------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def panda_world(panda: genplan.Robot) -> genplan.CollisionWorld:
    return panda.collision_world()


@pytest.fixture(scope="module")
def shelf(panda: genplan.Robot) -> Any:
    """The shelf environment, a planner with a small budget, one query."""
    from genplan.planning import Planner, PlannerSettings, environment

    env = environment("panda_shelf")
    world = env.world(panda)
    planner = Planner(panda, world=world, settings=PlannerSettings(max_extensions=40, retries=0))
    return env, world, planner, env.queries(panda, n=1, seed=0)[0]


@pytest.fixture(scope="module")
def ik(panda: genplan.Robot) -> Any:
    task = P.panda_task("ik")
    return task, P.GaussNewtonProjector(panda, task)


@pytest.fixture(scope="module")
def gan(panda: genplan.Robot) -> Any:
    from genplan.samplers.sampler import GanSampler

    return GanSampler(panda, seed=0)


# --------------------------------------------------------------------------------------------
# Robots: link_poses, random_configurations
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["panda", "talos"])
@fuzz(60)
@given(data=st.data())
def test_link_poses(name: str, data: Any) -> None:
    robot = genplan.load(name)
    n_links = robot.link_poses(robot.q_default).shape[0]
    q = data.draw(configurations(robot.nq), label="q")
    poses, exc = call(robot.link_poses, q)
    valid = read_configurations(q, robot.nq, robot.floating_base)
    if valid is None:
        return expect_refused(q, exc, "link_poses")
    assert exc is None, f"link_poses refused valid q: {exc}"
    assert poses.shape == valid.shape[:-1] + (n_links, 4, 4) and poses.dtype == np.float64
    assert finite(poses), f"non-finite poses for finite q {valid!r}"
    # a huge free-flyer quaternion too: finding PY-5 (fixed)
    assert rigid(poses), f"poses that are not rigid transforms for q {valid!r}"


@fuzz(40)
@given(links=st.one_of(st.none(), st.lists(st.sampled_from(["panda_hand", "panda_link0", "panda_hand_tcp", "", "nope"]),
                                            max_size=4)))
def test_link_poses_by_name(panda: genplan.Robot, links: Any) -> None:
    n_links = panda.link_poses(panda.q_default).shape[0]
    poses, exc = call(panda.link_poses, panda.q_default, links)
    if links is None or all(n.startswith("panda_") for n in links):
        assert exc is None, exc
        assert poses.shape == (n_links if links is None else len(links), 4, 4) and finite(poses)
    else:
        assert isinstance(exc, UnknownNameError), f"an unknown link name gave {exc!r}"


@fuzz(40)
@given(n=st.one_of(st.integers(-3, 50), st.sampled_from([True, 2.0, "3", None, np.int64(3), np.int8(-1)])),
       seed=st.one_of(st.none(), st.integers(-3, 2**32)))
def test_random_configurations(panda: genplan.Robot, n: Any, seed: Any) -> None:
    q, exc = call(panda.random_configurations, n, seed, errors=(GenplanError, TypeError))
    if seed is not None and seed < 0 and isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 0:
        assert isinstance(exc, SettingsError) and str(exc).startswith("rng:"), f"seed {seed}: {exc!r}"  # PY-10 (fixed)
        return
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        assert isinstance(exc, TypeError) and str(exc).startswith("n:"), f"random_configurations({n!r}): {exc!r}"
        return
    if n < 0:  # finding PY-3 (fixed)
        assert isinstance(exc, ShapeError) and str(exc).startswith("n:"), f"random_configurations({n!r}): {exc!r}"
        return
    assert exc is None and q.shape == (n, panda.nq) and finite(q)
    assert np.all((panda.lower <= q) & (q <= panda.upper)), "a random configuration outside the limits"


# finding PY-3 (fixed for n): random_configurations did not check n: n=-1 raised numpy's plain
# ValueError ('negative dimensions are not allowed'); now a ShapeError naming n (python/genplan/robots.py)
def test_random_configurations_refuses_a_negative_count_with_a_genplan_error(panda: genplan.Robot) -> None:
    _, exc = call(panda.random_configurations, -1, None)
    assert isinstance(exc, ShapeError) and str(exc).startswith("n:"), repr(exc)


# finding PY-10 (fixed; the rest of PY-3): random_configurations passed rng to
# np.random.default_rng unchecked: rng=-1 raised numpy's plain ValueError; now a SettingsError naming rng
def test_random_configurations_refuses_a_negative_seed_with_a_genplan_error(panda: genplan.Robot) -> None:
    _, exc = call(panda.random_configurations, 2, -1, errors=(BaseException,))
    assert isinstance(exc, GenplanError) and "rng" in str(exc), repr(exc)


# finding PY-4 (fixed): a complex array was accepted as configurations (numpy dropped the imaginary
# part with only a ComplexWarning): link_poses(np.zeros(7) + 1j) returned the poses of zeros
@pytest.mark.parametrize("q", [np.zeros(7) + 1j, np.zeros(7, dtype=np.complex64), np.array([np.complex128(1)] * 7, dtype=object),
                               [1j] * 7], ids=["complex128", "zero-imaginary", "object", "list"])
def test_complex_configurations_are_refused(panda: genplan.Robot, q: Any) -> None:
    _, exc = call(panda.link_poses, q)
    assert isinstance(exc, ShapeError) and "complex" in str(exc) and str(exc).startswith("q:"), exc
    _, exc = call(panda.collision_world().min_distance, q)
    assert isinstance(exc, ShapeError), exc


# finding PY-5 (fixed; Rust URDF-3): a free-flyer quaternion with huge finite components (1e300)
# passed the configuration check (it only refuses a zero norm), its norm overflowed and it
# normalised to zero: Talos link_poses answered rotation blocks of zeros, not rigid transforms.
# Now normalised without overflow (rust/core/src/kinematics.rs, KinematicModel::base_pose).
def test_a_huge_base_quaternion_gives_rigid_poses(talos: genplan.Robot) -> None:
    q = talos.q_default.copy()
    q[3:7] = 1e300
    poses, exc = call(talos.link_poses, q)
    assert exc is None and rigid(poses), exc
    q[3:7] = 0.5
    assert np.allclose(poses, talos.link_poses(q), atol=1e-12), "not the poses of the normalised quaternion"


# --------------------------------------------------------------------------------------------
# Robot files: a robot loads as its files say, or is refused (issue 35, finding 5)
# --------------------------------------------------------------------------------------------

@st.composite
def robot_files(draw: Any) -> tuple[str, str | None, str]:
    """A robot file (TOML text) for MIMIC (as mimic.urdf) and an SRDF for it (as arm.srdf), or
    None: every key with sensible and absurd values, states and pairs naming known and unknown
    joints and links; and MIMIC with its mimic, j2's type and j1's limits changed. Each choice
    is a sensible one three times in four, so that a good share of the robots load."""
    import json

    from tests.test_robots import MIMIC

    def pick(sensible: list[str], absurd: list[str]) -> str:
        return draw(st.one_of(st.sampled_from(sensible), st.sampled_from(sensible), st.sampled_from(sensible),
                              st.sampled_from(absurd)))

    mimic = '<mimic joint="j1" multiplier="-2" offset="0.1"/>'
    urdf = (MIMIC.replace(mimic, pick([mimic, '<mimic joint="j1" multiplier="0.5"/>', ""],
                                      ['<mimic joint="j3"/>', '<mimic joint="nope"/>', '<mimic joint="j2"/>',
                                       '<mimic joint="j1" multiplier="1e7"/>', '<mimic joint="j1" offset="nan"/>', "<mimic/>"]))
            .replace('<joint name="j2" type="revolute">',
                     f'<joint name="j2" type="{pick(["revolute", "prismatic"], ["continuous", "fixed"])}">')
            .replace('<limit lower="-1" upper="1"', f'<limit lower="{pick(["-1", "0.5"], ["1", "nan"])}" upper="1"'))
    srdf = None
    if draw(st.booleans()):
        parts = []
        for _ in range(draw(st.integers(0, 3))):
            a, b = pick(["base", "l1", "l2", "l3"], ["l9", ""]), pick(["base", "l1", "l2", "l3"], ["l9", ""])
            parts.append(f'<disable_collisions link1="{a}" link2="{b}"/>')
        for name in draw(st.lists(st.sampled_from(["home", "other", ""]), max_size=2, unique=True)):
            joints = "".join(
                f'<joint name="{j}" value="{pick(["0", "0.5", "-0.5", "0.1"], ["-1", "2.5", "100", "nan", "1e17", "abc", "0 0 0 0 0 0 1", "1 2", ""])}"/>'
                for j in draw(st.lists(st.sampled_from(["j1", "j3", "j1", "j3", "j2", "root_joint", "j7", ""]), max_size=3, unique=True)))
            parts.append(f'<group_state name="{name}" group="all">{joints}</group_state>')
        srdf = f'<robot name="mimic">{"".join(parts)}</robot>'
    lines = ['urdf = "mimic.urdf"']
    if srdf is not None:
        lines.append('srdf = "arm.srdf"')
        if draw(st.booleans()):
            lines.append(f"reference_state = {json.dumps(pick(['home', 'other'], ['nope']))}")
    locked = draw(st.lists(st.sampled_from(["j1", "j2", "j3", "j1", "j3", "j7"]), max_size=2, unique=True))
    if locked and draw(st.booleans()):
        values = ", ".join(f"{j} = {pick(['0.0', '0.5', '0.05', '-0.5'], ['2.5', '100.0'])}" for j in locked)
        lines.append(f"locked_joints = {{ {values} }}")
    elif locked:
        lines.append(f"locked_joints = {json.dumps(locked)}")
    for key, sensible, absurd in [("floating_base", ["true", "false"], ["1"]), ("merge_computed_pairs", ["true", "false"], ['"yes"']),
                                  ("name", ['"arm"'], ['"a/b"', '".."', '""'])]:
        if draw(st.booleans()):
            lines.append(f"{key} = {pick(sensible, absurd)}")
    frames = {}
    for _ in range(draw(st.integers(0, 2))):
        frames[pick(["tool", "hand", "l3"], ["l1", ""])] = pick(["l1", "l2", "l3"], ["l9", "j1", ""])
    if frames:
        lines.append("[frames]")
        lines += [f"{json.dumps(role)} = {json.dumps(link)}" for role, link in frames.items()]
    return "\n".join(lines) + "\n", srdf, urdf


@fuzz(80)
@given(files=robot_files())
def test_robot_files_load_as_they_say_or_are_refused(tmp_path: Path, files: tuple[str, str | None, str]) -> None:
    """A robot file, its URDF (with mimic joints) and its SRDF, absurd values and unknown names
    included: ``genplan.load`` raises a GenplanError naming the file, or gives a robot that is
    what the files say: mimic joints follow their masters (the Rust kinematics and Pinocchio
    agree), locked and default values lie within the limits, frames name links, the SRDF's
    pairs name links; warnings are RobotWarnings only."""
    import unittest.mock
    import xml.etree.ElementTree as ET

    import pinocchio as pin

    from genplan.errors import RobotWarning

    toml, srdf, urdf = files
    folder = _fresh(tmp_path)
    (folder / "mimic.urdf").write_text(urdf)
    if srdf is not None:
        (folder / "arm.srdf").write_text(srdf)
    (folder / "arm.toml").write_text(toml)
    with unittest.mock.patch.dict(os.environ, {"GENPLAN_CACHE": str(folder / "cache")}), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            robot = genplan.load(folder / "arm.toml")
        except GenplanError as exc:
            event(f"robot file: {type(exc).__name__}")
            assert "arm.toml" in str(exc) or "arm.srdf" in str(exc) or "mimic.urdf" in str(exc), exc
            return
        except BaseException as exc:  # noqa: BLE001 -- a PanicException is a BaseException
            pytest.fail(f"genplan.load raised {type(exc).__module__}.{type(exc).__qualname__}: {exc}")
    event("robot file: loaded")
    assert all(issubclass(w.category, RobotWarning) for w in caught), [str(w.message) for w in caught]
    assert robot.nq == robot.kinematics.nq == robot.model.nq
    assert robot.joint_names == robot.kinematics.active_joints
    joints = {j.get("name"): j for j in ET.fromstring(urdf).findall("joint")}
    for name, j in joints.items():  # a joint that mimics another is no coordinate of its own
        assert j.find("mimic") is None or j.get("type") == "fixed" or name not in robot.joint_names, name
    for name, value in robot.locked_joints.items():
        j = joints[name]
        lo, hi = float(j.find("limit").get("lower")), float(j.find("limit").get("upper"))
        mimic = j.find("mimic")
        if mimic is not None and mimic.get("joint") in robot.locked_joints and j.get("type") in ("revolute", "prismatic"):
            continue  # locked with its master, at the value it follows (checked by the poses below)
        assert j.get("type") == "continuous" or lo <= value <= hi, (name, value)
    bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    assert np.all(robot.q_default[bounded] >= robot.lower[bounded]) and np.all(robot.q_default[bounded] <= robot.upper[bounded])
    assert set(robot.frames.values()) <= set(robot.kinematics.link_names)
    assert all(a in robot.kinematics.link_names and b in robot.kinematics.link_names for a, b in robot.disabled_pairs)
    for q in [robot.q_default, *robot.random_configurations(3, 0)]:
        pin.framesForwardKinematics(robot.model, robot.data, q)
        poses = robot.link_poses(q)
        for i, link in enumerate(robot.kinematics.link_names):
            np.testing.assert_allclose(poses[i], robot.data.oMf[robot.model.getFrameId(link, pin.BODY)].homogeneous, atol=1e-9)


# --------------------------------------------------------------------------------------------
# Collision world: queries and obstacles
# --------------------------------------------------------------------------------------------


@fuzz(60)
@given(data=st.data())
def test_collision_queries(panda: genplan.Robot, panda_world: genplan.CollisionWorld, data: Any) -> None:
    q = data.draw(configurations(panda.nq), label="q")
    valid = read_configurations(q, panda.nq)
    hit, exc1 = call(panda_world.in_collision, q)
    dist, exc2 = call(panda_world.min_distance, q)
    if valid is None:
        expect_refused(q, exc1, "in_collision")
        return expect_refused(q, exc2, "min_distance")
    assert exc1 is None and exc2 is None, (exc1, exc2)
    hit, dist = np.asarray(hit), np.asarray(dist)
    assert hit.shape == dist.shape == valid.shape[:-1] and hit.dtype == bool and finite(dist)
    assert np.all(dist[hit] <= 1e-9) and np.all(dist[~hit] >= -1e-9), "min_distance disagrees with in_collision"
    if valid.ndim == 1:
        pairs, exc = call(panda_world.close_pairs, valid, 10.0)
        assert exc is None and pairs, "close_pairs within 10 m found nothing"
        closest = min(p[2] for p in pairs)
        assert abs(closest - float(dist)) < 1e-6, f"closest pair {closest} != min_distance {float(dist)}"


def test_min_distance_is_the_deepest_penetration(panda_world: genplan.CollisionWorld) -> None:
    """COL-1 (fixed): overlapping bounding boxes were skipped once a penetration was found."""
    q = [-1.966, 1.657, 0.093, -2.724, 0.716, 2.911, 0.655]
    closest = min(p[2] for p in panda_world.close_pairs(q, 1.0))
    assert abs(float(panda_world.min_distance(q)) - closest) < 1e-6


#: numbers at the documented bound 1e6 of obstacle sizes and positions (rust/core/src/collision/world.rs)
#: and of projection targets (rust/core/src/projection/validate.rs), and just beyond
AT_1E6 = st.sampled_from([1e6, -1e6, float(np.nextafter(1e6, 2e6)), -float(np.nextafter(1e6, 2e6)), 1e-12, 2e-12])


def vec3s() -> Any:
    return st.one_of(st.tuples(NUMBERS, NUMBERS, NUMBERS), st.tuples(SANE, SANE, SANE),
                     st.tuples(st.one_of(SANE, AT_1E6), st.one_of(SANE, AT_1E6), st.one_of(SANE, AT_1E6)),
                     numeric_arrays(hnp.array_shapes(min_dims=0, max_dims=2, max_side=4)))


def read_vec3(v: Any) -> np.ndarray | None:
    a = reals(v)
    if a is None:
        return None
    a = a.reshape(-1)
    return a if a.shape == (3,) else None


@fuzz(60)
@given(kind=st.sampled_from(["box", "sphere", "halfspace"]), a=vec3s(), b=vec3s(),
       r=st.one_of(NUMBERS, st.floats(0.01, 0.5), AT_1E6), rot=st.one_of(st.none(), numeric_arrays((3, 3)),
                                                                 st.just(np.eye(3)), numeric_arrays((2, 2))))
def test_obstacles(panda: genplan.Robot, kind: str, a: Any, b: Any, r: float, rot: Any) -> None:
    with np.errstate(all="ignore"):
        obstacle(panda, kind, a, b, r, rot)


#: The documented bounds of an obstacle (rust/core/src/collision/world.rs): sizes (half extents,
#: radii) in (0, MAX_EXTENT], centre coordinates and half-space offsets within MAX_EXTENT of 0 (m);
#: a half-space normal longer than MIN_NORMAL (any finite length above it: findings COL-2, COL-3,
#: fixed); a box rotation proper within ROTATION_TOLERANCE (rust/python/src/lib.rs, pose_from).
MAX_EXTENT, MIN_NORMAL, ROTATION_TOLERANCE = 1e6, 1e-12, 1e-6


def norm_without_overflow(v: np.ndarray) -> float:
    m = float(np.max(np.abs(v)))
    return 0.0 if m == 0.0 else m * float(np.linalg.norm(v / m))


def proper_rotation(r: np.ndarray) -> bool:
    return bool(finite(r) and np.max(np.abs(r.T @ r - np.eye(3))) <= ROTATION_TOLERANCE
                and abs(np.linalg.det(r) - 1.0) <= ROTATION_TOLERANCE)


def obstacle(panda: genplan.Robot, kind: str, a: Any, b: Any, r: float, rot: Any) -> None:
    world = panda.collision_world()
    va, vb = read_vec3(a), read_vec3(b)

    def position_ok(v: np.ndarray | None) -> bool:
        return bool(v is not None and finite(v) and np.all(np.abs(v) <= MAX_EXTENT))

    if kind == "box":
        out, exc = call(world.add_box, "o", a, b, rot)
        r3 = None if rot is None else reals(rot)
        rot_ok = rot is None or (r3 is not None and r3.shape == (3, 3) and proper_rotation(r3))
        ok = bool(va is not None and finite(va) and np.all((va > 0) & (va <= MAX_EXTENT)) and position_ok(vb) and rot_ok)
    elif kind == "sphere":
        out, exc = call(world.add_sphere, "o", r, b)
        ok = bool(position_ok(vb) and math.isfinite(r) and 0 < r <= MAX_EXTENT)
    else:
        out, exc = call(world.add_halfspace, "o", a, r)
        ok = bool(va is not None and finite(va) and norm_without_overflow(va) > MIN_NORMAL
                  and math.isfinite(r) and abs(r) <= MAX_EXTENT)
    assert (exc is None) == ok, f"add_{kind}: {'refused valid' if ok else 'accepted invalid'} input: {exc}"
    if ok:
        assert world.obstacle_names == ["o"]
        _, exc = call(world.add_sphere, "o", 0.1, [0, 0, 0])
        assert isinstance(exc, GenplanError), "a second obstacle with the same name"
        d = np.asarray(world.min_distance(panda.random_configurations(4, 0)))
        assert d.shape == (4,) and finite(d)


# finding COL-2 (fixed; Rust fuzz_collision): a half-space normal whose squared norm overflowed
# ([0, 0, 1e300]) was normalised to the zero vector instead of refused (a zero normal is refused);
# the world then held a degenerate half-space and min_distance was wrong. Now any finite normal
# longer than 1e-12 is normalised without overflow (rust/core/src/collision/world.rs, unit_normal).
def test_a_huge_half_space_normal_is_normalised_or_refused(panda: genplan.Robot) -> None:
    a, b = panda.collision_world(), panda.collision_world()
    _, exc = call(a.add_halfspace, "floor", [0, 0, 1e300], 0.1)
    b.add_halfspace("floor", [0, 0, 1], 0.1)
    q = panda.q_default
    assert exc is None, exc
    assert float(a.min_distance(q)) == pytest.approx(float(b.min_distance(q)))


def _adjust(x: Any, **kw: Any) -> Any:
    from genplan.pancake import adjust

    return adjust(x, updates=0, **kw)


def _execute(x: Any, **kw: Any) -> Any:
    from genplan import control

    return control.execute(x, **{"settle": 0.0, **kw})


_X = pancake.s_curve([0, 0, 0], [0.01, 0, 0], K=500)

#: finding PY-2 (fixed): strings (and other objects that are not numbers) where numbers are
#: expected leaked a plain ValueError from numpy or float(). Now a GenplanError naming the
#: argument, from every entry point: (call, the argument the message must name)
STRING_CASES: dict[str, tuple[Callable[[genplan.Robot], Any], str]] = {
    "add_sphere radius": (lambda r: r.collision_world().add_sphere("s", "x", [0, 0, 0]), "radius"),  # type: ignore[arg-type]
    "add_sphere center": (lambda r: r.collision_world().add_sphere("s", 0.1, "abc"), "center"),
    "add_box half_extents": (lambda r: r.collision_world().add_box("b", "abc", [0, 0, 0]), "half_extents"),
    "add_box rotation": (lambda r: r.collision_world().add_box("b", [1, 1, 1], [0, 0, 0], [["a"] * 3] * 3), "rotation"),
    "add_halfspace offset": (lambda r: r.collision_world().add_halfspace("h", [0, 0, 1], "x"), "offset"),  # type: ignore[arg-type]
    "add_halfspace normal": (lambda r: r.collision_world().add_halfspace("h", {"z": 1}, 0.0), "normal"),
    "close_pairs margin": (lambda r: r.collision_world().close_pairs(r.q_default, "x"), "margin"),  # type: ignore[arg-type]
    "phi acc": (lambda r: pancake.phi(0.0, ["a", "b"]), "acc"),
    "phi theta": (lambda r: pancake.phi("x", [0.0, 0.0]), "theta"),
    "phi g": (lambda r: pancake.phi(0.0, [0.0, 0.0], "g"), "g"),  # type: ignore[arg-type]
    "s_curve p_start": (lambda r: pancake.s_curve("abc", [0, 0, 0]), "p_start"),
    "s_curve K": (lambda r: pancake.s_curve([0, 0, 0], [0, 0, 1], "abc"), "K"),  # type: ignore[arg-type]
    "s_curve dt": (lambda r: pancake.s_curve([0, 0, 0], [0, 0, 1], 5, "x"), "dt"),  # type: ignore[arg-type]
    "linear p_end": (lambda r: pancake.linear([0, 0, 0], ["a", 0, 0]), "p_end"),
    "solve_batch targets": (lambda r: P.GaussNewtonProjector(r, P.panda_task("ik")).solve_batch(
        np.zeros((2, 7)), targets={"hand_position": "ab"}), "targets"),
    "adjust x_in": (lambda r: _adjust("abc"), "x_in"),
    "adjust p_end": (lambda r: _adjust(_X, p_end="abc"), "p_end"),
    "adjust seed": (lambda r: _adjust(_X, seed="abc"), "seed"),
    "adjust max_step": (lambda r: _adjust(_X, max_step="abc"), "max_step"),
    "execute trajectory": (lambda r: _execute([["a", "b", "c"]] * 3), "trajectory"),
    "execute tail": (lambda r: _execute(_X, tail="x"), "tail"),
    "execute settle": (lambda r: _execute(_X, settle="x"), "settle"),
    "gan sample_for targets": (lambda r: _gan_sampler(r).sample_for([["a", "b", "c"]]), "targets"),
}


def _gan_sampler(robot: genplan.Robot) -> Any:
    from genplan.samplers.sampler import GanSampler

    return GanSampler(robot, seed=0)


@pytest.mark.parametrize("case", sorted(STRING_CASES))
def test_strings_where_numbers_are_expected_raise_a_genplan_error(panda: genplan.Robot, case: str) -> None:
    f, name = STRING_CASES[case]
    _, exc = call(f, panda, errors=(BaseException,))
    assert isinstance(exc, GenplanError), f"{type(exc).__name__}: {exc}"
    assert name in str(exc), f"the message does not name {name}: {exc}"


# --------------------------------------------------------------------------------------------
# Projection: solve, solve_batch (with targets)
# --------------------------------------------------------------------------------------------

#: The largest absolute value of a term's numbers and of the damping settings (rust/core/src/projection/validate.rs)
P_MAX_MAGNITUDE = 1e6


def check_solution(task: Any, panda: genplan.Robot, q: np.ndarray, success: Any, residuals: dict[str, Any]) -> None:
    assert finite(q), f"a non-finite solution {q!r}"
    assert np.all((panda.lower - 1e-9 <= q) & (q <= panda.upper + 1e-9)), "a solution outside the limits"
    tol = {t.name: t.tolerance for t in task.primary}
    for name, r in residuals.items():
        r = np.asarray(r)
        assert finite(r) and np.all(r >= 0), f"residual {name} {r!r}"
        assert np.all(r[np.asarray(success)] < tol[name]), f"success with residual {name} over its tolerance"


@fuzz(50)
@given(data=st.data())
def test_solve(panda: genplan.Robot, ik: Any, data: Any) -> None:
    task, proj = ik
    q0 = data.draw(configurations(panda.nq), label="q0")
    q_nom = data.draw(st.one_of(st.none(), configurations(panda.nq)), label="q_nom")
    res, exc = call(proj.solve, q0, q_nom)
    v0, vn = read_configurations(q0, panda.nq), None if q_nom is None else read_configurations(q_nom, panda.nq)
    if v0 is None or v0.ndim != 1 or (q_nom is not None and (vn is None or vn.shape not in ((panda.nq,), (1, panda.nq)))):
        return expect_refused((q0, q_nom), exc, "solve")
    if vn is not None and vn.shape == (1, panda.nq) and exc is not None:
        return  # one row of nominals: either way
    assert exc is None, f"solve refused valid input: {exc}"
    assert res.q.shape == (panda.nq,)
    check_solution(task, panda, res.q, res.success, res.residuals)


@fuzz(50)
@given(data=st.data())
def test_solve_batch_with_targets(panda: genplan.Robot, ik: Any, data: Any) -> None:
    task, proj = ik
    n = data.draw(st.integers(0, 3), label="n")
    q0s = data.draw(st.one_of(hnp.arrays(np.float64, (n, panda.nq), elements=SANE), configurations(panda.nq)), label="q0s")
    targets = data.draw(st.one_of(
        st.none(),
        hnp.arrays(np.float64, (n, 3), elements=st.floats(-1, 1)),
        numeric_arrays(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4)),
        hnp.arrays(np.float64, (n, 3), elements=NUMBERS),
        hnp.arrays(np.float64, (n, 3), elements=st.one_of(st.floats(-1, 1), AT_1E6)),
    ), label="targets")
    res, exc = call(proj.solve_batch, q0s, targets=None if targets is None else {"hand_position": targets})
    qs = read_configurations(q0s, panda.nq)
    if qs is None or qs.ndim != 2:
        return expect_refused(q0s, exc, "solve_batch")
    if targets is not None:
        t = reals(targets)
        # a term's numbers finite and at most 1e6 in absolute value (rust/core/src/projection/validate.rs,
        # MAX_MAGNITUDE): finding PROJ-1 (fixed)
        if t is None or t.shape != (len(qs), 3) or not finite(t) or np.any(np.abs(t) > P_MAX_MAGNITUDE):
            assert isinstance(exc, GenplanError), f"targets {targets!r} accepted: {exc}"
            return
    assert exc is None, f"solve_batch refused valid input: {exc}"
    assert res.q.shape == qs.shape and len(res) == len(qs)
    check_solution(task, panda, res.q, res.success, res.residuals)


# finding PY-11 (fixed): solve_batch checked per-row targets only by their row count and each row's
# count of numbers (it reshapes them to (n, -1)): an empty batch took targets of any shape, and
# (n, 1, 3) passed as (n, 3); now the term's row shape is checked (python/genplan/projection.py)
@pytest.mark.parametrize("n, shape", [(0, (0,)), (0, (0, 5)), (1, (1, 1, 3))], ids=["(0,)", "(0,5)", "(1,1,3)"])
def test_mis_shaped_targets_are_refused(ik: Any, n: int, shape: tuple[int, ...]) -> None:
    _, proj = ik
    _, exc = call(proj.solve_batch, np.zeros((n, 7)), targets={"hand_position": np.zeros(shape)})
    assert isinstance(exc, ShapeError) and "targets" in str(exc), repr(exc)


# finding PROJ-1 (fixed; Rust fuzz_projection): targets were only checked to be finite; a huge one
# (1.8e308) made the solver's arithmetic overflow and solve_batch returned an all-NaN q (success
# False) without an error. Now every number of a term is bounded by 1e6 (rust/core/src/projection/validate.rs,
# MAX_MAGNITUDE), per-row targets checked before any work, the error naming the row.
@pytest.mark.parametrize("row", [0, 1])
def test_a_huge_target_gives_a_finite_answer_or_an_error(ik: Any, row: int) -> None:
    _, proj = ik
    targets = np.full((2, 3), 0.5)
    targets[row] = 1.7976931348623157e308
    res, exc = call(proj.solve_batch, np.zeros((2, 7)), targets={"hand_position": targets})
    assert isinstance(exc, GenplanError) and f"targets[{row}]" in str(exc), repr(exc)


# --------------------------------------------------------------------------------------------
# Planning: settings and plan inputs
# --------------------------------------------------------------------------------------------

#: The documented ranges (rust/core/src/planning/rrt.rs, Settings::validate; findings PLAN-1,
#: PLAN-2, fixed): lengths in (0, 1e6]; edge_resolution 0 or in [1e-6, 1e6], and then at least
#: step * max_jump / 2^20 (see edge_states); sample_batch in [1, 65536]
PLAN_MAX_LENGTH, PLAN_MIN_EDGE_RESOLUTION, PLAN_MAX_EDGE_STATES, PLAN_MAX_SAMPLE_BATCH = 1e6, 1e-6, 2**20, 2**16
PLANNER_FLOATS = {"step": "length", "max_jump": "length", "goal_tolerance": "length", "edge_resolution": "resolution"}
#: counts: (least, largest)
PLANNER_COUNTS = {"max_increments": (1, 2**64 - 1), "max_extensions": (1, 2**64 - 1), "retries": (0, 2**64 - 1),
                  "sample_batch": (1, PLAN_MAX_SAMPLE_BATCH), "max_empty_batches": (1, 2**64 - 1)}
PLANNER_FLAGS = ["project_samples", "lazy_edges", "simplify"]
PLANNER_DEFAULTS = {"step": 0.3, "max_jump": 3.0, "edge_resolution": 0.025}
#: (rust/core/src/projection/solver.rs, Settings::validate; finding PROJ-1, fixed): the damping in [0, 1e6]
SOLVER_FLOATS = {"mu": "damping", "mu_bar": "damping", "secondary_slack": "damping", "armijo_c1": "unit", "backtrack": "unit"}
SOLVER_COUNTS = {"max_iterations": (0, 2**64 - 1), "max_backtracks": (0, 2**64 - 1), "secondary_backtracks": (0, 2**64 - 1)}
SOLVER_FLAGS = ["clip_to_limits", "active_set"]

#: values at the bounds above and just beyond them
AT_BOUNDS = [1e6, float(np.nextafter(1e6, 2e6)), 1e-6, float(np.nextafter(1e-6, 0)), 1e-300, 2**16, 2**16 + 1, 2**40,
             2**64 - 1]
ANY_VALUE = st.one_of(NUMBERS, st.integers(-5, 100), st.sampled_from([2**63, 2**64, 2**70, -(2**63)]), st.booleans(),
                      st.none(), st.text(max_size=3), st.sampled_from(["auto", "linear", "kdtree", 1.5, [1], 2.0]),
                      st.sampled_from(AT_BOUNDS))


def in_range(kind: str, v: Any) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return False
    return {"length": 0 < v <= PLAN_MAX_LENGTH,
            "resolution": v == 0 or PLAN_MIN_EDGE_RESOLUTION <= v <= PLAN_MAX_LENGTH,
            "damping": 0 <= v <= P_MAX_MAGNITUDE, "unit": 0 < v < 1}[kind]


def edge_states(kw: dict[str, Any]) -> bool | None:
    """A tree edge (at most step * max_jump long) needs at most 2^20 states at edge_resolution;
    None when one of the three is out of its own range (its own verdict decides)."""
    v = {k: kw.get(k, d) for k, d in PLANNER_DEFAULTS.items()}
    if not all(in_range(PLANNER_FLOATS[k], x) for k, x in v.items()):
        return None
    er = float(v["edge_resolution"])
    return er == 0 or float(v["step"]) * float(v["max_jump"]) / er <= PLAN_MAX_EDGE_STATES


def check_settings(cls: Any, floats: dict[str, str], counts: dict[str, tuple[int, int]], flags: list[str],
                   kw: dict[str, Any], extra: Callable[[str, Any], bool | None] = lambda k, v: None,
                   joint: Callable[[dict[str, Any]], bool | None] = lambda kw: None) -> None:
    s, exc = call(cls, **kw)
    verdicts = {}
    for k, v in kw.items():
        verdict = extra(k, v)
        if verdict is None and k in floats:
            verdict = in_range(floats[k], v) if not isinstance(v, str) else False
        elif verdict is None and k in counts:
            verdict = (isinstance(v, int) and not isinstance(v, bool) and counts[k][0] <= v <= counts[k][1]
                       if not isinstance(v, float) else None)  # 2.0: either way
        elif verdict is None and k in flags:
            verdict = True if isinstance(v, bool) else None
        elif verdict is None:
            verdict = False  # unknown key
        verdicts[k] = verdict
    together = joint(kw)  # a bound between fields
    if all(v is True for v in verdicts.values()) and together is not False:
        assert exc is None, f"{cls.__name__}({kw}) refused: {exc}"
    if any(v is False for v in verdicts.values()) or together is False:
        assert isinstance(exc, SettingsError), f"{cls.__name__}({kw}) accepted (or not a SettingsError): {exc!r}"
    if exc is None:
        for k, v in kw.items():
            got = getattr(s, k)
            assert got == v or (isinstance(v, float) and got == pytest.approx(v)), f"{k}: {v!r} read back as {got!r}"
            if k in floats:
                assert in_range(floats[k], got)
        assert pickle.loads(pickle.dumps(s)) == s and s.replace() == s and cls(**s.to_dict()) == s
    else:
        assert isinstance(exc, SettingsError), f"{type(exc).__name__}: {exc}"
        suspects = [k for k, v in verdicts.items() if v is not True] + (["edge_resolution"] if together is False else [])
        assert any(f"{k}" in str(exc) for k in suspects), f"the error names none of {suspects}: {exc}"


def settings_kwargs(fields: list[str]) -> Any:
    keys = st.one_of(st.sampled_from(fields), st.sampled_from(["bogus", "Step", ""]))
    return st.dictionaries(keys, ANY_VALUE, max_size=4)


@fuzz(60)
@given(kw=settings_kwargs([*PLANNER_FLOATS, *PLANNER_COUNTS, *PLANNER_FLAGS, "neighbors"]))
def test_planner_settings(kw: dict[str, Any]) -> None:
    from genplan.planning import PlannerSettings

    def neighbors(k: str, v: Any) -> bool | None:
        return v in ("auto", "linear", "kdtree") if k == "neighbors" else None

    check_settings(PlannerSettings, PLANNER_FLOATS, PLANNER_COUNTS, PLANNER_FLAGS, kw, neighbors, edge_states)


@fuzz(60)
@given(kw=settings_kwargs([*SOLVER_FLOATS, *SOLVER_COUNTS, *SOLVER_FLAGS]))
def test_solver_settings(kw: dict[str, Any]) -> None:
    from genplan.projection import SolverSettings

    check_settings(SolverSettings, SOLVER_FLOATS, SOLVER_COUNTS, SOLVER_FLAGS, kw)


@fuzz(40)
@given(data=st.data())
def test_plan_inputs(panda: genplan.Robot, shelf: Any, data: Any) -> None:
    env, world, planner, query = shelf
    valid_start = st.just(query.start)
    valid_goals = st.sampled_from([query.goals, query.goals[:1], query.goals[-1]])
    start = data.draw(st.one_of(valid_start, valid_start, valid_start, st.just(query.start + 0.3),
                                hnp.arrays(np.float64, panda.nq, elements=st.floats(-1e-4, 1e-4)).map(lambda d: query.start + d),
                                configurations(panda.nq)), label="start")
    goals = data.draw(st.one_of(valid_goals, valid_goals, valid_goals, st.just(np.zeros((0, panda.nq))),
                                st.just(query.goals[None]), st.just(query.goals + 0.3), configurations(panda.nq)),
                      label="goals")
    res, exc = call(planner.plan, start, goals)
    s, g = read_configurations(start, panda.nq), read_configurations(goals, panda.nq)
    if s is None or s.ndim != 1 or g is None or g.size == 0:
        assert exc is not None, f"plan accepted start {start!r}, goals {goals!r}"
        # a joint value beyond 1e16 is an invalid start or goal (finding URDF-7), named as such
        beyond = isinstance(exc, (InvalidStartError, InvalidGoalError)) and "beyond 1e16" in str(exc)
        assert beyond or isinstance(exc, (ShapeError, NonFiniteError)), f"{type(exc).__name__} for malformed input: {exc}"
        return
    if exc is not None:
        assert isinstance(exc, (InvalidStartError, InvalidGoalError)), f"{type(exc).__name__}: {exc}"
        return
    event(f"plan: success {res.success}")
    if not res.success:
        assert res.goal_index is None
        return
    check_path(panda, world, planner.task, res, s, g.reshape(-1, panda.nq), planner.settings.goal_tolerance)


def check_path(panda: genplan.Robot, world: Any, task: Any, res: Any, start: np.ndarray, goals: np.ndarray,
               tol: float) -> None:
    """A success passes its own checks: finite rows from the start to the goal reached, every
    state valid (no collision) and on the manifold."""
    path = np.asarray(res.path)
    assert path.ndim == 2 and path.shape[1] == panda.nq and finite(path)
    assert np.linalg.norm(path[0] - start) <= 2 * tol and np.linalg.norm(path[-1] - goals[res.goal_index]) <= 2 * tol
    assert not np.any(world.in_collision(path)), "a successful path with a state in collision"
    on = P.GaussNewtonProjector(panda, task).solve_batch(path, parallel=False)
    assert on.success.all(), "a successful path with a state off the constraint manifold"


@fuzz(20)
@given(data=st.data())
def test_plans_that_succeed_pass_their_own_checks(panda: genplan.Robot, shelf: Any, data: Any) -> None:
    from genplan.planning import Planner, PlannerSettings

    env, world, _, query = shelf
    kw = data.draw(st.fixed_dictionaries({}, optional={
        "step": st.floats(0.05, 1.0), "edge_resolution": st.floats(5e-3, 0.1), "lazy_edges": st.booleans(),
        "simplify": st.booleans(), "project_samples": st.booleans(), "neighbors": st.sampled_from(["auto", "linear", "kdtree"]),
        "max_increments": st.integers(1, 20), "sample_batch": st.integers(1, 32)}), label="settings")
    sampler = data.draw(st.sampled_from(["uniform", "gan", "hybrid"]), label="sampler")
    order = data.draw(st.permutations(range(len(query.goals))), label="goal order")
    k = data.draw(st.integers(1, len(query.goals)), label="goals used")
    goals = query.goals[list(order)[:k]]
    planner = Planner(panda, world=world, sampler=sampler, seed=data.draw(st.integers(0, 99), label="seed"),
                      settings=PlannerSettings(max_extensions=60, retries=0, **kw))
    res, exc = call(planner.plan, query.start, goals)
    assert exc is None, f"a valid query refused: {exc}"
    event(f"plan: success {res.success}")
    if res.success:
        check_path(panda, world, planner.task, res, query.start, goals, planner.settings.goal_tolerance)
        check_trajectory(panda, world, planner.task, res)


def check_trajectory(panda: genplan.Robot, world: Any, task: Any, res: Any) -> None:
    """A successful plan's trajectory: refused (InvalidTrajectoryError naming a sample), or every
    sample within the joint limits with no tolerance, within the velocity and acceleration
    limits, on the manifold and collision-free."""
    from genplan.errors import InvalidTrajectoryError

    traj, exc = call(res.trajectory)
    if exc is not None:
        assert isinstance(exc, InvalidTrajectoryError) and "sample" in str(exc), repr(exc)
        event("trajectory refused")
        return
    event("trajectory")
    assert finite(traj.q) and finite(traj.qd) and finite(traj.qdd)
    assert (traj.q >= panda.lower).all() and (traj.q <= panda.upper).all(), "a sample outside the joint limits"
    assert (np.abs(traj.qd) <= traj.velocity_limits).all() and (np.abs(traj.qdd) <= traj.acceleration_limits).all()
    assert not np.any(world.in_collision(traj.q)), "a trajectory sample in collision"
    assert traj.within_tolerance


@fuzz(60)
@given(path=st.one_of(st.tuples(st.integers(1, 5), st.integers(0, 2**32 - 1)), configurations(7),
                      hnp.arrays(np.float64, st.tuples(st.integers(1, 5), st.just(7)), elements=st.floats(-3.0, 3.0))),
       rate=st.one_of(st.just(1000.0), st.floats(1.0, 1e4), NUMBERS),
       scale=st.one_of(st.just(1.0), st.floats(1e-3, 1.0), NUMBERS))
def test_parameterize(panda: genplan.Robot, path: Any, rate: Any, scale: Any) -> None:
    """Any path, rate and velocity scale: a trajectory every sample of which is finite and within
    the joint limits with no tolerance (and the velocity and acceleration limits), or a typed
    error: a path outside the joint limits and a rate whose samples would not fit in memory
    included (never an abort)."""
    from genplan.trajectory import parameterize

    if isinstance(path, tuple):  # (n, seed): n states within the limits
        path = panda.random_configurations(path[0], np.random.default_rng(path[1]))
    traj, exc = call(parameterize, panda, path, rate_hz=rate, velocity_scale=scale, errors=(GenplanError, TypeError))
    event(f"parameterize: {type(exc).__name__ if exc else 'timed'}")
    if exc is not None:
        return
    assert finite(traj.t) and finite(traj.q) and finite(traj.qd) and finite(traj.qdd)
    assert (traj.q >= panda.lower).all() and (traj.q <= panda.upper).all(), "a sample outside the joint limits"
    assert (np.abs(traj.qd) <= traj.velocity_limits).all() and (np.abs(traj.qdd) <= traj.acceleration_limits).all()
    states = read_configurations(path, 7)
    assert states is not None and ((states >= panda.lower) & (states <= panda.upper)).all(), "a path outside the limits timed"


# finding PLAN-1 (fixed): PlannerSettings accepted any finite edge_resolution > 0; with 1e-300 the
# edge's state count overflowed and plan() panicked ('capacity overflow', a PanicException in
# Python); 1e-9 asked for tens of GB. Now edge_resolution is 0 or in [1e-6, 1e6] and at least
# step * max_jump / 2^20 (rust/core/src/planning/rrt.rs, Settings::validate): a SettingsError
@pytest.mark.parametrize("kw", [{"edge_resolution": 1e-300}, {"edge_resolution": 1e-9},
                                {"step": 1e6, "max_jump": 1e6, "edge_resolution": 1.0}],
                         ids=["1e-300", "1e-9", "long-edges"])
def test_a_tiny_edge_resolution_is_refused_not_a_panic(kw: dict[str, float]) -> None:
    from genplan.planning import PlannerSettings

    _, exc = call(PlannerSettings, **kw, errors=(BaseException,))
    assert isinstance(exc, SettingsError) and "edge_resolution" in str(exc), repr(exc)


_ABORT = """
import resource
resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))
import genplan
from genplan.errors import GenplanError, SettingsError
from genplan.planning import Planner, PlannerSettings, environment
panda = genplan.load("panda"); env = environment("panda_shelf")
q = env.queries(panda, n=1, seed=0)[0]
try:
    Planner(panda, world=env.world(panda), settings=PlannerSettings(sample_batch=2**40)).plan(q.start, q.goals)
except GenplanError as e:
    assert isinstance(e, SettingsError) and "sample_batch" in str(e), repr(e)
else:
    raise SystemExit("sample_batch=2**40 accepted")
"""


# finding PLAN-2 (fixed): PlannerSettings accepted any sample_batch >= 1; with 2**40 the planner
# allocated sample_batch x nq floats and the process aborted ('memory allocation of 61572651155456
# bytes failed', SIGABRT: no exception, the interpreter died). Now sample_batch is in [1, 65536]
# (rust/core/src/planning/rrt.rs, Settings::MAX_SAMPLE_BATCH): a SettingsError. In a subprocess,
# so that a regression is a failure, not the end of the test run.
def test_a_huge_sample_batch_is_refused_not_an_abort() -> None:
    p = subprocess.run([sys.executable, "-c", _ABORT], capture_output=True, text=True, timeout=300,
                       env={**os.environ, "RUST_BACKTRACE": "0"})
    assert p.returncode == 0, f"exit {p.returncode}: {p.stderr[-300:]}"


# --------------------------------------------------------------------------------------------
# GAN sampler
# --------------------------------------------------------------------------------------------


@fuzz(40)
@given(n=st.one_of(st.integers(-3, 40), st.sampled_from([True, 2.0, 2.5, "3", None, np.int64(3), np.int8(-1)])))
def test_gan_sample(panda: genplan.Robot, gan: Any, n: Any) -> None:
    q, exc = call(gan.sample, n, errors=(GenplanError, TypeError))
    whole = isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 0
    if not whole:
        assert exc is not None, f"sample({n!r}) accepted"
        return
    assert exc is None, f"sample({n!r}): {exc}"
    assert q.shape == (int(n), panda.nq) and finite(q)


@fuzz(50)
@given(targets=st.one_of(
    hnp.arrays(np.float64, st.tuples(st.integers(0, 4), st.just(3)), elements=st.floats(-0.6, 1.0)),
    hnp.arrays(np.float64, st.tuples(st.integers(0, 4), st.just(3)), elements=st.floats(-2.0, 2.5)),
    numeric_arrays(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4)),
    hnp.arrays(np.float64, st.tuples(st.integers(1, 3), st.just(3)), elements=NUMBERS).map(lambda a: a.tolist()),
    st.sampled_from([None, "abc", [[1, 2]], {"x": 1}]),
))
def test_gan_sample_for(panda: genplan.Robot, gan: Any, targets: Any) -> None:
    q, exc = call(gan.sample_for, targets)
    t = reals(targets)
    lim = gan.model.target_limits()
    ok = (t is not None and t.ndim == 2 and t.shape[1] == 3 and finite(t)
          and bool(np.all((t >= lim[0]) & (t <= lim[1]))))
    if not ok:
        assert exc is not None, f"sample_for accepted {targets!r}"
        return
    if exc is not None:
        assert isinstance(exc, NonFiniteError), f"sample_for refused targets inside its limits: {exc}"
        return
    assert t is not None and q.shape == (len(t), panda.nq) and finite(q)


# --------------------------------------------------------------------------------------------
# Pancake: s_curve, phi, adjust
# --------------------------------------------------------------------------------------------


def poses() -> Any:
    return st.one_of(st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-4, 4)),
                     numeric_arrays(hnp.array_shapes(min_dims=0, max_dims=2, max_side=4)),
                     st.tuples(NUMBERS, NUMBERS, NUMBERS))


@fuzz(60)
@given(a=poses(), b=poses(), k=st.integers(-3, 600), dt=st.one_of(st.just(1e-3), NUMBERS))
def test_s_curve(a: Any, b: Any, k: int, dt: float) -> None:
    from genplan.pancake import s_curve

    x, exc = call(s_curve, a, b, k, dt)
    va, vb = read_vec3(a), read_vec3(b)
    ok = (va is not None and vb is not None and np.shape(a) == (3,) == np.shape(b) and finite(va) and finite(vb)
          and k >= 2 and math.isfinite(dt) and dt > 0)
    if not ok:
        assert exc is not None, f"s_curve accepted {a!r}, {b!r}, K={k}, dt={dt}"
        return
    assert va is not None and vb is not None
    # far poses too (findings PY-6, fixed): no overflow, every sample between the two
    assert exc is None, exc
    assert x.shape == (k, 3) and finite(x)
    assert np.all((np.minimum(va, vb) <= x) & (x <= np.maximum(va, vb))), "a sample outside [p_start, p_end]"
    assert np.array_equal(x[0], va) and np.array_equal(x[-1], vb)  # exactly: finding PY-9 (fixed)


# finding PY-9 (fixed): s_curve documents 'sample K - 1 exactly p_end' but computed
# p_start + 1 * (p_end - p_start), which rounds when |p_end| << |p_start| (from y = 1 to y = 1e-20,
# or 2.2e-313, the last sample was 0)
@pytest.mark.parametrize("a, b", [([1.0, 0, 0], [2.2250738585e-313, 0, 0]), ([1.0, 0, 0], [1e-20, 0, 0])],
                         ids=["subnormal", "tiny"])
@pytest.mark.parametrize("f", ["s_curve", "linear"])
def test_s_curve_ends_exactly_at_p_end(a: list[float], b: list[float], f: str) -> None:
    assert np.array_equal(getattr(pancake, f)(a, b, 5)[-1], b)


# finding PY-6 (fixed): s_curve between finite but far poses (y from -1e308 to 1e308) overflowed:
# (p_end - p_start) was inf, sample 0 NaN (0 * inf) and the rest inf, returned without an error
@pytest.mark.parametrize("f", ["s_curve", "linear"])
@pytest.mark.parametrize("a, b", [([-1e308, 0, 0], [1e308, 0, 0]), ([1.7976931348623157e308] * 3, [-1.7976931348623157e308] * 3),
                                  ([1.7976931348623157e308] * 3, [1.7e308] * 3)], ids=["opposite", "max", "same-sign"])
def test_s_curve_between_far_poses_is_finite_or_refused(f: str, a: list[float], b: list[float]) -> None:
    x, exc = call(getattr(pancake, f), a, b, 7)
    assert exc is None and finite(x), (exc, x)
    assert np.array_equal(x[0], a) and np.array_equal(x[-1], b)
    assert np.all((np.minimum(a, b) <= x) & (x <= np.maximum(a, b)))


def phi_args() -> Any:
    shapes = hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4)
    acc_shapes = st.one_of(st.tuples(st.integers(0, 4), st.sampled_from([2, 3])), shapes)
    return st.tuples(st.one_of(hnp.arrays(np.float64, shapes, elements=SANE), st.floats(-4, 4)),
                     st.one_of(hnp.arrays(np.float64, acc_shapes, elements=st.floats(-50, 50)),
                               numeric_arrays(acc_shapes)))


@fuzz(60)
@given(args=phi_args())
def test_phi(args: Any) -> None:
    from genplan.pancake import phi

    theta, acc = args
    th, u = reals(theta), reals(acc)
    if th is None or u is None or u.ndim < 1 or u.shape[-1] not in (2, 3):
        _, exc = call(phi, theta, acc)
        assert isinstance(exc, ShapeError), exc
        return
    try:
        shape = np.broadcast_shapes(th.shape, u.shape[:-1])
    except ValueError:  # finding PY-7 (fixed): numpy's plain ValueError
        _, exc = call(phi, theta, acc)
        assert isinstance(exc, ShapeError) and "theta" in str(exc) and "acc" in str(exc), exc
        return
    if not (finite(th) and finite(u[..., :2])):  # finding PY-7 (fixed): NaN out without an error
        _, exc = call(phi, theta, acc)
        assert isinstance(exc, NonFiniteError) and str(exc).startswith("theta" if not finite(th) else "acc"), exc
        return
    out, exc = call(phi, theta, acc)
    assert exc is None, exc
    assert out.shape == shape and finite(out) and np.all((-np.pi < out) & (out <= np.pi))


# finding PY-7 (fixed): pancake.phi did not check its inputs: NaN or inf in theta, acc or g came out
# as NaN without an error; theta and acc that do not broadcast raised numpy's plain ValueError
# ('shape mismatch'). Now the typed error naming the argument.
@pytest.mark.parametrize("theta, acc, g, error, name", [
    ([np.nan], [[0.0, 0.0]], 9.8, NonFiniteError, "theta"), ([0.0], [[np.nan, 0.0]], 9.8, NonFiniteError, "acc"),
    ([0.0], [[0.0, -np.inf, 0.0]], 9.8, NonFiniteError, "acc"), (0.0, [0.0, 0.0], np.nan, NonFiniteError, "g"),
    (0.0, [0.0, 0.0], np.inf, NonFiniteError, "g"), (np.zeros(3), np.zeros((2, 2)), 9.8, ShapeError, "theta"),
    (0.0, np.zeros(2) + 1j, 9.8, ShapeError, "acc")],
    ids=["nan-theta", "nan-acc", "inf-acc", "nan-g", "inf-g", "no-broadcast", "complex-acc"])
def test_phi_refuses_what_it_cannot_compute(theta: Any, acc: Any, g: float, error: type, name: str) -> None:
    from genplan.pancake import phi

    _, exc = call(phi, theta, acc, g, errors=(BaseException,))
    assert isinstance(exc, error) and str(exc).startswith(name), repr(exc)
    # a NaN in a_theta, which eq. 16 does not use, is no reason to refuse
    assert phi(0.0, [0.0, 0.0, np.nan]) == 0.0


@fuzz(25)
@given(data=st.data())
def test_adjust(data: Any) -> None:
    from genplan.pancake import adjust, s_curve

    base = s_curve([0, 0, 0], [0.05, 0.02, -0.4])
    x = data.draw(st.one_of(
        st.just(base),
        st.integers(1, 2).map(lambda b: np.stack([base] * b)),
        hnp.arrays(np.float64, (500, 3), elements=st.floats(-0.2, 0.2)),
        hnp.arrays(np.float64, st.sampled_from([(500, 3), (1, 500, 3), (500, 2), (3,), (2, 3)]), elements=NUMBERS),
        st.just(np.zeros((0, 500, 3))),  # an empty batch: finding PY-8 (fixed)
        numeric_arrays((1, 500, 3), elements=st.floats(-0.2, 0.2)),
    ), label="x_in")
    updates = data.draw(st.integers(0, 2), label="updates")
    r, exc = call(adjust, x, updates=updates, errors=(GenplanError, FloatingPointError))
    a = reals(x)
    ok = a is not None and a.shape[-2:] == (500, 3) and a.ndim in (2, 3) and finite(a) and np.all(np.abs(a) <= 1e4)
    if not ok:
        assert isinstance(exc, GenplanError), f"adjust accepted x_in {x!r}"
        return
    assert a is not None
    if isinstance(exc, FloatingPointError):
        return  # documented: an update diverged
    assert exc is None, exc
    b = 1 if a.ndim == 2 else a.shape[0]
    assert r.p.shape == (b, 500, 3) and r.phi.shape == (b, 500) and finite(r.p) and finite(r.phi)
    assert r.objective_history.shape == (updates + 1, b) and finite(r.objective_history)


# finding PY-8 (fixed): adjust refused an empty batch (0, 500, 3) with a ShapeError (issue 15 item 8:
# empty batches work everywhere)
@pytest.mark.parametrize("method", ["latent", "random-latent", "direct-u"])
def test_adjust_takes_an_empty_batch(method: str) -> None:
    from genplan.pancake import adjust

    r, exc = call(adjust, np.zeros((0, 500, 3)), method=method, updates=1, snapshots=(0, 1))
    assert exc is None and r.p.shape == r.v.shape == r.u.shape == (0, 500, 3) and r.phi.shape == (0, 500)
    assert r.objective_history.shape == (2, 0) and r.batch == 0 and set(r.snapshots) == {0, 1}


# --------------------------------------------------------------------------------------------
# Control: execute
# --------------------------------------------------------------------------------------------


@fuzz(40)
@given(data=st.data())
def test_execute(data: Any) -> None:
    from genplan import control
    from genplan.pancake import s_curve

    k = data.draw(st.integers(2, 40), label="K")
    end = data.draw(st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.5, 0.5)), label="end")
    x = data.draw(st.one_of(
        st.just(s_curve([0, 0, 0], end, K=k)),
        hnp.arrays(np.float64, (k, 3), elements=st.floats(-0.05, 0.05)),
        hnp.arrays(np.float64, st.tuples(st.integers(0, 4), st.integers(0, 4)), elements=NUMBERS),
        numeric_arrays((k, 3)),
    ), label="trajectory")
    tail = data.draw(st.one_of(st.just(0.0), st.floats(0, 0.2), NUMBERS), label="tail")  # any: finding CTRL-1 (fixed)
    strict = data.draw(st.booleans(), label="strict")
    log, exc = call(control.execute, x, settle=0.0, tail=tail, strict=strict)
    a = reals(x)
    ok = (a is not None and a.ndim == 2 and a.shape[1] == 3 and a.shape[0] >= 2 and finite(a)
          and 0 <= tail <= control.MAX_TAIL_S)
    if not ok:
        assert exc is not None, f"execute accepted a trajectory {x!r} / tail {tail}"
        if not 0 <= tail <= control.MAX_TAIL_S and a is not None and a.ndim == 2 and a.shape[1] == 3 and a.shape[0] >= 2 \
                and finite(a):
            assert isinstance(exc, SettingsError) and "tail" in str(exc), repr(exc)
        return
    assert a is not None
    if exc is not None:
        return  # unreachable pose, or over the limits with strict=True: GenplanError, checked by call()
    n = len(log.t)
    assert n >= a.shape[0] and log.p.shape == (n, 3) and log.q.shape == (n, 6)
    for k_ in ("t", "p", "q", "v", "tau", "phi", "position", "error_position"):
        assert finite(getattr(log, k_)), f"log.{k_} is not finite"


# finding CTRL-1 (fixed): execute(tail=1e9) was not checked against a bound: the deceleration tail
# asked numpy for 1e12 samples and raised numpy's MemoryError ('Unable to allocate 7.28 TiB')
@pytest.mark.parametrize("kwargs, name", [({"tail": 1e9}, "tail"), ({"tail": 1e300}, "tail"), ({"tail": 10.5}, "tail"),
                                          ({"settle": 1e9}, "settle"), ({"settle": 1e300}, "settle")])
def test_a_huge_tail_is_refused(kwargs: dict[str, float], name: str) -> None:
    from genplan import control
    from genplan.pancake import s_curve

    _, exc = call(control.execute, s_curve([0, 0, 0], [0.01, 0, 0], K=10), **{"settle": 0.0, **kwargs},
                  errors=(BaseException,))
    assert isinstance(exc, SettingsError) and str(exc).startswith(name), repr(exc)
    _, exc = call(control.deceleration_tail, s_curve([0, 0, 0], [0.01, 0, 0], K=10), 1e9, errors=(BaseException,))
    assert isinstance(exc, SettingsError) and str(exc).startswith("duration"), repr(exc)


# --------------------------------------------------------------------------------------------
# Model files: corrupted bytes
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_gan_files(panda: genplan.Robot, tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, bytes]:
    """An untrained small GAN for the Panda, saved: (weights, card) bytes."""
    import torch

    from genplan.samplers.base import Codec
    from genplan.samplers.gan import EnsembleGenerator, GanModel, default_config

    torch.manual_seed(0)
    cfg = default_config("panda", n_net=2, gen_hidden=(8,), noise_dim=4)
    gen = EnsembleGenerator(cfg.n_net, cfg.noise_dim + 3, cfg.gen_hidden, panda.nq)
    model = GanModel(cfg, panda, gen, Codec(panda, np.zeros(panda.nq), np.ones(panda.nq)))
    w, c = model.save(tmp_path_factory.mktemp("gan") / "tiny.safetensors")
    return w.read_bytes(), c.read_bytes()


@pytest.fixture(scope="module")
def tiny_seq2seq_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, bytes]:
    import torch

    from genplan.pancake.model import default_config
    from genplan.seq2seq.model import Seq2SeqModel, Seq2SeqNet

    torch.manual_seed(0)
    cfg = default_config(hidden=8)
    w, c = Seq2SeqModel(cfg, Seq2SeqNet(cfg)).save(tmp_path_factory.mktemp("s2s") / "tiny.safetensors")
    return w.read_bytes(), c.read_bytes()


def corrupt(data: bytes, how: str, pos: int, byte: int) -> bytes:
    if not data:
        return data
    i = pos % len(data)
    if how == "flip":
        return data[:i] + bytes([data[i] ^ (byte or 1)]) + data[i + 1:]
    if how == "truncate":
        return data[:i]
    return data[:i] + bytes([byte]) * 8 + data[i:]  # insert


def rehash(card: bytes, weights: bytes) -> bytes:
    """The card with the weights' sha256 written anew (so the loader's later checks are reached)."""
    import hashlib
    import json

    try:
        c = json.loads(card)
        c["weights_sha256"] = hashlib.sha256(weights).hexdigest()
        return json.dumps(c).encode()
    except Exception:  # noqa: BLE001 -- a card that is no longer a JSON object stays as it is
        return card


CORRUPTION = st.tuples(st.sampled_from(["weights", "card", "both", "data"]), st.sampled_from(["flip", "truncate", "insert"]),
                       st.integers(0, 2**20), st.integers(0, 255), st.booleans())


def write_corrupted(files: tuple[bytes, bytes], corruption: Any, path: Path) -> Path:
    which, how, pos, byte, fix_hash = corruption
    w, c = files
    if which == "data":  # a byte of the tensors themselves (past the header), the hash rewritten
        start = 8 + int.from_bytes(w[:8], "little")
        w = w[:start] + corrupt(w[start:], "flip", pos, byte)
        fix_hash = True
    if which in ("weights", "both"):
        w = corrupt(w, how, pos, byte)
    if which in ("card", "both"):
        c = corrupt(c, how, pos * 7919, byte)
    if fix_hash:
        c = rehash(c, w)
    return write_files((w, c), path)


def write_files(files: tuple[bytes, bytes], path: Path) -> Path:
    """Weights and card bytes as ``path/m.safetensors`` and ``path/m.json``."""
    path.mkdir(parents=True, exist_ok=True)
    (path / "m.safetensors").write_bytes(files[0])
    (path / "m.json").write_bytes(files[1])
    return path / "m.safetensors"


@fuzz(60)
@given(corruption=CORRUPTION)
def test_corrupted_gan_files(panda: genplan.Robot, tiny_gan_files: Any, tmp_path: Path, corruption: Any) -> None:
    from genplan.samplers.gan import load_model

    path = write_corrupted(tiny_gan_files, corruption, tmp_path / "gan")
    model, exc = call(load_model, panda, path)
    event(f"gan file: {'refused' if exc else 'loaded'}")
    if exc is not None:
        assert isinstance(exc, ModelFileError), f"{type(exc).__name__}: {exc}"
        return
    q, exc = call(model.sample, np.array([[0.3, 0.0, 0.5]]), 0)
    assert exc is None or isinstance(exc, NonFiniteError), exc
    assert exc is not None or (q.shape == (1, panda.nq) and finite(q))


@fuzz(40)
@given(corruption=CORRUPTION)
def test_corrupted_seq2seq_files(tiny_seq2seq_files: Any, tmp_path: Path, corruption: Any) -> None:
    from genplan.pancake.model import load_model

    path = write_corrupted(tiny_seq2seq_files, corruption, tmp_path / "s2s")
    _, exc = call(load_model, path)
    event(f"seq2seq file: {'refused' if exc else 'loaded'}")
    assert exc is None or isinstance(exc, ModelFileError), f"{type(exc).__name__}: {exc}"


def test_the_uncorrupted_files_load(panda: genplan.Robot, tiny_gan_files: Any, tiny_seq2seq_files: Any,
                                    tmp_path: Path) -> None:
    from genplan.pancake.model import load_model as load_seq2seq
    from genplan.samplers.gan import load_model as load_gan

    assert corrupt(b"ab", "flip", 0, 0) == bytes([ord("a") ^ 1]) + b"b"
    assert corrupt(b"abc", "truncate", 1, 0) == b"a" and corrupt(b"ab", "insert", 1, 7) == b"a" + b"\x07" * 8 + b"b"
    gan = load_gan(panda, write_files(tiny_gan_files, tmp_path / "g"))
    assert finite(gan.sample(np.array([[0.3, 0.0, 0.5]]), 0))
    load_seq2seq(write_files(tiny_seq2seq_files, tmp_path / "s"))


#: any JSON value: what a card (or a field of one) may be replaced with
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12),
                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
                    max_leaves=8)
#: the keys a GAN or flow card holds, and some it does not
CARD_FIELDS = st.sampled_from(["format", "config", "weights_sha256", "robot", "robot_kinematic_hash", "robot_source",
                               "task", "command", "data", "training", "bogus"])
CONFIG_FIELDS = st.sampled_from(["robot", "target_frame", "target_box", "noise_dim", "n_net", "gen_hidden", "task",
                                 "loss", "bogus"])


@fuzz(60)
@given(card=st.one_of(JSON, st.binary(max_size=64)), fields=st.dictionaries(CARD_FIELDS, JSON, max_size=3),
       config=st.dictionaries(CONFIG_FIELDS, JSON, max_size=2), rehash=st.booleans(),
       as_flow=st.booleans())
def test_arbitrary_cards_are_refused_with_a_model_file_error(panda: genplan.Robot, tiny_gan_files: Any,
                                                             tmp_path: Path, card: Any, fields: Any, config: Any,
                                                             rehash: bool, as_flow: bool) -> None:
    """The card beside valid weights replaced by any JSON value or bytes, or with any fields
    (the robot's kinematic hash included) or config fields set to any JSON value: loading
    (either family: the format may say flow) is refused with a ModelFileError, or the model loads
    and samples finite configurations."""
    import json

    from genplan.samplers.loading import load_sampler_model

    weights, good = tiny_gan_files
    if fields or config:
        c = json.loads(good)
        c.update(fields)
        if isinstance(c.get("config"), dict):
            c["config"].update(config)
        if as_flow:
            c["format"] = "genplan-flow/1"
        text = json.dumps(c).encode()
    else:
        text = card if isinstance(card, bytes) else json.dumps(card).encode()
    path = write_files((weights, rehash_card(text, weights) if rehash else text), tmp_path / "cards")
    model, exc = call(load_sampler_model, panda, path)
    event(f"card: {'refused' if exc else 'loaded'}")
    if exc is not None:
        assert isinstance(exc, ModelFileError), f"{type(exc).__name__}: {exc}"
        return
    q, exc = call(model.sample, np.array([[0.3, 0.0, 0.5]]), 0)
    assert exc is None or isinstance(exc, NonFiniteError), exc
    assert exc is not None or (q.shape == (1, panda.nq) and finite(q))


def rehash_card(card: bytes, weights: bytes) -> bytes:
    """:func:`rehash` for a card that may not be a JSON object (left as it is)."""
    return rehash(card, weights)


@fuzz(30)
@given(data=st.binary(max_size=256), header=st.one_of(JSON, st.binary(max_size=32)), with_length=st.booleans())
def test_arbitrary_bytes_as_weights_are_refused_with_a_model_file_error(panda: genplan.Robot, tiny_gan_files: Any,
                                                                        tmp_path: Path, data: bytes, header: Any,
                                                                        with_length: bool) -> None:
    """Any bytes as the weights (a safetensors-like header of any JSON, or none), with a card that
    vouches for their sha256: a ModelFileError, never another exception."""
    import json

    head = header if isinstance(header, bytes) else json.dumps(header).encode()
    weights = (len(head).to_bytes(8, "little") + head + data) if with_length else data
    path = write_files((weights, rehash(tiny_gan_files[1], weights)), tmp_path / "weights")
    _, exc = call(genplan.samplers.load_model, panda, path)
    assert isinstance(exc, ModelFileError), f"{type(exc).__name__}: {exc}"


def test_a_card_given_as_the_model_is_refused_naming_the_weights(panda: genplan.Robot, tiny_gan_files: Any,
                                                                 tiny_seq2seq_files: Any, tmp_path: Path) -> None:
    from genplan.pancake.model import load_model as load_seq2seq
    from genplan.samplers.loading import load_sampler_model

    for files, load in ((tiny_gan_files, lambda p: load_sampler_model(panda, p)), (tiny_seq2seq_files, load_seq2seq)):
        path = write_files(files, tmp_path / "m")
        _, exc = call(load, path.with_suffix(".json"))
        assert isinstance(exc, ModelFileError) and "is a model card; give the .safetensors file beside it" in str(exc)


# --------------------------------------------------------------------------------------------
# Data sets (genplan data) and the data cache: corrupted manifests, lock files and cached arrays,
# and random `genplan data` runs into one folder. Each either ends in a GenplanError (exit code
# 2) or gives exactly the data set its arguments make: never a traceback, never a mixed set, never
# a cached row outside the joint limits.
# --------------------------------------------------------------------------------------------

DATA_JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                         lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
                         max_leaves=6)


def _fresh(tmp_path: Path) -> Path:
    """A new folder for one hypothesis example (``tmp_path`` is shared by a test's examples)."""
    import tempfile

    return Path(tempfile.mkdtemp(dir=tmp_path))


def _quiet(*_: Any) -> None:
    """A ``log`` that prints nothing."""


@pytest.fixture(scope="module")
def reference_sets(panda: genplan.Robot) -> Callable[[int, int, int], str]:
    """The sha256 of the Panda data set of (size, seed, shard size), computed once each."""
    from genplan.samplers.data import dataset_sha256, valid_configurations

    known: dict[tuple[int, int, int], str] = {}

    def sha(n: int, seed: int, shard_size: int) -> str:
        if (n, seed, shard_size) not in known:
            known[n, seed, shard_size] = dataset_sha256(
                [valid_configurations(panda, n, seed, use_cache=False, progress=False, shard_size=shard_size)])
        return known[n, seed, shard_size]
    return sha


@pytest.fixture(scope="module")
def data_set_files(panda: genplan.Robot, tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """A finished data set (60 Panda configurations, seed 1, 3 shards): its files' bytes."""
    from genplan.executor import LocalExecutor
    from genplan.samplers.data import write_dataset

    out = tmp_path_factory.mktemp("data") / "d"
    write_dataset(out, panda, 60, seed=1, shard_size=20, executor=LocalExecutor(1), progress=False, log=_quiet)
    return {f.name: f.read_bytes() for f in out.iterdir()}


def _mutate_manifest(text: bytes, how: str, key: str, value: Any, pos: int, byte: int) -> bytes:
    import json

    if how != "field":
        return corrupt(text, how, pos, byte)
    m = json.loads(text)
    if key.startswith("shards."):
        shard = m["shards"][pos % len(m["shards"])]
        shard[key.removeprefix("shards.")] = value
    else:
        m[key] = value
    return json.dumps(m).encode()


MANIFEST_CORRUPTION = st.tuples(
    st.sampled_from(["flip", "truncate", "insert", "field", "field"]),
    st.sampled_from(["format", "complete", "data_size", "seed", "shard_size", "nq", "sha256", "shards", "robot",
                     "manifold", "shards.index", "shards.file", "shards.sha256", "shards.count"]),
    DATA_JSON, st.integers(0, 2**16), st.integers(0, 255))


@fuzz(40)
@given(corruption=MANIFEST_CORRUPTION)
def test_corrupted_data_set_manifests(panda: genplan.Robot, data_set_files: dict[str, bytes],
                                      reference_sets: Any, tmp_path: Path, corruption: Any) -> None:
    """A data set whose manifest was changed: read_dataset gives the data set or a GenplanError;
    rerunning the same `genplan data` gives the data set (repaired) or a GenplanError."""
    from genplan.executor import LocalExecutor
    from genplan.samplers.data import dataset_sha256, read_dataset, write_dataset

    folder = _fresh(tmp_path) / "d"
    folder.mkdir()
    for name, raw in data_set_files.items():
        (folder / name).write_bytes(raw)
    (folder / "manifest.json").write_bytes(_mutate_manifest(data_set_files["manifest.json"], *corruption))
    ref = reference_sets(60, 1, 20)
    got, exc = call(read_dataset, folder, panda)
    event(f"manifest read: {'refused' if exc else 'read'}")
    assert exc is not None or dataset_sha256([got[0]]) == ref
    m, exc = call(write_dataset, folder, panda, 60, 1, shard_size=20, executor=LocalExecutor(1), progress=False,
                  log=_quiet)
    event(f"manifest rerun: {'refused' if exc else 'written'}")
    if exc is None:
        assert m["sha256"] == ref and dataset_sha256([read_dataset(folder, panda)[0]]) == ref
    assert not (folder / "genplan.lock").exists()


LOCK_FIELDS = st.fixed_dictionaries(
    {"run": st.one_of(st.text(max_size=8), DATA_JSON), "host": st.sampled_from(["<this host>", "elsewhere", ""]),
     "pid": st.one_of(st.integers(-3, 2**22), st.sampled_from([1, 2**31, 2**40, 2**70]), DATA_JSON),
     "started": st.one_of(st.text(max_size=8), DATA_JSON)},
    optional={"pid_start": st.one_of(st.text(max_size=6), st.none(), DATA_JSON), "extra": DATA_JSON})


@fuzz(40)
@given(lock=st.one_of(LOCK_FIELDS, DATA_JSON, st.binary(max_size=40)), force=st.booleans())
def test_corrupted_lock_files(panda: genplan.Robot, reference_sets: Any, tmp_path: Path, lock: Any,
                              force: bool) -> None:
    """A data set folder holding any lock file: the run is refused (GenplanError, nothing
    written) or takes the lock and writes the data set its arguments make."""
    import json
    import socket

    from genplan.executor import LocalExecutor
    from genplan.samplers.data import LOCK, write_dataset

    folder = _fresh(tmp_path) / "d"
    folder.mkdir()
    if isinstance(lock, dict) and lock.get("host") == "<this host>":
        lock = {**lock, "host": socket.gethostname()}
    raw = lock if isinstance(lock, bytes) else json.dumps(lock).encode()
    (folder / LOCK).write_bytes(raw)
    m, exc = call(write_dataset, folder, panda, 40, 2, shard_size=20, executor=LocalExecutor(1), progress=False,
                  log=_quiet, force=force)
    event(f"lock: {'refused' if exc else 'taken'}{' (forced)' if force else ''}")
    if exc is not None:
        assert (folder / LOCK).read_bytes() == raw and not (folder / "manifest.json").exists()
    else:
        assert m["sha256"] == reference_sets(40, 2, 20) and not (folder / LOCK).exists()


DATA_RUN = st.fixed_dictionaries({
    "seed": st.sampled_from([0, 1]), "size": st.sampled_from([20, 30]), "shard": st.sampled_from([10, 20]),
    "task": st.sampled_from([None, None, "panda_ik", "panda_projection"]), "overwrite": st.booleans(),
    "workers": st.sampled_from([1, 2])})


@fuzz(15)
@given(runs=st.lists(DATA_RUN, min_size=2, max_size=3))
def test_random_data_runs_into_one_folder(reference_sets: Any, tmp_path: Path, runs: list[dict[str, Any]]) -> None:
    """`genplan data` runs one after the other into one --out: each exits 0 with exactly its own
    data set, or 2 with one line and the folder's complete data set (if any) untouched."""
    import contextlib
    import io
    import json

    from genplan.cli import main

    folder = _fresh(tmp_path) / "d"
    for run in runs:
        argv = ["data", "--robot", "panda", "--data-size", str(run["size"]), "--seed", str(run["seed"]),
                "--shard-size", str(run["shard"]), "--workers", str(run["workers"]), "--out", str(folder)]
        argv += ["--task", run["task"]] if run["task"] else []
        argv += ["--overwrite"] if run["overwrite"] else []
        before = (folder / "manifest.json").read_bytes() if (folder / "manifest.json").exists() else None
        err, out = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            code, exc = call(main, argv, errors=())
        assert exc is None and code in (0, 2), (code, err.getvalue()[-500:])
        assert "Traceback" not in err.getvalue()
        event(f"data run: exit {code}")
        if code == 0:
            m = json.loads((folder / "manifest.json").read_text())
            assert m["complete"] and m["sha256"] == reference_sets(run["size"], run["seed"], run["shard"])
        else:
            assert err.getvalue().splitlines()[-1].startswith("genplan: error: ")
            now = (folder / "manifest.json").read_bytes() if (folder / "manifest.json").exists() else None
            assert now == before
        assert not (folder / "genplan.lock").exists()


@fuzz(30)
@given(pos=st.integers(0, 2**16), byte=st.integers(1, 255), rehashed=st.booleans())
def test_corrupted_data_cache(panda: genplan.Robot, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, pos: int,
                              byte: int, rehashed: bool) -> None:
    """A byte of a cached data set changed: valid_configurations regenerates it (its sha256 does
    not match), or, when the hash was rewritten to match, returns finite rows within the joint
    limits (checked on read): never a joint at -47 rad."""
    import hashlib

    from genplan.cache import hash_path
    from genplan.samplers.data import cache_path, valid_configurations

    monkeypatch.setenv("GENPLAN_CACHE", str(_fresh(tmp_path)))
    ref = valid_configurations(panda, 40, 3, progress=False, shard_size=20)
    path = cache_path(panda, 40, 3, shard_size=20)
    raw = corrupt(path.read_bytes(), "flip", pos, byte)
    path.write_bytes(raw)
    if rehashed:
        hash_path(path).write_text(hashlib.sha256(raw).hexdigest())
    got, exc = call(valid_configurations, panda, 40, 3, progress=False, shard_size=20)
    assert exc is None, exc
    same = bool(np.array_equal(got, ref))
    event(f"cache: {'regenerated or intact' if same else 'changed within the limits'}")
    assert same or rehashed
    assert np.all(np.isfinite(got)) and np.all((got >= panda.lower) & (got <= panda.upper))
