"""Constraint projection and inverse kinematics: damped Gauss-Newton with a task hierarchy.

The GAN paper's Section III-B: residual terms with analytic Jacobians from Pinocchio, stacked
into a primary task; a secondary posture task runs in the null space of the primary (eq. 3);
damping lambda = mu r^T r + mu_bar (eq. 4); Armijo backtracking; clipping to the joint limits
after every step. A task succeeds when every primary term's residual is below its tolerance
(max absolute component of the unweighted residual, as in the authors' code).

Tasks are data: a list of terms. The paper's tasks are shipped task files (:func:`paper_task`);
a user task is any list of :class:`Term` objects::

    task = Task(primary=[FramePosition("hand", target=[0.5, 0, 0.6], weight=50),
                         JointLimits(weight=30)],
                secondary=[Posture()])
    result = GaussNewtonProjector(genplan.load("panda"), task).solve(q0)

One concept per module, every name exported here:

* :mod:`~genplan.projection.base` -- :class:`Term`, what every term shares;
* the built-in terms by family: :mod:`~genplan.projection.frame` (:class:`FramePose`,
  :class:`FramePosition`, :class:`FrameOrientation`, :class:`PointAt`, :class:`Plane`),
  :mod:`~genplan.projection.relative` (:class:`RelativePose`, :class:`RelativePosition`: one
  frame in another's), :mod:`~genplan.projection.joints`
  (:class:`Posture`, :class:`JointLimits`), :mod:`~genplan.projection.com` (:class:`ComBox`);
  and :mod:`~genplan.projection.custom` (:class:`CustomTerm`, a term of your own in Python);
* :mod:`~genplan.projection.task` -- :class:`Task`, :class:`Condition`, task files;
* :mod:`~genplan.projection.solver` -- :class:`GaussNewtonProjector`, :class:`SolverSettings`;
* :mod:`~genplan.projection.paper` -- the paper's tasks and constants (read when first used).
"""

from __future__ import annotations

from typing import Any

from genplan.projection import paper as _paper
# _State and _BoundTerm: what a Term subclass of your own uses in bind() (backend="pinocchio")
from genplan.projection.base import Array, Term, _BoundTerm, _State  # noqa: F401
from genplan.projection.com import ComBox
from genplan.projection.custom import CustomTerm
from genplan.projection.frame import FrameOrientation, FramePose, FramePosition, Plane, PointAt
from genplan.projection.joints import JointLimits, Posture
from genplan.projection.paper import TASK_KINDS, paper_task, panda_task, talos_task
from genplan.projection.relative import RelativePose, RelativePosition
from genplan.projection.solver import (
    AT_LIMIT, BACKENDS, BatchResult, GaussNewtonProjector, ProjectionResult, SolverSettings, check_task_use,
)
from genplan.projection.task import (
    TASKS_DIR, TERM_KINDS, Condition, Task, condition_term, default_task_name, load_task, manifold_task,
    python_term_entry, task_names, unset_condition_term,
)

__all__ = [
    "AT_LIMIT", "Array", "BACKENDS", "BatchResult", "ComBox", "Condition", "CustomTerm", "FrameOrientation", "FramePose",
    "FramePosition", "GaussNewtonProjector", "JointLimits", "PANDA_HAND_OFFSET", "PANDA_IK_BOX", "Plane", "PointAt",
    "Posture", "ProjectionResult", "RelativePose", "RelativePosition", "SolverSettings", "TALOS_COM_BOX", "TALOS_IK_BOX", "TASKS_DIR", "TASK_KINDS", "TERM_KINDS",
    "Task", "Term", "check_task_use", "condition_term", "default_task_name", "load_task", "manifold_task",
    "panda_task", "paper_task", "python_term_entry", "talos_task", "task_names", "unset_condition_term",
]



def __getattr__(name: str) -> Any:
    if name in _paper._CONSTANTS:  # the paper's constants, read from the shipped task files when first used
        return getattr(_paper, name)
    raise AttributeError(f"module 'genplan.projection' has no attribute '{name}'")
