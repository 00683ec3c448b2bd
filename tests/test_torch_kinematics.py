"""Differentiable torch kinematics against Pinocchio (float64, 1e-9)."""

import numpy as np
import pinocchio as pin
import pytest
import torch

import genplan
from genplan.errors import ShapeError
from genplan.torch_kinematics import TorchKinematics
from tests.conftest import random_configurations


@pytest.mark.parametrize("name", ["panda", "talos", "ur5", "kinova"])  # kinova: continuous joints ([cos, sin])
def test_frames_and_com_match_pinocchio(name: str) -> None:
    robot = genplan.load(name)
    kin = TorchKinematics(robot, dtype=torch.float64)
    qs = random_configurations(robot, 200, seed=3)
    qt = torch.tensor(qs, dtype=torch.float64)
    joints = kin.joint_placements(qt)
    com = kin.center_of_mass(qt, joints).numpy()
    frames = list(robot.frames)
    placements = {f: kin.frame_placement(qt, f, joints) for f in frames}
    for i, q in enumerate(qs):
        pin.framesForwardKinematics(robot.model, robot.data, q)
        for f in frames:
            ref = robot.data.oMf[robot.frame_id(f)]
            rot, pos = placements[f]
            assert np.abs(pos[i].numpy() - ref.translation).max() <= 1e-9
            assert np.abs(rot[i].numpy() - ref.rotation).max() <= 1e-9
        np.testing.assert_allclose(com[i], pin.centerOfMass(robot.model, robot.data, q), atol=1e-9)
    for f in frames:  # without the joints' pass, a frame's placement runs its own chain: the same numbers
        rot, pos = kin.frame_placement(qt, f)
        assert torch.allclose(rot, placements[f][0], rtol=0, atol=1e-12)
        assert torch.allclose(pos, placements[f][1], rtol=0, atol=1e-12)


def test_float32_chain_and_its_gradient_match_the_full_pass(panda: genplan.Robot) -> None:
    kin = TorchKinematics(panda, dtype=torch.float32)
    q = torch.tensor(random_configurations(panda, 50, seed=4), dtype=torch.float32, requires_grad=True)
    rot, pos = kin.frame_placement(q, "hand")
    (grad_chain,) = torch.autograd.grad((pos.sum() + rot.sum()), q)
    rot_full, pos_full = kin.frame_placement(q, "hand", kin.joint_placements(q))
    (grad_full,) = torch.autograd.grad((pos_full.sum() + rot_full.sum()), q)
    ref = np.array([panda.frame_placement(x, "hand").translation for x in q.detach().double().numpy()])
    np.testing.assert_allclose(pos.detach().numpy(), ref, atol=1e-5)
    assert torch.allclose(grad_chain, grad_full, atol=1e-5)


def test_gradients_flow_and_match_pinocchio_jacobian(panda: genplan.Robot) -> None:
    kin = TorchKinematics(panda)
    q = torch.tensor(panda.random_configurations(1, 0), requires_grad=True)
    _, pos = kin.frame_placement(q, "hand")
    jac = torch.stack([torch.autograd.grad(pos[0, k], q, retain_graph=True)[0][0] for k in range(3)])
    fid = panda.frame_id("hand")
    ref = pin.computeFrameJacobian(panda.model, panda.data, q.detach().numpy()[0], fid, pin.LOCAL_WORLD_ALIGNED)[:3]
    np.testing.assert_allclose(jac.numpy(), ref, atol=1e-9)


def test_bad_shape(panda: genplan.Robot) -> None:
    with pytest.raises(ShapeError, match="expected last dimension 7"):
        TorchKinematics(panda).joint_placements(torch.zeros(2, 6, dtype=torch.float64))
