"""The seq2seq paper's sections of ``report.md`` (adjustment and controller), from the JSON of
``genplan bench adjust`` and ``genplan bench control``."""

from __future__ import annotations

from typing import Any

from genplan.experiments.common import table

METHODS = ("latent", "random-latent", "direct-u", "casadi")
LABELS = {"latent": "case 1: latent (encoder z)", "random-latent": "case 2: random latent", "direct-u": "case 3: direct U",
          "casadi": "CasADi + IPOPT (peer)"}


def _curve_at(curve: list[float], k: int) -> str:
    return f"{curve[k]:.3g}" if len(curve) > k else "-"


def adjust_section(res: dict[str, Any]) -> str:
    out = []
    for objective in ("j1", "j2"):
        rows = []
        found: dict[str, dict[str, Any]] = {}
        for m in METHODS:
            r = res.get(f"adjust/adjust_{objective}_{m}.json")
            if r is None or r.get("diverged"):
                continue
            found[m] = r
            c = r["objective_curve"]
            speed = (f"{r['ms_per_update']:.2f} ms / update" if "ms_per_update" in r
                     else f"{r['ms_per_problem']:.0f} ms / solve")
            to_level = (r.get("ms_to_j1_below_1e-3") or {}).get("median") if objective == "j1" else None
            rows.append([LABELS[m], r.get("step", "-"), r.get("problems", "-"), _curve_at(c, 0),
                         "-" if m == "casadi" else _curve_at(c, 5), f"{c[-1]:.3g}", f"{r['rmse_pos_mm']:.3g}",
                         f"{r['rmse_ang_deg']:.3g}", f"{r['max_abs_phi_deg']:.1f}", "yes" if r["constraint_ok"] else "NO",
                         speed, "-" if to_level is None else f"{to_level:.1f}"])
        if not rows:
            out.append(f"_{objective.upper()}: not run_\n")
            continue
        if objective == "j1":
            head = ("**J1 (eq. 17): reach 27 end poses from S-curve inputs; error = end pose vs target.** Paper "
                    "(case 1): mean J1 < 1e-3 after 5 updates, RMSE 0.27 mm / 0.30 deg after 100 updates, 1.21 s "
                    "per update (i7-8700).")
        else:
            head = ("**J2 (eq. 24): turn the pancake over more slowly; error = how far the end lies outside the "
                    "allowed ranges.**")
        notes = []
        lat, cas = found.get("latent"), found.get("casadi")
        if lat is not None:
            notes.append(f"One latent update costs {lat['ms_per_update']:.2f} ms per problem (batched), "
                         f"{1210.0 / lat['ms_per_update']:.0f}x less than the paper's 1.21 s.")
        if objective == "j1" and lat is not None and cas is not None:
            t_lat = (lat.get("ms_to_j1_below_1e-3") or {}).get("median")
            if t_lat:
                notes.append(f"Time to J1 < 1e-3 per problem (median): latent {t_lat:.1f} ms, CasADi + IPOPT solve "
                             f"{cas['ms_per_problem']:.0f} ms ({cas['ms_per_problem'] / t_lat:.0f}x).")
        out.append(head + "\n\n" + table(["method", "step rule", "problems", "J before", "J after 5", "J final",
                                           "RMSE pos mm", "RMSE ang deg", "max abs(phi) deg", "inside cone", "time",
                                           "ms to J<1e-3"], rows) + "\n\n" + " ".join(notes) + "\n")
    return "\n".join(out)


def _fmt(v: Any, spec: str = ".3g") -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return format(v, spec)
    return "-" if v is None else str(v)


def control_section(res: dict[str, Any]) -> str:
    c = res.get("control.json")
    if c is None:
        return "_not run_\n"
    runs = [("adjusted trajectory, P-D + DOB", c), ("same, without the DOB", c.get("without_dob")),
            ("same, no disturbances", c.get("undisturbed")),
            ("the paper's plain J2 plan, P-D + DOB", c.get("paper_j2")),
            ("unadjusted (too fast) input", c.get("unadjusted")),
            ("CasADi J2 solution, P-D + DOB", c.get("casadi_j2"))]
    rows = []
    for label, r in runs:
        if not isinstance(r, dict):
            continue
        rows.append([label, _fmt(r.get("max_tracking_error_mm")), _fmt(r.get("max_tracking_error_deg")),
                     _fmt(r.get("max_abs_phi_deg"), ".1f"), _fmt(r.get("slipped")),
                     _fmt(r.get("first_slip_time_s")), _fmt(r.get("us_per_tick"))])
    ratio = c.get("dob_tracking_error_ratio")
    ratio_txt = ""
    if isinstance(ratio, dict):
        ratio_txt = ("\n\nTracking error without / with the DOB (max position, max attitude): "
                     f"{_fmt(ratio.get('max_position'))} / {_fmt(ratio.get('max_attitude'))}.")
    crit = c.get("criterion_control_tick") or {}
    tick = f" One controller tick (criterion median): {_fmt(crit.get('median_us'))} us." if crit.get("median_us") else ""
    source = (c.get("trajectory") or {}).get("source", "?")
    return (f"The {source} trajectory executed at 1 kHz by the task-space P-D + disturbance-observer controller on "
            "the simulated UR5 with joint friction, an offset and a payload error (paper Fig. 12). "
            "The pancake slips when |phi| exceeds 45 deg; slip is judged during the motion (in the 0.1 s tail the "
            "pancake is meant to leave: the flip).\n\n"
            + table(["run", "max err mm", "max err deg", "max abs(phi) deg", "slipped", "first slip s", "us / tick"], rows)
            + ratio_txt + tick + "\n")
