"""genplan.pancake.control: the seq2seq paper's spatula experiment as one configuration of the
general 1 kHz loop, on the simulated UR5.

It keeps the results of the spatula loop it replaced (below); its conventions are cross-checked
with Pinocchio (the commanded pose is where Pinocchio puts the spatula at the initial
configuration), phi of the loop against the pancake module's function; slip verdicts, the DOB's
effect, input errors, settings errors naming the field, joint limits, paced mode, the
deceleration tail and the run's bounds.

tests/data/control_reference.npz holds the runs of the code at 03c44ab (the Fig. 12 experiment as
``genplan bench control`` runs it, the controller's unit-test runs; written by
tests/data/make_control_reference.py): each is replayed here with today's classes and compared,
every summary number to 1e-9 (relative, or 1e-15 absolute for the numbers that are zero up to
rounding), every tick of the Fig. 12 run with the DOB to 1e-9 (relative; 1e-12 absolute), and
every discrete outcome (the pancake's slip and its tick, when it leaves the blade, damped,
saturated and limit ticks, the first limit event) exactly. Not to the bit: the plant computes
the same dynamics in another order (the articulated-body algorithm instead of CRBA + Cholesky,
the RK stages' joint angles by angle addition, the friction's tanh in one exp), which moves each
evaluation by rounding (1e-16 relative). The loop is stable, so those differences do not grow:
measured over every run, the summary numbers agree to 1e-13 relative except where the task
inverse is damped near a singularity (``singular``: 4.3e-10, the most sensitive run) or a
reference jump saturates the motion (``jump``: 3.2e-11), and the Fig. 12 run's joint positions
to 2.2e-16 rad, its torques to 3.1e-13 N m (7e-12 relative). A change of the method (a gain, a
model term, the integrator) moves them by 1e-6 or more.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import control
from genplan.errors import GenplanError, LimitExceededError, NonFiniteError, SettingsError, ShapeError
from genplan.pancake import control as pc
from genplan.pancake.trajectories import phi as phi_py
from genplan.pancake.trajectories import s_curve

GENTLE = s_curve([0.0, 0.0, 0.0], [0.06, 0.02, -0.4])
#: the paper's unadjusted J2 input (Section 5.2): constant velocity to [0, 0, -3 pi / 4] in 0.5 s
LINE = np.linspace([0.0, 0.0, 0.0], [0.0, 0.0, -0.75 * math.pi], 500)

REFERENCE = Path(__file__).parent / "data" / "control_reference.npz"


# ---------------------------------------------------------------------------------------------
# the reference: the runs of the spatula loop at 03c44ab
# ---------------------------------------------------------------------------------------------

def load_reference() -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    with np.load(REFERENCE) as z:
        arrays = {k: z[k] for k in z.files}
    return json.loads(str(arrays.pop("meta"))), arrays


def settings(described: dict[str, Any]) -> dict[str, Any]:
    """The arguments of SpatulaArm today for a run described with the old classes' fields."""
    kw: dict[str, Any] = {}
    for key, value in described.items():
        if key == "controller":
            v = dict(value)
            assert v.pop("torque_limit") is None
            kp = [v.pop("kpp")] * 3 + [v.pop("kpr")] * 3
            kv = [v.pop("kvp")] * 3 + [v.pop("kvr")] * 3
            kw["controller"] = pc.PAPER_CONTROLLER.replace(kp=kp, kv=kv, **v)
        elif key == "disturbances":
            v = dict(value)
            mass, com = v.pop("payload_mass"), v.pop("payload_com")
            payload = control.Payload(mass=mass, com=com) if mass > 0 else None
            kw["disturbances"] = control.Disturbances(payload=payload, **v)
        elif key == "limits":
            kw["limits"] = control.JointLimits(policy="log", **value)
        else:
            kw[key] = value
    return kw


def replay(run: dict[str, Any], arrays: dict[str, np.ndarray]) -> pc.SpatulaLog:
    traj = arrays[f"trajectory_{run['trajectory']}"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.LimitWarning)
        return pc.SpatulaArm(**settings(run["arm"])).execute(traj, **run["execute"])


