"""A Python constraint term importable by its entry (``tests.custom_terms_example:OnCircle``), for
the tests of python terms in task files, cards and data-generation workers
(tests/test_custom_terms.py) and benches/custom_term_data.py.

``OnCircle``: a frame's origin on a horizontal circle (a centre and a radius about the world's
vertical through the centre): a curve, which no built-in term expresses (a Plane holds the
height, nothing holds the radius). Its defaults hold the Panda's wrist (``panda_link6``) on a
circle of 0.3 m about the base's axis, 0.6 m up: within the wrist's reach, crossed by it in a
curve of configurations (the elbow, whose reach is a sphere, would only graze such a circle)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from genplan.projection import CustomTerm


@dataclass(frozen=True)
class OnCircle(CustomTerm):
    """r = (z - c_z, |(x, y) - (c_x, c_y)| - radius) of the frame's origin p = (x, y, z);
    dr/dv = [e_z; u] R J_local[:3], u the unit radial direction in the horizontal plane."""

    robot: Any = None
    frame: str = "panda_link6"
    center: tuple[float, float, float] = (0.0, 0.0, 0.6)
    radius: float = 0.3
    dim = 2

    def residual_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model = self.robot.model
        data = model.createData()
        fid = self.robot.frame_id(self.frame)
        c = np.asarray(self.center, dtype=float)
        rs, js = [], []
        for row in q:
            pin.computeJointJacobians(model, data, row)
            pin.updateFramePlacements(model, data)
            m = data.oMf[fid]
            jp = m.rotation @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)[:3]
            d = m.translation[:2] - c[:2]
            rho = float(np.hypot(*d))
            u = d / rho if rho > 1e-12 else np.zeros(2)
            rs.append([m.translation[2] - c[2], rho - self.radius])
            js.append(np.vstack([jp[2], u @ jp[:2]]))
        return np.array(rs), np.array(js)

    def residual(self, q: np.ndarray) -> np.ndarray:
        return self.residual_and_jacobian(q)[0]

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        return self.residual_and_jacobian(q)[1]
