"""Rust rigid-body dynamics (genplan._core.Dynamics) against Pinocchio on random states, on every
fixed-base robot of ``genplan bench robots`` (the Panda, UR3/5/10, the xArm7 from its URDF, the
Kinova with its continuous joints).

Mass matrix (crba), bias forces (nonLinearEffects = rnea at zero acceleration), full rnea,
forward dynamics (aba), generalised gravity, frame placement, Jacobian and its time derivative
(LOCAL_WORLD_ALIGNED) of the tool frame (genplan.control.tool_frame) and of a frame off it, with
and without an added payload; relative error <= 1e-9.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core
from genplan.control import tool_frame
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.experiments.benchmarks.robots import ROBOTS

TOL = 1e-9
#: every robot of `genplan bench robots` with a fixed base (Talos has a free flyer)
CASES = [name for name in ROBOTS if name != "talos"]


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(1.0, np.linalg.norm(b)))


def full_crba(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    m = pin.crba(model, data, q)
    return np.triu(m) + np.triu(m, 1).T


def with_offset_frame(model: pin.Model, link: str, offset: pin.SE3) -> tuple[pin.Model, int]:
    """A copy of the model with a frame at ``link`` moved by ``offset``."""
    m = copy.deepcopy(model)
    fid = m.getFrameId(link)
    f = m.frames[fid]
    new = m.addFrame(pin.Frame(f"{link}_offset", f.parentJoint, fid, f.placement * offset, pin.FrameType.OP_FRAME))
    return m, new


OFFSET = pin.SE3(pin.rpy.rpyToMatrix(0.2, -0.3, 0.5), np.array([0.01, -0.02, 0.1]))


@pytest.fixture(scope="module", params=CASES)
def case(request):
    robot = ROBOTS[request.param]()
    assert not robot.floating_base
    dyn = _core.Dynamics.from_description(robot.description)
    return robot, dyn, tool_frame(robot)


def test_every_fixed_base_robot_of_the_robots_bench_is_covered():
    assert set(CASES) == {"panda", "ur3", "ur5", "ur10", "xarm7", "kinova"}
    assert ROBOTS["talos"]().floating_base


def test_same_joints_and_mass(case):
    robot, dyn, _ = case
    assert dyn.joint_names == robot.joint_names
    assert (dyn.nq, dyn.nv) == (robot.nq, robot.nv)
    moving = sum(robot.model.inertias[j].mass for j in range(1, robot.model.njoints))
    assert abs(dyn.moving_mass - moving) < 1e-12


def test_dynamics_match_pinocchio_on_random_states(case):
    robot, dyn, link = case
    model = robot.model
    data = model.createData()
    rng = np.random.default_rng(0)
    pmodel, pfid = with_offset_frame(model, link, OFFSET)
    pdata = pmodel.createData()
    offset = OFFSET.homogeneous.tolist()
    fid = model.getFrameId(link)
    worst: dict[str, float] = {}
    for _ in range(25):
        q = pin.randomConfiguration(model)
        v = rng.normal(size=model.nv) * 2.0
        a = rng.normal(size=model.nv) * 3.0
        tau = rng.normal(size=model.nv) * 10.0
        err = {
            "M": rel(dyn.mass_matrix(q), full_crba(model, data, q)),
            "nle": rel(dyn.nonlinear_effects(q, v), pin.nonLinearEffects(model, data, q, v)),
            "rnea": rel(dyn.rnea(q, v, a), pin.rnea(model, data, q, v, a)),
            "gravity": rel(dyn.gravity_torque(q), pin.computeGeneralizedGravity(model, data, q)),
            "aba": rel(dyn.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau)),
        }
        pin.computeJointJacobians(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        err["placement"] = rel(dyn.frame_placement(q, link), data.oMf[fid].homogeneous)
        err["J"] = rel(dyn.frame_jacobian(q, link), pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED))
        pin.computeJointJacobiansTimeVariation(model, data, q, v)
        pin.updateFramePlacements(model, data)
        err["dJ"] = rel(dyn.frame_jacobian_time_variation(q, v, link),
                        pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED))
        # a frame off the link, rotated: the spatula point is such a frame
        pin.computeJointJacobians(pmodel, pdata, q)
        pin.framesForwardKinematics(pmodel, pdata, q)
        err["placement_offset"] = rel(dyn.frame_placement(q, link, offset), pdata.oMf[pfid].homogeneous)
        err["J_offset"] = rel(dyn.frame_jacobian(q, link, offset),
                              pin.getFrameJacobian(pmodel, pdata, pfid, pin.LOCAL_WORLD_ALIGNED))
        pin.computeJointJacobiansTimeVariation(pmodel, pdata, q, v)
        pin.updateFramePlacements(pmodel, pdata)
        err["dJ_offset"] = rel(dyn.frame_jacobian_time_variation(q, v, link, offset),
                               pin.getFrameJacobianTimeVariation(pmodel, pdata, pfid, pin.LOCAL_WORLD_ALIGNED))
        for k, e in err.items():
            worst[k] = max(worst.get(k, 0.0), e)
    assert max(worst.values()) <= TOL, worst


def test_payload_matches_pinocchio(case):
    robot, _, link = case
    dyn = _core.Dynamics.from_description(robot.description)
    mass, com = 0.8, np.array([0.02, -0.01, 0.05])
    inertia = np.array([[0.004, 0.0005, 0.0], [0.0005, 0.003, 0.0002], [0.0, 0.0002, 0.002]])
    dyn.add_inertia(link, mass, com.tolist(), inertia.tolist(), OFFSET.homogeneous.tolist())
    model = copy.deepcopy(robot.model)
    f = model.frames[model.getFrameId(link)]
    model.inertias[f.parentJoint] = model.inertias[f.parentJoint] + (f.placement * OFFSET).act(pin.Inertia(mass, com, inertia))
    data = model.createData()
    rng = np.random.default_rng(1)
    for _ in range(10):
        q = pin.randomConfiguration(model)
        v = rng.normal(size=model.nv)
        assert rel(dyn.mass_matrix(q), full_crba(model, data, q)) <= TOL
        assert rel(dyn.nonlinear_effects(q, v), pin.nonLinearEffects(model, data, q, v)) <= TOL


#: every joint kind (prismatic, continuous, revolute), off-axis origins, rotated inertias (the
#: presets' inertial frames are all unrotated), a link lumped through a fixed joint
MIXED = str(Path(__file__).parent / "data" / "mixed.urdf")  # also read by rust/core/tests/dynamics.rs


def test_every_joint_kind_and_rotated_inertias_match_pinocchio():
    model = pin.buildModelFromUrdf(MIXED)
    data = model.createData()
    dyn = _core.Dynamics.from_urdf(MIXED)
    assert (dyn.nq, dyn.nv) == (model.nq, model.nv) == (4, 3)
    fid = model.getFrameId("tip")
    rng = np.random.default_rng(3)
    for _ in range(25):
        q = pin.randomConfiguration(model)
        v, a = rng.normal(size=3), rng.normal(size=3)
        assert rel(dyn.mass_matrix(q), full_crba(model, data, q)) <= TOL
        assert rel(dyn.rnea(q, v, a), pin.rnea(model, data, q, v, a)) <= TOL
        assert rel(dyn.forward_dynamics(q, v, a), pin.aba(model, data, q, v, a)) <= TOL
        pin.computeJointJacobiansTimeVariation(model, data, q, v)
        pin.updateFramePlacements(model, data)
        assert rel(dyn.frame_jacobian(q, "tip"), pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)) <= TOL
        assert rel(dyn.frame_jacobian_time_variation(q, v, "tip"),
                   pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED)) <= TOL


def test_gravity_is_settable_and_bad_input_raises():
    dyn = _core.Dynamics.from_description(genplan.load("ur5").description)
    q = np.zeros(6)
    assert dyn.gravity == [0.0, 0.0, -9.81]
    dyn.gravity = [0.0, 0.0, 0.0]
    assert np.allclose(dyn.gravity_torque(q), 0.0)
    with pytest.raises(ShapeError, match=r"q: expected shape \(6,\)"):
        dyn.mass_matrix(np.zeros(5))
    with pytest.raises(NonFiniteError, match="velocity v: element 2 is not finite"):
        dyn.nonlinear_effects(q, np.array([0, 0, np.nan, 0, 0, 0.0]))
    with pytest.raises(UnknownNameError, match="unknown link 'flange'"):
        dyn.frame_jacobian(q, "flange")
    with pytest.raises(SettingsError, match="not a rotation"):
        dyn.frame_jacobian(q, "tool0", (2 * np.eye(4)).tolist())
    with pytest.raises(GenplanError, match="added mass must be finite and >= 0"):
        dyn.add_inertia("tool0", -1.0, [0, 0, 0], np.eye(3).tolist())
    with pytest.raises(GenplanError, match="floating base"):
        _core.Dynamics.from_description(genplan.load("talos").description)


def test_phi_in_rust_matches_eq16():
    from genplan.pancake.trajectories import phi

    rng = np.random.default_rng(2)
    theta = rng.uniform(-4.0, 4.0, size=2000)
    acc = rng.normal(scale=15.0, size=(2000, 2))
    for g in (9.8, 9.81):
        # eq. 16 written out here (the oracle): the angle of g - u past the blade's inward normal
        oracle = np.angle(np.exp(1j * (np.arctan2(-g - acc[:, 1], -acc[:, 0]) + np.pi / 2 - theta)))
        native = _core.pancake_phi(theta, acc, g)
        assert np.all((native > -np.pi) & (native <= np.pi))
        assert np.allclose(np.exp(1j * native), np.exp(1j * oracle), rtol=0, atol=1e-12)
        # the library's numpy entry point (broadcasting over any shape) is the native definition
        assert np.array_equal(phi(theta.reshape(40, 50), acc.reshape(40, 50, 2), g=g), native.reshape(40, 50))
    # the conventions of pancake/trajectories.py: level at rest is 0, tilted by theta at rest is -theta
    assert _core.pancake_phi(np.array([0.0]), np.zeros((1, 2)))[0] == 0.0
    assert np.isclose(_core.pancake_phi(np.array([0.4]), np.zeros((1, 2)))[0], -0.4)