def close(a: Any, b: Any, rtol: float = 1e-9, atol: float = 1e-15) -> bool:
    if isinstance(b, (list, tuple)):
        # per-joint values within rtol of the largest: a joint the motion does not load holds
        # only rounding residue (1e-10 N m beside 19 N m), which any reordering of the sums moves
        scale = max((abs(y) for y in b if isinstance(y, float) and math.isfinite(y)), default=0.0)
        return len(a) == len(b) and all(close(x, y, rtol, max(atol, rtol * scale)) for x, y in zip(a, b))
    if isinstance(b, float) and isinstance(a, float):
        return math.isclose(a, b, rel_tol=rtol, abs_tol=atol) or (math.isnan(a) and math.isnan(b))
    return a == b


@pytest.fixture(scope="module")
def replayed() -> tuple[dict[str, Any], dict[str, np.ndarray], dict[str, pc.SpatulaLog]]:
    meta, arrays = load_reference()
    runs = {name: replay(run, arrays) for name, run in meta["runs"].items()}
    return meta, arrays, runs


def test_every_run_has_the_reference_summary(replayed):
    meta, _, runs = replayed
    assert len(runs) >= 20
    for name, run in meta["runs"].items():
        log = runs[name]
        for key, expect in run["summary"].items():
            assert close(log.summary[key], expect), (name, key, log.summary[key], expect)
        assert [log.motion_start, log.motion_end] == run["motion"], name
        v, w = log.limit_violation, run["limit_violation"]
        assert (v is None) == (w is None), name
        if w is not None:
            assert {k: v[k] for k in ("tick", "joint", "quantity", "unit", "message")} == \
                   {k: w[k] for k in ("tick", "joint", "quantity", "unit", "message")}, name
            assert close(v["value"], w["value"]) and close(v["limit"], w["limit"]), name


def test_the_fig12_run_is_the_same_every_tick(replayed):
    _, arrays, runs = replayed
    log = runs["fig12_j2exec_dob"]
    for key in ("q", "tau", "tau_dis_hat", "error_position", "error_rotation", "phi", "slide"):
        ref = arrays[f"log_fig12_j2exec_dob_{key}"]
        got = getattr(log, key)
        assert got.shape == ref.shape, key
        assert np.allclose(got, ref, rtol=1e-9, atol=1e-12), (key, float(np.max(np.abs(got - ref))))


def test_the_pancake_outcomes_are_identical(replayed):
    """The discrete outcome of every run is the reference's exactly, not within a tolerance: the
    pancake's slip verdict, the time of its first slip and of leaving the blade, the damped,
    saturated and limit ticks, where the motion starts and ends, and the first limit event."""
    meta, _, runs = replayed
    discrete = ("ticks", "slipped", "first_slip_time", "left_time", "damped_ticks", "first_damped_time",
                "saturated_ticks", "limit_ticks", "stopped_at_limit")
    slipped = 0
    for name, run in meta["runs"].items():
        log = runs[name]
        got = {k: log.summary[k] for k in discrete}
        assert got == {k: run["summary"][k] for k in discrete}, name
        assert [log.motion_start, log.motion_end] == run["motion"], name
        v, w = log.limit_violation, run["limit_violation"]
        assert (v is None) == (w is None), name
        if w is not None:
            assert (v["tick"], v["joint"], v["quantity"]) == (w["tick"], w["joint"], w["quantity"]), name
        slipped += bool(got["slipped"])
    # the comparison covers both outcomes of the flip
    assert 0 < slipped < len(meta["runs"])


def test_strict_refuses_the_jump_with_the_reference_message(replayed):
    meta, arrays, _ = replayed
    with pytest.raises(LimitExceededError) as e:
        pc.SpatulaArm(settle=0.2).execute(arrays["trajectory_jump"], strict=True)
    assert str(e.value) == meta["strict_jump_message"]


# ---------------------------------------------------------------------------------------------
# the experiment
# ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def reference_runs():
    ref = pc.reference_disturbances()
    return {
        "dob": pc.execute(GENTLE, disturbances=ref, settle=0.5),
        "no_dob": pc.execute(GENTLE, disturbances=ref, settle=0.5, dob=False),
    }


