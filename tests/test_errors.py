"""genplan.errors: the typed errors for a caller's bad input. Every class is a ValueError, and each
is raised by a real entry point, from the Python front end and from the native core where both
check, with a message that names the argument at fault."""

from __future__ import annotations

import ast
import inspect
import json
import pickle
import shutil

import numpy as np
import pytest

import genplan
from genplan import _core
from genplan import projection as P
import genplan.errors as E
from genplan.errors import (CallbackError, GenplanError, InvalidGoalError, InvalidStartError, ModelFileError,
                            NonFiniteError, RobotFileError, SettingsError, ShapeError, UnknownNameError)
from genplan.planning import Planner, PlannerSettings, environment, make_sampler
from genplan.samplers.base import models_dir
from genplan.samplers.gan import load_model


def test_every_error_is_a_value_error_and_a_genplan_error() -> None:
    classes = [getattr(E, name) for name in E.__all__ if not issubclass(getattr(E, name), Warning)]
    assert GenplanError in classes and CallbackError in classes
    for cls in classes:
        assert issubclass(cls, GenplanError) and issubclass(cls, ValueError), cls
    # distinct kinds: no class is a subclass of another, apart from the base
    for a in classes:
        for b in classes:
            if a is not b and b is not GenplanError:
                assert not issubclass(a, b), (a, b)
    # the native core raises these very classes (defined in genplan._core, re-exported here)
    with pytest.raises(SettingsError) as info:
        PlannerSettings(step=-1.0)
    assert type(info.value) is SettingsError


def test_native_error_classes_are_defined_once_and_shared() -> None:
    native = _core.ERRORS
    names = [cls.__name__ for cls in native]
    # one table: each class once, GenplanError first, the others its direct subclasses
    assert len(set(names)) == len(names) == len({id(cls) for cls in native})
    assert native[0] is GenplanError and GenplanError.__bases__ == (ValueError,)
    for cls in native[1:]:
        assert cls.__bases__ == (GenplanError,), cls
    for cls in native:
        # the same object under the native module and the public one, named after the public one
        assert getattr(_core, cls.__name__) is cls and getattr(E, cls.__name__) is cls
        assert (cls.__module__, cls.__qualname__) == ("genplan.errors", cls.__name__)
        assert cls.__doc__, cls
    # genplan/errors.py defines none of them again: its class statements are the errors only
    # Python raises, each a GenplanError (apart from the warning)
    tree = ast.parse(inspect.getsource(E))
    defined = {node.name for node in tree.body if isinstance(node, ast.ClassDef)}
    assert defined and not defined & set(names)
    assert set(E.__all__) == defined | set(names)
    for name in defined - {"RobotWarning"}:
        assert issubclass(getattr(E, name), GenplanError) and getattr(E, name).__module__ == "genplan.errors", name


def _pickled(exc: BaseException) -> BaseException:
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is type(exc) and back.args == exc.args and str(back) == str(exc)
    return back


@pytest.mark.parametrize("name", [n for n in E.__all__ if n != "RobotWarning"])
def test_every_error_pickles(name: str) -> None:
    cls = getattr(E, name)
    if cls is E.ShardsFailedError:
        exc = cls("2 of 4 shards failed", {1: "boom", 3: "bang"})
        assert _pickled(exc).failures == {1: "boom", 3: "bang"}  # type: ignore[attr-defined]
        return
    exc = cls(f"q: a {name}")
    exc.__notes__ = ["a note"]  # what add_note (Python 3.11) sets; an attribute pickle must keep
    assert _pickled(exc).__notes__ == ["a note"]  # type: ignore[attr-defined]


def test_a_native_error_pickles_as_raised(panda: genplan.Robot) -> None:
    with pytest.raises(ShapeError) as info:
        panda.kinematics.forward_kinematics(np.zeros((2, 3, 7)))
    back = _pickled(info.value)
    assert isinstance(back, E.ShapeError) and isinstance(back, ValueError)


