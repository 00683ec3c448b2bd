"""The seq2seq paper's experiment (Section 5, Figs. 10-12) on the simulated UR5.

    genplan bench control --out benches/results/control.json   # + control_fig12.png beside it

Executes the turning-over trajectory with the paper's 1 kHz task-space P-D + DOB controller (the
spatula configuration of genplan's loop: ``genplan.pancake.control``) under the reference plant
deviations (payload error, joint friction, torque offset:
``genplan.pancake.control.reference_disturbances()``), after a settle phase and with the paper's
0.1 s constant-deceleration tail:

* the trajectory is the latent-adjusted one from the paper's constant-velocity input to
  ``[0, 0, -3 pi / 4]`` when the shipped seq2seq model ``genplan/models/pancake_seq2seq.safetensors``
  exists, else a cycloidal S-curve to the same end pose (not adjusted; it is expected to lose the
  pancake). The objective (``--objective``) is by default ``j2-exec``
  (:class:`genplan.pancake.adjustment.J2Executable`: eq. 24 plus execution margins, 500 Adam
  updates); the paper's plain J2 plan (eq. 24, 20 latent updates) is executed too
  (``paper_j2``): its optimum rides the cone's edge and ends in near free fall, and the pancake
  slides off under the controller's tracking lag;
* the same run without the DOB gives the tracking-error ratio the DOB buys;
* the unadjusted input (constant velocity, too fast for the pancake) gives the slip verdict the
  adjustment is for;
* when casadi is installed (the ``bench`` extra), the same J2 problem solved by CasADi + IPOPT with
  a hard friction cone is executed too (an adjusted trajectory that exists without the model);
* ``us_per_tick``: median over ``--repeats`` unpaced runs of the Rust loop's wall time per tick
  (controller + plant RK4 + pancake); a paced run (wall-clock 1 ms ticks) reports the jitter.

Slip and phi verdicts cover the motion (the K samples), not the tail, where the pancake is
meant to leave the spatula (that is the flip). Tracking errors cover the motion and the tail.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import control
from genplan.cli import args as A
from genplan.experiments.common import machine, save_figure, table, write_json
from genplan.pancake import control as pc

#: the paper's J2 input (Section 5.2) and horizon
P_END = (0.0, 0.0, -0.75 * math.pi)
K = 500


def model_path() -> Path:
    """Where the shipped seq2seq model lives (``genplan.pancake.model.default_path()``; checked
    without importing torch)."""
    return Path(control.__file__).resolve().parent / "models" / "pancake_seq2seq.safetensors"


def line_input(k: int = K) -> NDArray[np.float64]:
    """The paper's J2 input: constant velocity from the origin to ``P_END`` in ``k`` samples."""
    from genplan.pancake import linear

    return linear([0.0, 0.0, 0.0], P_END, K=k)


def casadi_j2_trajectory() -> tuple[NDArray[np.float64], float] | None:
    """The J2 problem solved by CasADi + IPOPT (the peer of the latent method), if casadi is
    installed (the ``bench`` extra) and the solve succeeds: (trajectory (K, 3), seconds)."""
    try:
        from genplan.experiments.peers.casadi import PancakeNLP
    except ImportError:
        return None
    try:
        nlp = PancakeNLP(objective="j2")
        t0 = time.perf_counter()
        r = nlp.solve([0.0, 0.0, 0.0], list(P_END))
    except ImportError:
        return None
    if not r["success"]:
        return None
    return np.asarray(r["p"], dtype=np.float64), time.perf_counter() - t0


def planned_phi(p: NDArray[np.float64], dt: float = pc.DT) -> NDArray[np.float64]:
    """phi of a pose trajectory from its central-difference accelerations (end samples: one-sided)."""
    from genplan.pancake.trajectories import phi

    acc = np.gradient(np.gradient(p, dt, axis=0), dt, axis=0)
    return phi(p[:, 2], acc[:, :2])