def test_the_settings_are_the_cores_and_the_spatula_is_one_configuration_of_the_loop():
    assert pc.SpatulaSetup is genplan._core.SpatulaSetup and pc.Disturbances is control.Disturbances
    ref = pc.reference_disturbances()
    assert ref.coulomb == [3.0, 3.0, 2.0, 0.4, 0.4, 0.2] and ref.payload == control.Payload(mass=0.3)
    assert pc.PAPER_CONTROLLER == control.ControllerSettings(acceleration_feedforward=False, singular_det=1e-3)
    # task space on the spatula point (tool0 moved 0.1 m along its z axis), every axis servoed
    c = pc.SpatulaArm(settle=0.0).controller
    assert (c.space, c.frame, c.frame_offset, c.axes) == ("task", "tool0", [0.0, 0.0, 0.1], [1.0] * 6)


def test_command_pose_is_eq23_and_lands_on_the_ur5_spatula_frame():
    """The IK start configuration puts Pinocchio's tool0 frame, moved 0.1 m along its z axis,
    exactly at eq. 23's command: the attitude convention and the tool frame as documented."""
    arm = pc.SpatulaArm(settle=0.0)
    robot = genplan.load("ur5")
    data = robot.model.createData()
    fid = robot.model.getFrameId("tool0")
    for p in ([0.0, 0.0, 0.0], [0.1, -0.1, -2.5], [-0.1, 0.1, 3.0]):
        pos, rot = arm.command_pose(p)
        assert np.allclose(pos, [0.5, p[0], p[1] + 0.35])
        expect = pin.utils.rotate("x", p[2]) @ pin.utils.rotate("y", math.pi / 2)
        assert np.allclose(rot, expect, atol=1e-15)
        q0 = arm.check(np.array([p, p]))
        pin.framesForwardKinematics(robot.model, data, q0)
        spatula = data.oMf[fid] * pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1]))
        assert np.allclose(spatula.translation, pos, atol=1e-9)
        assert np.allclose(spatula.rotation, rot, atol=1e-9)
        # blade normal and in-plane direction of the pancake module's theta
        assert np.allclose(-rot[:, 0], [0.0, -math.sin(p[2]), math.cos(p[2])], atol=1e-12)


@pytest.mark.parametrize("y", [-0.3, 0.3])
@pytest.mark.parametrize("z", [-0.3, 0.3])
def test_a_region_three_times_the_papers_is_reachable(y, z):
    """The paper's end poses lie in y, z in [-0.1, 0.1] m, theta in [-pi, pi]; J2 lets the end
    stray 0.2 m and the tail adds a few cm. Moves from the start to corners of +-0.3 m with the
    spatula turned almost upside down either way pass the pre-loop reachability check."""
    arm = pc.SpatulaArm(settle=0.0)
    for theta in (-math.pi + 0.05, math.pi - 0.05):
        q0 = arm.check(s_curve([0.0, 0.0, 0.0], [y, z, theta]))
        assert q0.shape == (6,)


def test_log_shapes_and_phi_of_the_loop_match_the_pancake_function(reference_runs):
    log = reference_runs["dob"]
    n = 500 + 500
    assert log.t.shape == (n,) and log.q.shape == (n, 6) and log.rotation.shape == (n, 3, 3)
    for name in ("p_cmd", "p", "position_cmd", "position"):
        assert getattr(log, name).shape == (n, 3)
    for name in ("tau", "tau_dis_hat", "tau_dis", "acceleration"):
        assert getattr(log, name).shape == (n, 6)
    assert (log.motion_start, log.motion_end) == (500, 1000)
    assert log.jitter is None and log.lateness is None
    # phi of the achieved motion, recomputed in Python from the logged tilt and acceleration
    assert np.allclose(log.phi, phi_py(log.p[:, 2], log.acceleration[:, 1:3], g=9.81), atol=1e-12)
    # logged achieved pose = the command minus the logged error
    assert np.allclose(np.linalg.norm(log.position_cmd - log.position, axis=1), log.error_position)
    assert np.allclose(log.p[:, :2], log.position[:, 1:3] - [0.0, 0.35])


def test_the_dob_halves_the_tracking_error_and_estimates_the_disturbance(reference_runs):
    dob, no = reference_runs["dob"], reference_runs["no_dob"]
    assert dob.max_tracking_error_mm < 10.0
    assert no.max_tracking_error_mm > 1.5 * dob.max_tracking_error_mm
    assert no.max_tracking_error_deg > 1.5 * dob.max_tracking_error_deg
    # at the end of the settle phase the estimate has converged to the (static) disturbance
    k = dob.motion_start - 1
    assert np.allclose(dob.tau_dis_hat[k], dob.tau_dis[k], atol=0.05 * np.abs(dob.tau_dis[k]).max())


