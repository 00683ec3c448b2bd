"""Writes tests/data/control_reference.npz: the spatula controller's runs (the seq2seq paper's
Fig. 12 experiment as ``genplan bench control`` runs it, and the runs of the controller's unit
tests) as computed by the code at commit 03c44ab, before the 1 kHz loop became one loop for every
fixed-base robot. tests/test_pancake_control.py replays the same trajectories through today's
code and checks that the spatula configuration of the general loop gives the same numbers.

Stored per run: the trajectory it executed (so that the replay needs neither torch nor casadi),
how it was run, every summary number (float64, full precision) and a SHA-256 of each log array
(bit-identity); the joint positions, torques, observer estimate, tracking errors, phi and slide
of the Fig. 12 run with the DOB, every tick (within-noise comparisons).

    PYTHONPATH=<checkout at 03c44ab>/python .venv/bin/python tests/data/make_control_reference.py
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from genplan import control
from genplan.errors import LimitExceededError
from genplan.experiments.benchmarks import control as bench
from genplan.pancake.trajectories import s_curve

#: the log arrays compared bit for bit (names of the ExecutionLog at 03c44ab)
ARRAYS = ("t", "p_cmd", "p", "position_cmd", "position", "rotation", "error_position", "error_rotation", "q", "v",
          "tau", "tau_dis_hat", "tau_dis", "acceleration", "phi", "slide", "normal", "pancake_mode", "damped", "det_j")
#: the arrays of the Fig. 12 run with the DOB stored whole
LOGGED = ("q", "tau", "tau_dis_hat", "error_position", "error_rotation", "phi", "slide")
#: the summary numbers compared (all but the wall time)
SUMMARY = ("ticks", "max_error_position", "max_error_rotation", "rms_error_position", "rms_error_rotation", "max_abs_phi",
           "slipped", "first_slip_time", "left_time", "max_abs_slide", "damped_ticks", "first_damped_time",
           "min_abs_det_j", "saturated_ticks", "max_abs_tau", "max_abs_v", "limit_ticks", "stopped_at_limit")


def trajectories() -> dict[str, np.ndarray]:
    """Every trajectory the runs execute: the unit tests' and the Fig. 12 experiment's."""
    jump = np.zeros((400, 3))
    jump[200:, 0] = 0.3
    out = {
        "gentle": s_curve([0.0, 0.0, 0.0], [0.06, 0.02, -0.4]),
        "line": np.linspace([0.0, 0.0, 0.0], [0.0, 0.0, -0.75 * math.pi], 500),
        "fast": s_curve([0.0, 0.0, 0.0], [0.06, 0.02, -0.4], K=120),
        "singular": s_curve([0.6, 0.0, 0.0], [0.672, 0.0, 0.0]),
        "jump": jump,
        "short": s_curve([0.0, 0.0, 0.0], [0.01, 0.0, -0.1], K=100),
    }
    x, _, details = bench.adjusted_trajectory(objective="j2-exec")
    out["j2exec"] = x
    out["unadjusted_model_output"] = details["unadjusted_model_output"]
    out["j2"], _, _ = bench.adjusted_trajectory(objective="j2")
    peer = bench.casadi_j2_trajectory()
    if peer is not None:
        out["casadi_j2"] = peer[0]
    return out


#: name -> (trajectory, keyword arguments of control.SpatulaArm, of SpatulaArm.execute)
def runs() -> dict[str, tuple[str, dict[str, Any], dict[str, Any]]]:
    ref = control.Disturbances.reference()
    no_dob = control.ControllerConfig(dob=False)
    fig12 = {"j2exec": "j2exec", "j2": "j2", "unadjusted": "line", "unadjusted_model_output": "unadjusted_model_output",
             "casadi_j2": "casadi_j2"}
    out: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {}
    for name, traj in fig12.items():
        out[f"fig12_{name}_dob"] = (traj, {"disturbances": ref, "settle": 1.0}, {"tail": 0.1})
        out[f"fig12_{name}_no_dob"] = (traj, {"disturbances": ref, "settle": 1.0, "controller": no_dob}, {"tail": 0.1})
        out[f"fig12_{name}_undisturbed"] = (traj, {"settle": 1.0}, {"tail": 0.1})
    out.update({
        "gentle_dob": ("gentle", {"disturbances": ref, "settle": 0.5}, {}),
        "gentle_no_dob": ("gentle", {"disturbances": ref, "settle": 0.5, "controller": no_dob}, {}),
        "gentle_strict": ("gentle", {"settle": 0.2}, {"strict": True}),
        "line_tail": ("line", {"disturbances": ref, "settle": 0.3}, {"tail": 0.1}),
        "fast": ("fast", {"settle": 0.2}, {}),
        "singular": ("singular", {"settle": 0.0, "controller": control.ControllerConfig(singular_det=1e-2)}, {}),
        "jump": ("jump", {"settle": 0.2}, {}),
        "jump_velocity_limit": ("jump", {"settle": 0.2, "limits": control.JointLimits(torque=[math.inf] * 6,
                                                                                        velocity=[0.5] * 6)}, {}),
        "short_substeps_4": ("short", {"settle": 0.0, "substeps": 4, "disturbances": ref}, {}),
        "short_acceleration_feedforward": ("short", {"settle": 0.1, "controller": control.ControllerConfig(
            acceleration_feedforward=True, velocity_feedforward=False)}, {"tail": 0.05}),
        "short_no_model_compensation": ("short", {"settle": 0.5, "controller": control.ControllerConfig(
            model_compensation=False), "disturbances": ref}, {}),
    })
    return out


def describe(arm_kw: dict[str, Any], run_kw: dict[str, Any]) -> dict[str, Any]:
    """The run's settings as plain data (the replay rebuilds them with today's classes)."""
    d: dict[str, Any] = {}
    for k, v in arm_kw.items():
        d[k] = v.to_dict() if hasattr(v, "to_dict") else v
    return {"arm": d, "execute": dict(run_kw)}


def sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def main() -> None:
    trajs = trajectories()
    out: dict[str, Any] = {f"trajectory_{k}": v for k, v in trajs.items()}
    meta: dict[str, Any] = {"commit": "03c44ab", "runs": {}}
    for name, (traj, arm_kw, run_kw) in runs().items():
        if traj not in trajs:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", control.LimitWarning)
            log = control.SpatulaArm(**arm_kw).execute(trajs[traj], **run_kw)
        s = log.summary
        meta["runs"][name] = {
            "trajectory": traj, **describe(arm_kw, run_kw),
            "summary": {k: s[k] for k in SUMMARY},
            "limit_violation": s["limit_violation"],
            "motion": [log.motion_start, log.motion_end],
            "sha256": {k: sha(getattr(log, k)) for k in ARRAYS},
        }
        if name == "fig12_j2exec_dob":
            for k in LOGGED:
                out[f"log_{name}_{k}"] = getattr(log, k)
    # strict: the jump is refused at the tick where it first exceeds a limit
    try:
        control.SpatulaArm(settle=0.2).execute(trajs["jump"], strict=True)
    except LimitExceededError as e:
        meta["strict_jump_message"] = str(e)
    else:
        raise AssertionError("the jump passed strict")
    out["meta"] = np.array(json.dumps(meta, indent=1, sort_keys=True))
    path = Path(__file__).with_name("control_reference.npz")
    np.savez_compressed(path, **out)
    print(f"wrote {path} ({len(meta['runs'])} runs, {len(out)} arrays)")


if __name__ == "__main__":
    main()