#: objective -> (latent updates, step rule) of the bench's adjustment
ADJUSTMENT = {"j2": (20, "adaptive"), "j2-exec": (500, "adam")}


def adjusted_trajectory(updates: int | None = None, path: Path | None = None, objective: str = "j2-exec",
                        step: str | None = None) -> tuple[NDArray[np.float64], str, dict[str, Any]]:
    """(trajectory (K, 3), source, details): the trajectory adjusted for ``objective``
    (``"j2"``: the paper's eq. 24, default 20 adaptive updates; ``"j2-exec"``: eq. 24 plus
    execution margins, default 500 Adam updates) from the shipped model (or ``path``) when it
    exists, else an S-curve to the same end pose."""
    if objective not in ADJUSTMENT:
        raise ValueError(f"objective must be one of {sorted(ADJUSTMENT)}, got {objective!r}")
    d_updates, d_step = ADJUSTMENT[objective]
    updates = d_updates if updates is None else updates
    step = d_step if step is None else step
    path = model_path() if path is None else Path(path)
    if not path.is_file():
        from genplan.pancake.trajectories import s_curve

        x = s_curve([0.0, 0.0, 0.0], P_END, K=K)
        return x, "s-curve to [0, 0, -3 pi/4] (no seq2seq model: not adjusted)", {
            "planned_max_abs_phi_deg": float(np.degrees(np.abs(planned_phi(x)).max())),
        }
    # torch: only when the model is there
    import torch

    from genplan.pancake import physics as ph
    from genplan.pancake.adjustment import J2, J2Executable, adjust, normal_acceleration
    from genplan.pancake.model import load_model

    model = load_model(path)
    obj = J2Executable() if objective == "j2-exec" else J2()
    t0 = time.perf_counter()
    res = adjust(line_input(model.config.K), objective=obj, method="latent", updates=updates, model=model,
                 step=step, snapshots=(0,))
    adjust_s = time.perf_counter() - t0
    r = ph.Rollout(**{k: torch.as_tensor(getattr(res, k), dtype=torch.float32) for k in ("p", "v", "u", "phi")})
    paper_j2 = J2()
    paper_terms = paper_j2.values(r)
    details = {
        "objective": objective,
        "adjust_s": adjust_s,
        "updates": updates,
        "step": step,
        "objective_before": float(res.objective_history[0, 0]),
        "objective_after": float(res.objective_history[-1, 0]),
        "j2_after": float(paper_j2.combine(paper_terms)[0]),
        "j2_terms_after": {k: float(v[0]) for k, v in paper_terms.items()},
        "planned_max_abs_phi_deg": float(np.degrees(np.abs(res.phi[0]).max())),
        "planned_min_normal_acceleration": float(normal_acceleration(r)[0].min()),
        "planned_end_pose": res.p[0, -1].tolist(),
        "planned_end_distance_m": float(np.hypot(*res.p[0, -1, :2])),
        "planned_max_speed": np.abs(res.v[0]).max(0).tolist(),
        "model_sha256": str(model.card.get("weights_sha256", ""))[:12],
        "unadjusted_model_output": res.snapshots[0]["p"][0],
    }
    what = "eq. 24 + execution margins (J2Executable)" if objective == "j2-exec" else "eq. 24 (J2)"
    return res.p[0], f"seq2seq, latent-adjusted for {what}: {updates} {step} updates, {path.name}", details