def test_gentle_move_keeps_the_pancake_and_the_papers_unadjusted_input_loses_it(reference_runs):
    assert not reference_runs["dob"].slipped
    assert reference_runs["dob"].max_abs_phi_deg < 45.0
    with pytest.warns(control.LimitWarning, match="wrist_3_joint' exceeds its velocity limit"):
        log = pc.execute(LINE, disturbances=pc.reference_disturbances(), settle=0.3, tail=0.1)
    assert log.slipped
    first = log.summary["first_slip_time"] - 0.3
    # constant rotation, no linear acceleration: phi = -theta leaves the cone near theta = -45 deg
    theta_at_slip = -0.75 * math.pi * first / 0.499
    assert -60.0 < math.degrees(theta_at_slip) < -40.0
    assert log.slip[log.motion_start:log.motion_end].any()
    assert log.t.shape == (300 + 500 + 100,)


def test_the_same_move_too_fast_slips():
    fast = s_curve([0.0, 0.0, 0.0], [0.06, 0.02, -0.4], K=120)
    with pytest.warns(control.LimitWarning, match="wrist_3_joint' exceeds its velocity limit"):
        log = pc.execute(fast, settle=0.2)
    assert log.slipped and log.max_abs_phi_deg > 45.0


@pytest.mark.parametrize("bad, error, match", [
    (np.zeros((10, 2)), ShapeError, r"expected shape \(K, 3\)"),
    (np.zeros((1, 3)), ShapeError, r"K >= 2"),
    (np.array([[0.0, 0.0, 0.0], [0.0, np.nan, 0.0]]), NonFiniteError, r"row 1 \(z\) is not finite"),
    (np.linspace([0.0, 0.0, 0.0], [0.9, 0.0, 0.0], 100), GenplanError, r"not reachable"),
])
def test_bad_trajectories_raise_before_the_loop(bad, error, match):
    with pytest.raises(error, match=match):
        pc.execute(bad, settle=0.0)


def test_bad_configuration_raises():
    with pytest.raises(SettingsError, match=r"payload.mass must be finite and in \[0, 100\] kg, got -1"):
        pc.execute(GENTLE, disturbances=control.Disturbances(payload=control.Payload(mass=-1.0)))
    with pytest.raises(SettingsError, match=r"disturbances.coulomb must have 6 values \(one per joint\) or none, got 2"):
        pc.execute(GENTLE, disturbances=control.Disturbances(coulomb=[1.0, 2.0]))
    with pytest.raises(SettingsError, match="ControllerSettings: unknown setting 'kpp'"):
        pc.PAPER_CONTROLLER.replace(kpp=1.0)
    with pytest.raises(SettingsError, match="controller: expected a ControllerSettings"):
        pc.SpatulaArm(controller={"dob": False})
    with pytest.raises(GenplanError, match="6-joint"):
        pc.execute(GENTLE, robot="panda")
    with pytest.raises(SettingsError, match="settle"):
        pc.execute(GENTLE, settle=-1.0)


def test_singularity_mid_run_is_damped_and_reported():
    """Reaching sideways to the edge of the UR5's workspace on its elbow-up branch (y = 0.672 m;
    the branch ends at 0.6727 m, where the elbow is straight): the task Jacobian becomes
    singular, the inverse is damped, the run completes and reports the damped ticks (and the
    elbow's speed just over its rated 3.15 rad/s near the singularity)."""
    arm = pc.SpatulaArm(settle=0.0, controller=pc.PAPER_CONTROLLER.replace(singular_det=1e-2))
    traj = s_curve([0.6, 0.0, 0.0], [0.672, 0.0, 0.0])
    with pytest.warns(control.LimitWarning, match="'elbow_joint' exceeds its velocity limit"):
        log = arm.execute(traj)
    s = log.summary
    assert s["min_abs_det_j"] < 1e-3
    assert s["damped_ticks"] > 0 and s["first_damped_time"] is not None
    assert log.damped.sum() == s["damped_ticks"]
    assert np.all(np.isfinite(log.tau)) and np.all(np.isfinite(log.q))
    assert log.max_tracking_error_mm < 10.0
    # one step further along the same branch is out of reach: refused before the loop
    with pytest.raises(GenplanError, match="not reachable"):
        arm.execute(s_curve([0.6, 0.0, 0.0], [0.7, 0.0, 0.0]))