def test_shape_error(panda: genplan.Robot) -> None:
    world = panda.collision_world()
    # Python front end
    with pytest.raises(ShapeError, match=r"^q: expected shape \(7,\) or \(n, 7\), got \(6,\)"):
        panda.link_poses(np.zeros(6))
    with pytest.raises(ShapeError, match=r"^q: expected shape \(7,\) or \(n, 7\), got \(2, 5\)"):
        world.in_collision(np.zeros((2, 5)))
    # native core (the same messages: the checks of these calls live there)
    with pytest.raises(ShapeError, match=r"^q: expected shape \(7,\) or \(n, 7\), got \(2, 3, 7\)"):
        panda.kinematics.forward_kinematics(np.zeros((2, 3, 7)))
    with pytest.raises(ShapeError, match=r"^q: expected shape \(7,\) or \(n, 7\), got \(2, 5\)"):
        world.native.in_collision(np.zeros((2, 5)))


def test_non_finite_error(panda: genplan.Robot) -> None:
    q = panda.q_default.copy()
    q[2] = np.nan
    with pytest.raises(NonFiniteError, match=r"^q: element \(2,\) is not finite \(nan\)"):
        panda.link_poses(q)
    # native core: the element of a batch as (row, column)
    qs = np.zeros((3, 7))
    qs[1, 4] = -np.inf
    with pytest.raises(NonFiniteError, match=r"^q: element \(1, 4\) is not finite \(-inf\)"):
        panda.collision_world().native.min_distance(qs)


def test_unknown_name_error(panda: genplan.Robot) -> None:
    with pytest.raises(UnknownNameError, match=r"unknown robot 'nope' \(known: kinova, panda, talos, ur10, ur3, ur5; or a robot file"):
        genplan.load("nope")
    with pytest.raises(UnknownNameError, match="unknown environment 'kitchen'"):
        environment("kitchen")
    with pytest.raises(UnknownNameError, match="robot 'panda' has no frame 'elbow'"):
        panda.frame_id("elbow")
    # native core: an unknown link of the Rust kinematics
    with pytest.raises(UnknownNameError, match="unknown link 'nope'"):
        panda.link_poses(panda.q_default, ["nope"])


def test_settings_error(panda: genplan.Robot) -> None:
    task = P.paper_task(panda, "projection")
    with pytest.raises(SettingsError, match="factor must be positive, got -1"):
        task.with_tolerances_scaled(-1)
    with pytest.raises(SettingsError, match="n and k must be >= 1"):
        environment("panda_shelf").queries(panda, n=0)
    # native core: the settings defined in Rust name the field
    with pytest.raises(SettingsError, match="step must be positive and finite, got -1"):
        PlannerSettings(step=-1)
    with pytest.raises(SettingsError, match="unknown setting 'stepp'"):
        PlannerSettings(stepp=0.2)


def test_generic_genplan_error(panda: genplan.Robot, talos: genplan.Robot) -> None:
    with pytest.raises(GenplanError, match="environment 'talos_task1' is for talos, not panda") as info:
        environment("talos_task1").world(panda)
    assert type(info.value) is GenplanError
    box = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    with pytest.raises(GenplanError, match=r"^box: expected \[\[xmin") as info:
        make_sampler(panda, "gan", gan_box=box)
    assert type(info.value) is GenplanError  # the shape and the numbers are fine, the order is not
    # native core: a base box whose lower corner is above its upper one
    with pytest.raises(GenplanError, match=r"bad base box \[1.0, 1.0, 1.0\] .. \[0.0, 0.0, 0.0\]"):
        make_sampler(talos, "uniform", base_box=box)


def _copy_robot(tmp_path, urdf_text) -> genplan.Robot:
    """The Panda's robot file in tmp_path, its URDF replaced by urdf_text, loaded."""
    panda = genplan.load("panda")
    (tmp_path / "panda.urdf").write_text(urdf_text)
    f = tmp_path / "panda.toml"
    f.write_text(f'urdf = "panda.urdf"\ncollision_urdf = "{panda.collision_urdf_path}"\nsrdf = "{panda.srdf_path}"\n'
                 'locked_joints = ["panda_finger_joint1", "panda_finger_joint2"]\nreference_state = "default"\n'
                 '[frames]\nhand = "panda_hand"\ntcp = "panda_hand_tcp"\n')
    return genplan.load(f)


