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


def _skew(v: torch.Tensor) -> torch.Tensor:
    z = torch.zeros_like(v[..., 0])
    return torch.stack(
        [torch.stack([z, -v[..., 2], v[..., 1]], -1),
         torch.stack([v[..., 2], z, -v[..., 0]], -1),
         torch.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def quaternion_to_matrix(quat: torch.Tensor) -> torch.Tensor:
    """(B, 4) quaternions [x, y, z, w] (normalised here) to (B, 3, 3) rotation matrices."""
    q = quat / quat.norm(dim=-1, keepdim=True)
    x, y, z, w = q.unbind(-1)
    return torch.stack(
        [torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
         torch.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
         torch.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


class TorchKinematics(torch.nn.Module):
    """Batched forward kinematics of a :class:`~genplan.robots.Robot` in torch."""

    def __init__(self, robot: Robot, dtype: torch.dtype = torch.float64) -> None:
        super().__init__()
        self.robot = robot
        model = robot.model
        self.nq = model.nq
        self._parents: list[int] = []
        self._kinds: list[str] = []
        self._idx_q: list[int] = []
        rots, trans, axes, masses, levers = [], [], [], [], []
        for jid in range(1, model.njoints):
            kind, axis = _joint_kind(model.joints[jid])
            self._parents.append(int(model.parents[jid]))
            self._kinds.append(kind)
            self._idx_q.append(int(model.joints[jid].idx_q))
            placement = model.jointPlacements[jid]
            rots.append(np.array(placement.rotation))
            trans.append(np.array(placement.translation))
            axes.append(axis or (0.0, 0.0, 0.0))
            masses.append(float(model.inertias[jid].mass))
            levers.append(np.array(model.inertias[jid].lever))
        self.register_buffer("_rot0", torch.tensor(np.array(rots), dtype=dtype))
        self.register_buffer("_trans0", torch.tensor(np.array(trans), dtype=dtype))
        self.register_buffer("_axes", torch.tensor(np.array(axes), dtype=dtype))
        self.register_buffer("_masses", torch.tensor(masses, dtype=dtype))
        self.register_buffer("_levers", torch.tensor(np.array(levers), dtype=dtype))
        self.total_mass = float(sum(masses))
        self._frames: dict[str, tuple[int, torch.Tensor, torch.Tensor]] = {}

    def joint_placements(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World placements of every joint (Pinocchio's oMi for i >= 1): (B, J, 3, 3), (B, J, 3)."""
        if q.shape[-1] != self.nq:
            raise ShapeError(f"q: expected last dimension {self.nq}, got {tuple(q.shape)}")
        batch = q.shape[0]
        eye = torch.eye(3, dtype=q.dtype, device=q.device)
        rots: list[torch.Tensor] = []
        poss: list[torch.Tensor] = []
        for j, (parent, kind, iq) in enumerate(zip(self._parents, self._kinds, self._idx_q)):
            r0 = self._rot0[j].to(q.dtype)
            p0 = self._trans0[j].to(q.dtype)
            if parent == 0:
                r_par = r0.expand(batch, 3, 3)
                p_par = p0.expand(batch, 3)
            else:
                rp, pp = rots[parent - 1], poss[parent - 1]
                r_par = rp @ r0
                p_par = pp + (rp @ p0.unsqueeze(-1)).squeeze(-1)
            if kind == "free":
                rm = quaternion_to_matrix(q[:, iq + 3:iq + 7])
                rots.append(r_par @ rm)
                poss.append(p_par + (r_par @ q[:, iq:iq + 3].unsqueeze(-1)).squeeze(-1))
            elif kind in ("revolute", "continuous"):
                if kind == "revolute":
                    theta = q[:, iq].reshape(batch, 1, 1)
                    sin, cos = torch.sin(theta), torch.cos(theta)
                else:  # [cos, sin] in q, used as given (Pinocchio's convention: q is normalised)
                    cos, sin = q[:, iq].reshape(batch, 1, 1), q[:, iq + 1].reshape(batch, 1, 1)
                k = _skew(self._axes[j].to(q.dtype)).expand(batch, 3, 3)
                rm = eye + sin * k + (1 - cos) * (k @ k)
                rots.append(r_par @ rm)
                poss.append(p_par)
            else:  # prismatic
                d = q[:, iq:iq + 1] * self._axes[j].to(q.dtype)
                rots.append(r_par)
                poss.append(p_par + (r_par @ d.unsqueeze(-1)).squeeze(-1))
        return torch.stack(rots, 1), torch.stack(poss, 1)

    def _frame(self, frame: str) -> tuple[int, torch.Tensor, torch.Tensor]:
        if frame not in self._frames:
            fid = self.robot.frame_id(frame)
            f = self.robot.model.frames[fid]
            self._frames[frame] = (
                int(f.parentJoint),
                torch.tensor(np.array(f.placement.rotation), dtype=self._rot0.dtype),
                torch.tensor(np.array(f.placement.translation), dtype=self._rot0.dtype),
            )
        return self._frames[frame]

    def frame_placement(self, q: torch.Tensor, frame: str,
                        joints: tuple[torch.Tensor, torch.Tensor] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """World rotation (B, 3, 3) and position (B, 3) of a frame (role or frame name).
        Pass ``joints`` (from :meth:`joint_placements`) to reuse one forward pass."""
        rots, poss = self.joint_placements(q) if joints is None else joints
        parent, r_f, p_f = self._frame(frame)
        if parent == 0:
            b = q.shape[0]
            return r_f.to(q.dtype).expand(b, 3, 3), p_f.to(q.dtype).expand(b, 3)
        rp, pp = rots[:, parent - 1], poss[:, parent - 1]
        return rp @ r_f.to(q.dtype), pp + (rp @ p_f.to(q.dtype).unsqueeze(-1)).squeeze(-1)

    def center_of_mass(self, q: torch.Tensor, joints: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """Centre of mass (B, 3), as Pinocchio's ``centerOfMass``."""
        rots, poss = self.joint_placements(q) if joints is None else joints
        world = poss + (rots @ self._levers.to(q.dtype).unsqueeze(-1)).squeeze(-1)  # (B, J, 3)
        m = self._masses.to(q.dtype)
        return (world * m[None, :, None]).sum(1) / m.sum()