def test_paced_mode_reports_jitter():
    traj = s_curve([0.0, 0.0, 0.0], [0.01, 0.0, -0.1], K=100)
    log = pc.execute(traj, settle=0.0, paced=True)
    j = log.jitter
    assert j is not None and {"lateness_p50_us", "lateness_p99_us", "lateness_max_us", "overruns"} <= set(j)
    assert log.lateness.shape == (100,) and np.all(log.lateness >= 0)
    assert j["lateness_p50_us"] <= j["lateness_p99_us"] <= j["lateness_max_us"]
    assert log.us_per_tick >= 990.0  # paced: one tick per millisecond of wall time


def test_deceleration_tail():
    x = np.linspace([0.0, 0.0, 0.0], [0.1, -0.05, -2.0], 500)
    v = (x[-1] - x[-2]) / 1e-3
    out = pc.deceleration_tail(x, 0.1)
    assert out.shape == (600, 3) and np.array_equal(out[:500], x)
    vel = np.diff(out, axis=0) / 1e-3
    assert np.allclose(vel[499:], v * (1 - (np.arange(100) + 0.5) / 100)[:, None], atol=1e-9)
    assert np.allclose(out[-1], x[-1] + v * 0.05)
    assert np.array_equal(pc.deceleration_tail(x, 0.0), x)
    with pytest.raises(SettingsError, match="duration"):
        pc.deceleration_tail(x, -0.1)


# ---------------------------------------------------------------------------------------------
# settings and joint limits
# ---------------------------------------------------------------------------------------------

C, D, S, P = control.ControllerSettings, control.Disturbances, pc.SpatulaSetup, control.Payload


@pytest.mark.parametrize("make, field", [
    (lambda: C(dt=0.0), "controller.dt"),
    (lambda: C(dt=-1e-3), "controller.dt"),
    (lambda: C(dt=math.nan), "controller.dt"),
    (lambda: C(dt=math.inf), "controller.dt"),
    (lambda: C(dob_cutoff_hz=0.0), "controller.dob_cutoff_hz"),
    (lambda: C(dob_cutoff_hz=-2.0), "controller.dob_cutoff_hz"),
    (lambda: C(kp=[-450.0] + [450.0] * 5), "controller.kp"),
    (lambda: C(kv=[60.0] * 5 + [math.nan]), "controller.kv"),
    (lambda: C(max_damping=-0.1), "controller.max_damping"),
    (lambda: P(mass=-0.3), "payload.mass"),
    (lambda: P(mass=101.0), "payload.mass"),
    (lambda: P(mass=math.inf), "payload.mass"),
    (lambda: P(com=[0.0, 0.0, 5.0]), "payload.com"),
    (lambda: D(viscous=[-1.0] * 6), "disturbances.viscous"),
    (lambda: D(friction_velocity=0.0), "disturbances.friction_velocity"),
    (lambda: S(spatula_mass=500.0), "setup.spatula_mass"),
    (lambda: S(spatula_length=-0.1), "setup.spatula_length"),
    (lambda: pc.PancakeSettings(blade_half_length=0.0), "pancake.blade_half_length"),
    (lambda: control.JointLimits(velocity=[3.0] * 5 + [0.0]), "limits.velocity"),
    (lambda: control.JointLimits(velocity=[math.nan] * 6), "limits.velocity"),
])
def test_bad_setting_values_raise_settings_errors_naming_the_field(make, field):
    """Checked once, by the native core, when the setting is made."""
    with pytest.raises(SettingsError, match=rf"^settings: {field.replace('.', r'[.]')} "):
        make()


@pytest.mark.parametrize("kwargs, field", [
    ({"limits": control.JointLimits(torque=[150.0] * 5)}, "limits.torque"),
    ({"disturbances": D(offset=[1.0] * 7)}, "disturbances.offset"),
    ({"setup": S(q_seed=[0.0] * 5)}, "setup.q_seed"),
])
def test_settings_of_the_wrong_length_for_the_arm_name_the_field(kwargs, field):
    with pytest.raises(GenplanError, match=field.replace(".", "[.]")):
        pc.SpatulaArm(**kwargs).check(GENTLE)