def test_robot_file_error(panda: genplan.Robot, tmp_path) -> None:
    urdf = panda.urdf_path.read_text()
    # loading a robot: a URDF that cannot be parsed (the reader's reason), and one without a frame
    # the robot file names
    with pytest.raises(RobotFileError, match=r"cannot parse URDF .*panda\.urdf: expected 'link' tag, not 'robot'"):
        _copy_robot(tmp_path, "<robot name='panda'><link name='a'></robot>")
    with pytest.raises(UnknownNameError, match=r"unknown link 'panda_hand_tcp' \(frame 'tcp' of robot file .*panda.toml\)"):
        _copy_robot(tmp_path, urdf.replace('"panda_hand_tcp"', '"panda_tool"'))
    # native core: the Rust URDF parser
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(RobotFileError, match="cannot parse URDF .*bad.urdf"):
        type(panda.kinematics).from_urdf(bad)


def test_model_file_error(panda: genplan.Robot, talos: genplan.Robot, tmp_path) -> None:
    weights, card = tmp_path / "panda_gan.safetensors", tmp_path / "panda_gan.json"
    shutil.copy(models_dir() / "panda_gan.safetensors", weights)
    shutil.copy(models_dir() / "panda_gan.json", card)
    assert load_model(panda, weights).config.robot == "panda"
    # a tampered weight file (one byte changed): its sha256 is not the card's
    data = bytearray(weights.read_bytes())
    data[-1] ^= 0xFF
    weights.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match=r"panda_gan\.safetensors does not match its card"):
        load_model(panda, weights)
    # a card whose config lacks a required field (the weights are the card's again)
    shutil.copy(models_dir() / "panda_gan.safetensors", weights)
    c = json.loads(card.read_text())
    del c["config"]["target_frame"]
    card.write_text(json.dumps(c))
    with pytest.raises(ModelFileError, match=r"GAN model card .*panda_gan\.json has a bad config: .*target_frame"):
        load_model(panda, weights)
    # the model of another robot
    shutil.copy(models_dir() / "panda_gan.json", card)
    with pytest.raises(ModelFileError, match=r"panda_gan\.safetensors is a GAN for robot 'panda', not 'talos'"):
        load_model(talos, weights)


@pytest.fixture(scope="module")
def shelf(panda: genplan.Robot):
    env = environment("panda_shelf")
    world = env.world(panda)
    planner = Planner(panda, world=world)
    # the planner refuses a start or goal off its manifold before it checks validity: both are on it
    free = env.queries(panda, n=1, seed=0)[0].start
    folded = free.copy()
    folded[1], folded[3] = 1.7, -0.1  # the arm folded into the table
    folded = planner.projector.solve(folded).q
    assert not world.in_collision(free) and world.in_collision(folded)
    return planner, free, folded


def test_invalid_start_and_goal_errors(shelf) -> None:
    planner, free, folded = shelf
    with pytest.raises(InvalidStartError, match="^start: the configuration is not valid"):
        planner.plan(folded, free[None])
    with pytest.raises(InvalidGoalError, match="^goals: none of the goal configurations is valid"):
        planner.plan(free, folded[None])


def test_callback_error(shelf) -> None:
    planner, free, _ = shelf

    class WrongShape:
        def sample(self, n: int) -> np.ndarray:
            return np.zeros((n, 3))

    # native core: a Python sampler called back from the Rust planner (a goal farther than one
    # step: a nearer one is joined by the direct edge without sampling)
    goal = environment("panda_shelf").queries(planner.robot, n=1, seed=0)[0].goals[0]
    assert np.linalg.norm(goal - free) > planner.settings.step
    with pytest.raises(CallbackError, match=r"sampler.sample\(n\): expected shape \(16, 7\)"):
        planner.plan(free, goal[None], sampler=WrongShape())
    # Python front end: an objective of the latent adjustment that returns one value, not one per problem
    from genplan.pancake.adjustment import adjust
    from genplan.pancake.trajectories import s_curve

    x = np.stack([s_curve(np.zeros(3), [0.1, 0.0, 0.0])] * 2)
    with pytest.raises(CallbackError, match=r"the objective must return one value per problem, shape \(2,\)"):
        adjust(x, lambda r: r.p.sum(), updates=1)