def criterion_tick() -> dict[str, Any] | None:
    """The last criterion result of ``control_tick/ur5`` (``cargo bench -p genplan-core --bench
    control``), if there is one in ``target/criterion``."""
    import json
    from datetime import datetime, timezone

    root = Path(__file__).resolve().parents[3]
    candidates = [root / "target" / "criterion" / d / "new" / "estimates.json" for d in ("control_tick_ur5", "control_tick/ur5")]
    est = next((c for c in candidates if c.is_file()), None)
    if est is None:
        return None
    median = json.loads(est.read_text())["median"]
    ci = median["confidence_interval"]
    return {"median_us": median["point_estimate"] / 1e3, "ci95_us": [ci["lower_bound"] / 1e3, ci["upper_bound"] / 1e3],
            "measured": datetime.fromtimestamp(est.stat().st_mtime, timezone.utc).isoformat(timespec="seconds"),
            "command": "cargo bench -p genplan-core --bench control"}


def _deviation(log: pc.SpatulaLog, nominal: pc.SpatulaLog) -> dict[str, float]:
    """How far a disturbed run's spatula strays from the undisturbed plant's (after settling)."""
    sl = slice(log.motion_start, None)
    dp = np.linalg.norm(log.position[sl] - nominal.position[sl], axis=1)
    dr = np.einsum("nij,nkj->nik", log.rotation[sl], nominal.rotation[sl])
    ang = np.arccos(np.clip((np.trace(dr, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    return {"max_mm": 1e3 * float(dp.max()), "max_deg": math.degrees(float(ang.max())),
            "rms_mm": 1e3 * float(np.sqrt(np.mean(dp ** 2))), "rms_deg": math.degrees(float(np.sqrt(np.mean(ang ** 2))))}


def _first(log: pc.SpatulaLog, mask: NDArray[np.bool_]) -> float | None:
    """Seconds from the motion's start to the first tick of ``mask`` during the motion (None: not
    during the motion; in the tail the pancake is meant to leave)."""
    hits = np.flatnonzero(mask[log.motion_start:log.motion_end])
    return None if hits.size == 0 else float(log.t[log.motion_start + hits[0]] - log.t[log.motion_start])


def _run_summary(log: pc.SpatulaLog) -> dict[str, Any]:
    s = log.summary
    return {
        "max_tracking_error_mm": log.max_tracking_error_mm,
        "max_tracking_error_deg": log.max_tracking_error_deg,
        "rms_tracking_error_mm": 1e3 * s["rms_error_position"],
        "rms_tracking_error_deg": math.degrees(s["rms_error_rotation"]),
        "max_abs_phi_deg": log.max_abs_phi_deg,
        "slipped": log.slipped,
        "first_slip_time_s": _first(log, log.pancake_mode != 0),
        "left_spatula_time_s": _first(log, log.pancake_mode == 2),
        "min_normal_acceleration": float(log.normal[log.motion_start:log.motion_end].min()),
        "max_slide_mm": 1e3 * s["max_abs_slide"],
        "damped_ticks": s["damped_ticks"],
        "max_abs_tau_nm": s["max_abs_tau"],
        "max_abs_v_rad_s": s["max_abs_v"],
        "joint_limit_violation": log.limit_violation,
        "us_per_tick": log.us_per_tick,
    }


def run(updates: int | None = None, repeats: int = 7, settle: float = 1.0, tail: float = 0.1, paced: bool = True,
        png: Path | None = None, objective: str = "j2-exec") -> dict[str, Any]:
    traj, source, details = adjusted_trajectory(updates, objective=objective)
    unadjusted_output = details.pop("unadjusted_model_output", None)
    dist = pc.reference_disturbances()
    arm = pc.SpatulaArm(disturbances=dist, settle=settle)
    arm_no_dob = pc.SpatulaArm(disturbances=dist, settle=settle, controller=pc.PAPER_CONTROLLER.replace(dob=False))
    logs = [arm.execute(traj, tail=tail) for _ in range(max(1, repeats))]
    with_dob = logs[-1]
    without = arm_no_dob.execute(traj, tail=tail)
    nominal = pc.SpatulaArm(settle=settle).execute(traj, tail=tail)
    unadjusted = arm.execute(line_input(), tail=tail)
    dev_dob, dev_no = _deviation(with_dob, nominal), _deviation(without, nominal)

    def ratio(a: float, b: float) -> float:
        return a / max(b, 1e-15)

    payload: dict[str, Any] = {
        "us_per_tick": statistics.median(log.us_per_tick for log in logs),
        **{k: v for k, v in _run_summary(with_dob).items() if k != "us_per_tick"},
        "deviation_from_undisturbed": dev_dob,
        "us_per_tick_runs": [log.us_per_tick for log in logs],
        "ticks_per_run": int(with_dob.t.shape[0]),
        "without_dob": {**_run_summary(without), "deviation_from_undisturbed": dev_no},
        "undisturbed": _run_summary(nominal),
        "dob_tracking_error_ratio": {
            "note": "without / with the DOB (> 1: the DOB helps); deviation = distance to the response of the "
                    "undisturbed plant, i.e. the part of the error the DOB exists to reject",
            "max_position": ratio(without.max_tracking_error_mm, with_dob.max_tracking_error_mm),
            "max_attitude": ratio(without.max_tracking_error_deg, with_dob.max_tracking_error_deg),
            "rms_position": ratio(without.summary["rms_error_position"], with_dob.summary["rms_error_position"]),
            "rms_attitude": ratio(without.summary["rms_error_rotation"], with_dob.summary["rms_error_rotation"]),
            "deviation_position": ratio(dev_no["max_mm"], dev_dob["max_mm"]),
            "deviation_attitude": ratio(dev_no["max_deg"], dev_dob["max_deg"]),
        },
        "unadjusted": {"source": "the paper's J2 input: constant velocity to [0, 0, -3 pi/4] in 0.5 s",
                       "planned_max_abs_phi_deg": float(np.degrees(np.abs(planned_phi(line_input())).max())),
                       **_run_summary(unadjusted)},
        "trajectory": {"source": source, "K": int(traj.shape[0]), "tail_s": tail, "settle_s": settle, **details},
        "disturbances": {**dist.to_dict(), "payload": dist.payload.to_dict() if dist.payload else None},
        "controller": arm.controller.to_dict(),
        "setup": pc.SpatulaSetup().to_dict(),
        "robot": "ur5",
        "machine": machine(),
        "command": "genplan " + " ".join(sys.argv[1:]) if sys.argv and sys.argv[0].endswith("genplan") else None,
    }
    peer = casadi_j2_trajectory()
    if peer is not None:
        x, solve_s = peer
        log_peer = arm.execute(x, tail=tail)
        log_peer_no = arm_no_dob.execute(x, tail=tail)
        log_peer_nom = pc.SpatulaArm(settle=settle).execute(x, tail=tail)
        d_with, d_no = _deviation(log_peer, log_peer_nom), _deviation(log_peer_no, log_peer_nom)
        payload["casadi_j2"] = {"source": "the same J2 problem solved by CasADi + IPOPT (hard friction cone; "
                                          "genplan.experiments.peers.casadi), executed the same way",
                                "solve_s": solve_s,
                                "planned_end_pose": x[-1].tolist(), **_run_summary(log_peer),
                                "deviation_from_undisturbed": d_with,
                                "without_dob": {**_run_summary(log_peer_no), "deviation_from_undisturbed": d_no},
                                "undisturbed": _run_summary(log_peer_nom),
                                "dob_deviation_ratio": {"position": ratio(d_no["max_mm"], d_with["max_mm"]),
                                                        "attitude": ratio(d_no["max_deg"], d_with["max_deg"])}}
    if objective != "j2" and "objective" in details:
        x, src, det = adjusted_trajectory(objective="j2")
        det.pop("unadjusted_model_output", None)
        log_j2 = arm.execute(x, tail=tail)
        payload["paper_j2"] = {"source": src, "plan": det, **_run_summary(log_j2),
                               "undisturbed": _run_summary(pc.SpatulaArm(settle=settle).execute(x, tail=tail))}
    if unadjusted_output is not None:
        log0 = arm.execute(unadjusted_output, tail=tail)
        payload["unadjusted_model_output"] = {"source": "the model's output before any update (Fig. 11, 0th)",
                                              **_run_summary(log0)}
    if paced:
        paced_log = arm.execute(traj, tail=tail, paced=True)
        payload["jitter_us"] = paced_log.jitter
        payload["paced_matches_unpaced"] = bool(np.array_equal(paced_log.q, with_dob.q))
    crit = criterion_tick()
    if crit is not None:
        payload["criterion_control_tick"] = crit
    if png is not None:
        figure(with_dob, without, unadjusted, source, png)
        payload["figure"] = str(png)
    return payload


def figure(dob: pc.SpatulaLog, no_dob: pc.SpatulaLog, unadjusted: pc.SpatulaLog, source: str, path: Path) -> None:
    """Fig. 12 of the paper: command and response of y, z, theta over time; plus the tracking
    error with and without the DOB and the friction-cone angle phi of the achieved motion."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0 = dob.t[dob.motion_start]
    sl = slice(max(0, dob.motion_start - 100), None)
    t = dob.t[sl] - t0
    t_end = dob.t[dob.motion_end - 1] - t0
    fig, ax = plt.subplots(5, 1, figsize=(7.5, 11), sharex=True)
    labels = [("y [mm]", 0, 1e3), ("z [mm]", 1, 1e3), ("theta [deg]", 2, 180 / math.pi)]
    for a, (lab, c, scale) in zip(ax[:3], labels):
        a.plot(t, dob.p_cmd[sl, c] * scale, "k-", lw=1.2, label="command")
        a.plot(t, dob.p[sl, c] * scale, "C0-", lw=1.0, label="response (DOB)")
        a.plot(t, no_dob.p[sl, c] * scale, "C1--", lw=1.0, label="response (no DOB)")
        a.set_ylabel(lab)
    ax[0].legend(loc="best", fontsize=8)
    ax[3].plot(t, dob.error_position[sl] * 1e3, "C0-", lw=1.0, label="position, DOB")
    ax[3].plot(t, no_dob.error_position[sl] * 1e3, "C1--", lw=1.0, label="position, no DOB")
    ax3b = ax[3].twinx()
    ax3b.plot(t, np.degrees(dob.error_rotation[sl]), "C2-", lw=0.8, label="attitude, DOB")
    ax3b.plot(t, np.degrees(no_dob.error_rotation[sl]), "C3--", lw=0.8, label="attitude, no DOB")
    ax[3].set_ylabel("error [mm]")
    ax3b.set_ylabel("error [deg]")
    ax[3].legend(loc="upper left", fontsize=7)
    ax3b.legend(loc="upper right", fontsize=7)
    cone = math.degrees(math.atan(1.0))
    ax[4].axhspan(-cone, cone, color="C0", alpha=0.12, label="|phi| < atan(mu)")
    ax[4].plot(t, np.degrees(dob.phi[sl]), "C0-", lw=1.0, label="phi (executed)")
    tu = unadjusted.t[sl] - unadjusted.t[unadjusted.motion_start]
    ax[4].plot(tu, np.degrees(unadjusted.phi[sl]), "C3:", lw=1.0, label="phi (unadjusted input)")
    slip = dob.slip[sl]
    if slip.any():
        ax[4].plot(t[slip], np.degrees(dob.phi[sl][slip]), "r.", ms=2, label="pancake sliding/off")
    ax[4].set_ylabel("phi [deg]")
    ax[4].set_ylim(-180, 180)
    ax[4].legend(loc="lower left", fontsize=7)
    for a in ax:
        a.axvspan(t_end, t[-1], color="0.85", alpha=0.5)
        a.axvline(0.0, color="0.5", lw=0.5)
    ax[-1].set_xlabel("time from motion start [s] (grey: 0.1 s deceleration tail)")
    import textwrap

    fig.suptitle("UR5 spatula, 1 kHz task-space P-D + DOB (2 Hz)\n" + "\n".join(textwrap.wrap(source, 90)), fontsize=9)
    fig.tight_layout()
    path = Path(path)
    save_figure(fig, path, dpi=120)
    plt.close(fig)
    print(f"wrote {path}")


def _row(label: str, r: dict[str, Any]) -> list[Any]:
    """A table row of one run's summary (:func:`_run_summary`)."""
    v = r.get("joint_limit_violation")
    limits = "yes" if v is None else f"no: {v['joint']} {v['quantity']} at {v['time']:.3f} s"
    return [label, r["max_tracking_error_mm"], r["max_tracking_error_deg"], r["max_abs_phi_deg"], r["slipped"], limits]


def print_table(p: dict[str, Any]) -> None:
    rows = [
        _row("executed (DOB)", p),
        _row("executed (no DOB)", p["without_dob"]),
        _row("undisturbed plant", p["undisturbed"]),
        *([_row("paper's J2 plan (DOB)", p["paper_j2"])] if "paper_j2" in p else []),
        *([_row("CasADi J2 optimum (DOB)", p["casadi_j2"])] if "casadi_j2" in p else []),
        _row("unadjusted input (DOB)", p["unadjusted"]),
    ]
    print(f"trajectory: {p['trajectory']['source']}")
    print(table(["run", "max err [mm]", "max err [deg]", "max |phi| [deg]", "slipped", "within joint limits"], rows))
    r = p["dob_tracking_error_ratio"]
    print(f"DOB, error without / with: max {r['max_position']:.2f} (position) {r['max_attitude']:.2f} (attitude); "
          f"rms {r['rms_position']:.2f} / {r['rms_attitude']:.2f}; deviation from the undisturbed response "
          f"{r['deviation_position']:.2f} / {r['deviation_attitude']:.2f}")
    print(f"us per tick (controller + plant + pancake, median of {len(p['us_per_tick_runs'])} runs): {p['us_per_tick']:.2f}")
    if "jitter_us" in p:
        j = p["jitter_us"]
        print(f"paced 1 ms: lateness p50 {j['lateness_p50_us']:.1f} us, p99 {j['lateness_p99_us']:.1f} us, "
              f"max {j['lateness_max_us']:.1f} us, overruns {j['overruns']}")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--objective", choices=sorted(ADJUSTMENT), default="j2-exec",
                   help="j2-exec (default): eq. 24 plus execution margins (J2Executable); j2: the paper's eq. 24")
    p.add_argument("--updates", type=A.non_negative_int, default=None,
                   help="latent updates (default: 500 Adam for j2-exec; 20 adaptive for j2, the paper's 20)")
    p.add_argument("--repeats", type=A.positive_int, default=7, help="unpaced runs timed for us_per_tick")
    p.add_argument("--settle", type=A.non_negative_float, default=1.0,
                   help="seconds holding the start pose before the motion")
    p.add_argument("--tail", type=A.non_negative_float, default=0.1, help="constant-deceleration tail (s; the paper: 0.1)")
    p.add_argument("--no-paced", action="store_true", help="skip the wall-clock paced run (jitter)")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")
    p.add_argument("--png", type=A.output_file, default=None,
                   help="Fig. 12-like figure (default: <out stem>_fig12.png beside --out)")


def main(args: argparse.Namespace) -> int:
    png = args.png
    if png is None and args.out is not None:
        png = args.out.with_name(args.out.stem + "_fig12.png")
    with warnings.catch_warnings():  # the table and the JSON say which runs exceed the joint limits
        warnings.simplefilter("ignore", control.LimitWarning)
        payload = run(args.updates, args.repeats, args.settle, args.tail, not args.no_paced, png, args.objective)
    print_table(payload)
    write_json(args.out, payload)
    return 0