def test_a_setting_of_the_wrong_type_names_the_field():
    with pytest.raises(SettingsError, match=r"ControllerSettings\.dt: expected a number, got '1ms'"):
        C(dt="1ms")  # type: ignore[arg-type]


def test_default_joint_limits_are_the_urdfs(ur5):
    """The limits every run is checked against are the URDF's, as Pinocchio reads them."""
    limits = pc.SpatulaArm(settle=0.0).limits
    assert np.array_equal(limits["torque"], ur5.model.effortLimit)
    assert np.array_equal(limits["velocity"], ur5.model.velocityLimit)
    assert limits["torque"].tolist() == [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]
    own = pc.SpatulaArm(settle=0.0, limits=control.JointLimits(velocity=[1.0] * 6, policy="log")).limits
    assert own["velocity"].tolist() == [1.0] * 6 and np.array_equal(own["torque"], ur5.model.effortLimit)


#: the issue's unsafe trajectory: the command jumps 30 cm sideways after 0.2 s
JUMP = np.zeros((400, 3))
JUMP[200:, 0] = 0.3


def test_a_30_cm_jump_is_flagged_and_warned_about():
    with pytest.warns(control.LimitWarning, match="exceeded the arm's joint limits") as record:
        log = pc.execute(JUMP, settle=0.2)
    assert record[0].filename == __file__  # the warning points at the caller
    assert log.exceeded_limits
    v = log.limit_violation
    assert v is not None and v["joint"] == "shoulder_pan_joint" and v["quantity"] == "torque"
    assert v["time"] == pytest.approx(0.4) and v["tick"] == 400 and log.t[v["tick"]] == pytest.approx(v["time"])
    assert abs(v["value"]) > 1e4 and v["limit"] == 150.0 and v["unit"] == "N m"
    assert abs(v["value"]) == pytest.approx(abs(log.tau[v["tick"], 0]))
    assert log.summary["limit_ticks"] > 1 and max(log.summary["max_abs_v"]) > 3.2
    assert v["message"] in str(record[0].message)


def test_strict_refuses_the_jump_naming_the_joint_time_and_limit():
    with pytest.raises(LimitExceededError, match=r"^trajectory refused \(strict=True\): joint 'shoulder_pan_joint' exceeds "
                                                 r"its torque limit at t = 0.400 s: \|torque\| = \d+ N m > 150 N m$"):
        pc.execute(JUMP, settle=0.2, strict=True)
    # a speed limit of one's own, torque unchecked
    limits = control.JointLimits(torque=[math.inf] * 6, velocity=[0.5] * 6, policy="log")
    with pytest.raises(LimitExceededError, match=r"exceeds its velocity limit at t = 0.4\d\d s: .* > 0.500 rad/s"):
        pc.SpatulaArm(settle=0.2, limits=limits).execute(JUMP, strict=True)


def test_a_gentle_move_is_within_the_limits_strict_or_not(reference_runs):
    assert not reference_runs["dob"].exceeded_limits and reference_runs["dob"].limit_violation is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", control.LimitWarning)
        log = pc.execute(GENTLE, settle=0.2, strict=True)
    assert not log.exceeded_limits and log.summary["limit_ticks"] == 0


# ---------------------------------------------------------------------------------------------
# size bounds and inputs (findings CTRL-1 and PY-2 / PY-4 of tests/test_fuzz_inputs.py)
# ---------------------------------------------------------------------------------------------

SHORT = s_curve([0.0, 0.0, 0.0], [0.01, 0.0, 0.0], K=10)


