"""Differentiable, batched forward kinematics in torch, derived from a robot's Pinocchio model.

Frame placements and the centre of mass as torch functions of q (Pinocchio's convention for q,
including a free-flyer base), so GAN losses can be back-propagated through them. In float64 it
agrees with Pinocchio to 1e-9 (tests/test_torch_kinematics.py).

>>> kin = TorchKinematics(genplan.load("panda"))
>>> rot, pos = kin.frame_placement(q, "hand")     # (B, 3, 3), (B, 3)
>>> com = kin.center_of_mass(q)                    # (B, 3)
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import torch

from genplan.errors import RobotFileError, ShapeError
from genplan.robots import Robot

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _joint_kind(joint: pin.JointModel) -> tuple[str, tuple[float, float, float] | None]:
    """("free" | "revolute" | "continuous" | "prismatic", axis) of a Pinocchio joint model."""
    name = joint.shortname()
    if name == "JointModelFreeFlyer":
        return "free", None
    # unbounded (continuous) revolute joints take [cos, sin] in q; checked before "JointModelR"
    if name.startswith("JointModelRUB") and name[len("JointModelRUB"):] in _AXES:
        return "continuous", _AXES[name[len("JointModelRUB"):]]
    if name == "JointModelRevoluteUnboundedUnaligned":
        return "continuous", tuple(float(a) for a in np.asarray(joint.extract().axis, dtype=float))
    for prefix, kind in (("JointModelR", "revolute"), ("JointModelP", "prismatic")):
        if name.startswith(prefix):
            suffix = name[len(prefix):]
            if suffix in _AXES:
                return kind, _AXES[suffix]
            if suffix.endswith("Unaligned") or suffix in ("evoluteUnaligned", "rismaticUnaligned"):
                axis = np.asarray(joint.extract().axis, dtype=float)
                return kind, tuple(float(a) for a in axis)
    raise RobotFileError(f"joint type {name} is not supported by TorchKinematics")


def quaternion_to_matrix(quat: torch.Tensor) -> torch.Tensor:
    """(B, 4) quaternions [x, y, z, w] (normalised here) to (B, 3, 3) rotation matrices."""
    q = quat / quat.norm(dim=-1, keepdim=True)
    x, y, z, w = q.unbind(-1)
    return torch.stack(
        [torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
         torch.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
         torch.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


class TorchKinematics(torch.nn.Module):
    """Batched forward kinematics of a :class:`~genplan.robots.Robot` in torch.

    A joint's placement in its parent's is the affine matrix ``[R | p]`` (3 x 4), affine in two
    numbers ``(a, b)`` of q: ``C0 + a C1 + b C2`` with constant 4 x 4 matrices (Rodrigues' formula
    with the joint's fixed placement folded in): a revolute joint's sine and cosine of its angle, a
    continuous joint's [sin, cos] entries of q, a prismatic joint's displacement and 0. So every
    joint's local placement is a few element-wise operations over the batch and the chain one
    matrix product per joint, forward and backward; a frame's placement runs only the chain of
    its joint's ancestors.
    """

    def __init__(self, robot: Robot, dtype: torch.dtype = torch.float64) -> None:
        super().__init__()
        self.robot = robot
        model = robot.model
        self.nq = model.nq
        self._parents: list[int] = []
        self._kinds: list[str] = []
        self._idx_q: list[int] = []
        for jid in range(1, model.njoints):
            kind, _ = _joint_kind(model.joints[jid])
            self._parents.append(int(model.parents[jid]))
            self._kinds.append(kind)
            self._idx_q.append(int(model.joints[jid].idx_q))
        revolute = [iq for kind, iq in zip(self._kinds, self._idx_q) if kind == "revolute"]
        # (a, b) of each joint as columns of the features [q, sin(revolute q), cos(revolute q), 0]
        nr, zero = len(revolute), self.nq + 2 * len(revolute)
        self._a: list[int] = []
        self._b: list[int] = []
        c0s, c1s, c2s, rots, trans, masses, levers = [], [], [], [], [], [], []
        for j, jid in enumerate(range(1, model.njoints)):
            kind, axis = _joint_kind(model.joints[jid])
            iq = self._idx_q[j]
            placement = model.jointPlacements[jid]
            r0, p0 = np.array(placement.rotation), np.array(placement.translation)
            rots.append(r0)
            trans.append(p0)
            c0, c1, c2 = np.zeros((4, 4)), np.zeros((4, 4)), np.zeros((4, 4))
            c0[:3, :3], c0[:3, 3], c0[3, 3] = r0, p0, 1.0
            a, b = zero, zero
            if kind in ("revolute", "continuous"):
                assert axis is not None
                # r0 (I + s K + (1 - c) K^2) = r0 (I + K^2) + s r0 K - c r0 K^2
                k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
                c0[:3, :3] = r0 @ (np.eye(3) + k @ k)
                c1[:3, :3] = r0 @ k
                c2[:3, :3] = -r0 @ k @ k
                if kind == "revolute":
                    a, b = self.nq + revolute.index(iq), self.nq + nr + revolute.index(iq)
                else:  # [cos, sin] in q, used as given (Pinocchio's convention: q is normalised)
                    a, b = iq + 1, iq
            elif kind == "prismatic":  # rotation r0, translation p0 + d r0 axis
                c1[:3, 3] = r0 @ np.asarray(axis)
                a = iq
            self._a.append(a)
            self._b.append(b)
            c0s.append(c0)
            c1s.append(c1)
            c2s.append(c2)
            masses.append(float(model.inertias[jid].mass))
            levers.append(np.array(model.inertias[jid].lever))
        self.register_buffer("_revolute_q", torch.tensor(revolute, dtype=torch.long))
        self.register_buffer("_c0", torch.tensor(np.array(c0s).reshape(-1, 4, 4), dtype=dtype))
        self.register_buffer("_c1", torch.tensor(np.array(c1s).reshape(-1, 4, 4), dtype=dtype))
        self.register_buffer("_c2", torch.tensor(np.array(c2s).reshape(-1, 4, 4), dtype=dtype))
        self.register_buffer("_rot0", torch.tensor(np.array(rots).reshape(-1, 3, 3), dtype=dtype))
        self.register_buffer("_trans0", torch.tensor(np.array(trans).reshape(-1, 3), dtype=dtype))
        self.register_buffer("_masses", torch.tensor(masses, dtype=dtype))
        self.register_buffer("_levers", torch.tensor(np.array(levers).reshape(-1, 3), dtype=dtype))
        self.total_mass = float(sum(masses))
        self._frames: dict[str, tuple[int, torch.Tensor]] = {}
        #: per joint list, dtype and device of :meth:`_chain`: the joints' a and b feature columns
        #: and their C0, C1, C2
        self._selections: dict[tuple[tuple[int, ...], torch.dtype, torch.device], tuple[torch.Tensor, ...]] = {}

    def _ancestors(self, joints: list[int]) -> list[int]:
        """The 0-based joints ``joints`` and all their ancestors, in the model's (parent-first) order."""
        need: set[int] = set()
        for j in joints:
            while j >= 0 and j not in need:
                need.add(j)
                j = self._parents[j] - 1
        return sorted(need)

    def _chain(self, q: torch.Tensor, joints: list[int]) -> dict[int, torch.Tensor]:
        """World placements (B, 3, 4) of the 0-based ``joints`` (ancestors first, as
        :meth:`_ancestors` lists them), by joint."""
        if q.shape[-1] != self.nq:
            raise ShapeError(f"q: expected last dimension {self.nq}, got {tuple(q.shape)}")
        batch = q.shape[0]
        key = (tuple(joints), q.dtype, q.device)
        if key not in self._selections:
            sel = torch.tensor(joints, dtype=torch.long)
            self._selections[key] = (
                torch.tensor([self._a[j] for j in joints], dtype=torch.long, device=q.device),
                torch.tensor([self._b[j] for j in joints], dtype=torch.long, device=q.device),
                *(c[sel].to(q) for c in (self._c0, self._c1, self._c2)))
        a_col, b_col, c0, c1, c2 = self._selections[key]
        rev = q.index_select(1, self._revolute_q.to(q.device))
        feats = torch.cat([q, torch.sin(rev), torch.cos(rev), q.new_zeros(batch, 1)], 1)
        a, b = feats.index_select(1, a_col)[:, :, None, None], feats.index_select(1, b_col)[:, :, None, None]
        # (B, n, 4, 4), split by joint in one operation (its backward stacks the gradients once)
        local = (c0 + a * c1 + b * c2).unbind(1)
        out: dict[int, torch.Tensor] = {}
        for i, j in enumerate(joints):
            m = local[i]
            if self._kinds[j] == "free":
                iq = self._idx_q[j]
                r0, p0 = self._rot0[j].to(q), self._trans0[j].to(q)
                top = torch.cat([r0 @ quaternion_to_matrix(q[:, iq + 3:iq + 7]),
                                 (p0 + q[:, iq:iq + 3] @ r0.T).unsqueeze(-1)], -1)
                m = torch.cat([top, c0[i, 3:].expand(batch, 1, 4)], 1)
            parent = self._parents[j] - 1
            out[j] = m[:, :3] if parent < 0 else out[parent] @ m
        return out

    def joint_placements(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World placements of every joint (Pinocchio's oMi for i >= 1): (B, J, 3, 3), (B, J, 3)."""
        chain = self._chain(q, list(range(len(self._parents))))
        t = torch.stack([chain[j] for j in range(len(self._parents))], 1)
        return t[..., :3], t[..., 3]

    def _frame(self, frame: str) -> tuple[int, torch.Tensor]:
        """The frame's parent joint (1-based, 0: the universe) and its placement there (4 x 4)."""
        if frame not in self._frames:
            f = self.robot.model.frames[self.robot.frame_id(frame)]
            self._frames[frame] = (int(f.parentJoint), torch.tensor(np.array(f.placement.homogeneous),
                                                                    dtype=self._c0.dtype))
        return self._frames[frame]

    def frame_placement(self, q: torch.Tensor, frame: str,
                        joints: tuple[torch.Tensor, torch.Tensor] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """World rotation (B, 3, 3) and position (B, 3) of a frame (role or frame name).
        Pass ``joints`` (from :meth:`joint_placements`) to reuse one forward pass; without it,
        only the joints between the root and the frame are computed."""
        parent, placement = self._frame(frame)
        f = placement.to(q)
        if parent == 0:
            if q.shape[-1] != self.nq:
                raise ShapeError(f"q: expected last dimension {self.nq}, got {tuple(q.shape)}")
            b = q.shape[0]
            return f[:3, :3].expand(b, 3, 3), f[:3, 3].expand(b, 3)
        if joints is None:
            t = self._chain(q, self._ancestors([parent - 1]))[parent - 1] @ f
            return t[..., :3], t[..., 3]
        rp, pp = joints[0][:, parent - 1], joints[1][:, parent - 1]
        return rp @ f[:3, :3], pp + (rp @ f[:3, 3].unsqueeze(-1)).squeeze(-1)

    def center_of_mass(self, q: torch.Tensor, joints: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """Centre of mass (B, 3), as Pinocchio's ``centerOfMass``."""
        rots, poss = self.joint_placements(q) if joints is None else joints
        world = poss + (rots @ self._levers.to(q).unsqueeze(-1)).squeeze(-1)  # (B, J, 3)
        m = self._masses.to(q)
        return (world * m[None, :, None]).sum(1) / m.sum()
