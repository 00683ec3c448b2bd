"""``genplan execute``: run a trajectory on the simulated robot at 1 kHz (genplan.control.execute).

    genplan execute --robot panda --trajectory plan_trajectory.npz --out log.npz --plot log.png --html log.html

The trajectory is a file of :meth:`genplan.trajectory.Trajectory.save` (``.npz``, ``.json``,
``.csv``: e.g. ``genplan plan --trajectory``), or an ``.npz`` with arrays ``t`` and ``q``
(optionally ``qd``, ``qdd``); another rate than ``--dt`` is resampled. The controller is the
seq2seq paper's P-D + disturbance observer in the task space of ``--task-frame`` (default: the
robot's tool frame), or ``--joint-space``. ``--payload-mass`` puts a load the controller knows at
that frame; ``--unknown-payload-mass`` one it does not know (a model error the observer
absorbs). The log (``.npz``: per tick the joint and tool-frame tracking errors, torques, the
observer's estimate, limit ratios; ``genplan.control.ExecutionLog``), a plot of the errors and
torques (``--plot``, PNG) and a 3D view of the executed motion beside the planned one (``--html``:
:func:`genplan.viewer.export_execution_html`) are written atomically. Exit code 0 when the run is
executable (within the joint limits, without a collision when ``--scene`` is given), else 1.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import warnings
from pathlib import Path
from typing import Any

from genplan.cli import args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True, help="a preset name (genplan info lists them), a robot file (.toml) or a URDF")
    p.add_argument("--trajectory", type=A.existing_file, required=True,
                   help="a trajectory file (.npz, .json, .csv of Trajectory.save), or an .npz with arrays t and q")
    p.add_argument("--task-frame", default=None,
                   help="the controlled (and logged) frame: a role such as 'hand' or a link name; default: the tool frame")
    p.add_argument("--joint-space", action="store_true", help="servo the joints instead of the task frame")
    p.add_argument("--payload-mass", type=A.non_negative_float, default=0.0,
                   help="kg held at the task frame, known to the controller (default 0)")
    p.add_argument("--unknown-payload-mass", type=A.non_negative_float, default=0.0,
                   help="kg held at the task frame that the controller does not know (default 0)")
    p.add_argument("--no-dob", action="store_true", help="do not feed the disturbance observer back")
    p.add_argument("--dt", type=A.positive_float, default=1e-3, help="control period in seconds (default 0.001)")
    p.add_argument("--settle", type=A.non_negative_float, default=0.5,
                   help="seconds holding the first sample before the motion (default 0.5)")
    p.add_argument("--strict", action="store_true",
                   help="refuse a trajectory over the torque limits and stop at the first tick over a limit")
    p.add_argument("--scene", default=None, help="check the executed motion against a scene (a shipped name or a file)")
    p.add_argument("--task", default=None, help="report the task's constraint residuals along the executed motion")
    p.add_argument("--out", type=A.output_file, required=True, help="the log (.npz)")
    p.add_argument("--plot", type=A.output_file, default=None, help="a PNG of the tracking errors and torques")
    p.add_argument("--html", type=A.output_file, default=None,
                   help="a 3D view (one HTML file, works offline) of the executed motion, a translucent robot, beside "
                        "the planned one; needs pip install 'genplan[viewer]'")


def read_trajectory(path: Path) -> Any:
    """A Trajectory file, or an .npz with arrays ``t`` and ``q`` (and optionally ``qd``, ``qdd``)."""
    import numpy as np

    from genplan._files import read_npz
    from genplan.errors import DataFileError
    from genplan.trajectory import Trajectory

    if path.suffix.lower() != ".npz":
        return Trajectory.load(path)
    arrays = read_npz(path, "--trajectory")
    if "meta" in arrays:
        return Trajectory._from_npz(arrays, path)
    if "t" not in arrays or "q" not in arrays:
        raise DataFileError(f"--trajectory {path}: an .npz needs the arrays t and q (or a Trajectory file), "
                            f"has {sorted(arrays)}")
    try:
        return {k: np.asarray(arrays[k], dtype=np.float64) for k in ("t", "q", "qd", "qdd") if k in arrays}
    except (TypeError, ValueError) as exc:
        raise DataFileError(f"--trajectory {path}: an array is not numbers ({exc})") from None


def main(args: argparse.Namespace) -> int:
    import genplan
    from genplan.control import ControllerSettings, Disturbances, JointLimits, LimitWarning, Payload, execute

    if args.out.suffix.lower() != ".npz":
        raise A.UsageError(f"--out {args.out}: the log is written as .npz")
    if args.plot is not None and args.plot.suffix.lower() != ".png":
        raise A.UsageError(f"--plot {args.plot}: the plot is written as .png")
    if args.html is not None:
        if args.html.suffix.lower() not in (".html", ".htm"):
            raise A.UsageError(f"--html {args.html}: the view is written as .html")
        if importlib.util.find_spec("viser") is None:
            raise A.UsageError(f"--html {args.html}: the view needs the optional dependency viser: "
                               "pip install 'genplan[viewer]'")
    robot = genplan.load(args.robot)
    trajectory = read_trajectory(args.trajectory)
    controller = ControllerSettings(space="joint" if args.joint_space else "task", frame=args.task_frame,
                                    dob=not args.no_dob)
    payload = Payload(mass=args.payload_mass) if args.payload_mass > 0 else None
    unknown = Payload(mass=args.unknown_payload_mass) if args.unknown_payload_mass > 0 else None
    world = None
    if args.scene is not None:
        world = robot.collision_world()
        world.add_scene(args.scene)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LimitWarning)
        log = execute(robot, trajectory, controller=controller, disturbances=Disturbances(payload=unknown),
                      payload=payload, limits=JointLimits(), dt=args.dt, settle=args.settle, strict=args.strict,
                      world=world, task=args.task)
    log.save(args.out)
    s = log.summary
    print(f"{robot.name}: {len(log.t)} ticks at {args.dt * 1e3:g} ms ({log.meta['space']} space on "
          f"{log.meta['frame']}), {log.us_per_tick:.2f} us a tick ({log.realtime_factor:.0f}x real time)")
    print(f"  tool frame: max error {log.max_tracking_error_mm:.3f} mm / {log.max_tracking_error_deg:.3f} deg; "
          f"joints: max error {math.degrees(log.max_joint_error):.3f} deg")
    print(f"  torque / limit: max {s['max_torque_ratio']:.3f} (reference {log.reference_torque_ratio:.3f}); "
          f"speed / limit: max {s['max_velocity_ratio']:.3f}; saturated ticks {s['saturated_ticks']}")
    for w in caught:
        print(f"  warning: {w.message}")
    if log.residuals:
        worst = max(log.residuals, key=lambda k: log.residuals[k] / log.tolerances[k])
        print(f"  task: largest residual ratio {log.residuals[worst] / log.tolerances[worst]:.3f} ({worst})")
    if log.in_collision is not None:
        print(f"  collision: {f'yes, {int(log.in_collision.sum())} ticks' if log.collided else 'none'}")
    print(f"  wrote {args.out}")
    if args.plot is not None:
        log.plot(args.plot)
        print(f"  wrote {args.plot}")
    if args.html is not None:
        from genplan.trajectory import Trajectory
        from genplan.viewer import export_execution_html

        planned = trajectory if isinstance(trajectory, Trajectory) else None  # else the run's reference
        export_execution_html(robot, log, args.html, planned=planned, scene=args.scene)
        print(f"  wrote {args.html}")
    return 0 if log.executable else 1