@pytest.mark.parametrize("kwargs, match", [
    ({"tail": 1e9}, r"^tail must be in \[0, 10\] seconds, got 1000000000.0"),
    ({"tail": 1e300}, r"^tail must be in \[0, 10\] seconds"),
    ({"tail": math.inf}, r"^tail must be in \[0, 10\] seconds"),
    ({"tail": -0.1}, r"^tail must be in \[0, 10\] seconds"),
    ({"tail": math.nan}, r"^tail must be in \[0, 10\] seconds"),
    ({"tail": "0.1s"}, r"^tail: cannot be read as a real number"),
    ({"settle": 60.5}, r"^settle must be in \[0, 60\] seconds"),
    ({"settle": 1e300}, r"^settle must be in \[0, 60\] seconds"),
    ({"settle": [1.0]}, r"^settle: expected one number"),
    # within the seconds, over the run's ticks: dt = 1 us makes 10 s of tail 10^7 ticks
    ({"tail": 10.0, "controller": pc.PAPER_CONTROLLER.replace(dt=1e-6)}, r"^tail: 10.0 s at dt = 1e-06 s is 1e\+07 ticks; "
                                                                         r"a run is limited to 10000000 ticks"),
    ({"settle": 30.0, "controller": pc.PAPER_CONTROLLER.replace(dt=1e-6)}, r"^settle: 30.0 s at dt = 1e-06 s is 3e\+07 ticks"),
])
def test_run_lengths_are_bounded_before_anything_is_allocated(kwargs, match):
    """CTRL-1: tail=1e9 asked numpy for 10^12 samples (MemoryError); settle=1e300 overflowed the
    native config's tick count."""
    with pytest.raises(SettingsError, match=match):
        pc.execute(SHORT, **{"settle": 0.0, **kwargs})


def test_the_tail_bound_is_the_documented_one():
    assert pc.MAX_TAIL_S == 10.0 and pc.MAX_SETTLE_S == 60.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.LimitWarning)  # no settle phase: a torque peak at the start
        log = pc.execute(SHORT, settle=0.0, tail=pc.MAX_TAIL_S)  # the bound itself runs
    assert len(log.t) == 10 + 10_000 and log.motion_end == 10
    with pytest.raises(SettingsError, match=r"^duration must be in \[0, 10\] seconds"):
        pc.deceleration_tail(SHORT, 1e9)
    with pytest.raises(SettingsError, match=r"^duration: 1.0 s at dt = 1e-09 s is 1e\+09 ticks"):
        pc.deceleration_tail(SHORT, 1.0, dt=1e-9)


def test_the_run_limit_is_the_native_cores():
    """pc.MAX_TICKS mirrors MAX_TICKS of rust/core/src/control.rs: a settle phase of
    MAX_TICKS - 1 ticks passes the Python check, and the core refuses it with two trajectory rows
    (before any allocation); one tick more is refused in Python, naming settle."""
    dt = 60.0 / (pc.MAX_TICKS - 1)  # 60 s of settle: MAX_TICKS - 1 ticks
    arm = pc.SpatulaArm(settle=60.0, controller=pc.PAPER_CONTROLLER.replace(dt=dt))
    assert arm.settle_ticks == pc.MAX_TICKS - 1
    with pytest.raises(GenplanError, match=rf"^a run is limited to {pc.MAX_TICKS} ticks; got 2 trajectory rows "
                                           rf"\+ {pc.MAX_TICKS - 1} settle ticks"):
        arm.execute(SHORT[:2])
    with pytest.raises(SettingsError, match=rf"^settle: 60.0 s at dt = .* ticks; a run is limited to {pc.MAX_TICKS}"):
        pc.SpatulaArm(settle=60.0, controller=pc.PAPER_CONTROLLER.replace(dt=60.0 / (pc.MAX_TICKS + 1)))


@pytest.mark.parametrize("call, error, match", [
    (lambda: pc.execute([["a", "b", "c"]] * 3, settle=0.0), ShapeError, "^trajectory: cannot be read"),
    (lambda: pc.execute(SHORT + 0j, settle=0.0), ShapeError, "^trajectory: complex numbers"),
    (lambda: pc.execute(SHORT, settle="x"), SettingsError, "^settle: cannot be read"),
    (lambda: pc.SpatulaArm(settle=0.0).command_pose("abc"), ShapeError, "^p: cannot be read"),
    (lambda: pc.SpatulaArm(settle=0.0).spatula_pose(np.zeros(6) + 1j), ShapeError, "^q: complex numbers"),
    (lambda: pc.SpatulaArm(settle=0.0).spatula_pose(np.zeros(5)), ShapeError, r"^q: expected shape \(6,\)"),
    (lambda: pc.deceleration_tail(SHORT, "x"), SettingsError, "^duration: cannot be read"),
    (lambda: pc.deceleration_tail(SHORT, 0.1, dt="x"), SettingsError, "^dt: cannot be read"),
])
def test_values_that_are_not_real_numbers_name_the_argument(call, error, match):
    """PY-2 / PY-4: numpy's ValueError or TypeError, or the imaginary part dropped."""
    with pytest.raises(error, match=match):
        call()
