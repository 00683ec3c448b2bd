"""genplan.control: the 1 kHz spatula controller on the simulated UR5 (Rust loop).

Conventions cross-checked with Pinocchio (the commanded pose is where Pinocchio puts the spatula
at the initial configuration), phi of the loop against the pancake module's function, defaults
of the typed Python API against the Rust core's, slip verdicts, the DOB's effect, input errors,
paced mode, and the deceleration tail.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core, control
from genplan.errors import GenplanError, LimitExceededError, NonFiniteError, SettingsError, ShapeError
from genplan.pancake.trajectories import phi as phi_py
from genplan.pancake.trajectories import s_curve

GENTLE = s_curve([0.0, 0.0, 0.0], [0.06, 0.02, -0.4])
#: the paper's unadjusted J2 input (Section 5.2): constant velocity to [0, 0, -3 pi / 4] in 0.5 s
LINE = np.linspace([0.0, 0.0, 0.0], [0.0, 0.0, -0.75 * math.pi], 500)


@pytest.fixture(scope="module")
def reference_runs():
    ref = control.Disturbances.reference()
    return {
        "dob": control.execute(GENTLE, disturbances=ref, settle=0.5),
        "no_dob": control.execute(GENTLE, disturbances=ref, settle=0.5, dob=False),
    }


def test_python_defaults_are_the_rust_defaults():
    defaults, reference = _core.spatula_defaults()
    cfg = control._config(None, None, None, None, substeps=1, settle_ticks=0)
    assert cfg == defaults
    assert dataclasses.asdict(control.Disturbances.reference()) == reference


def test_command_pose_is_eq23_and_lands_on_the_ur5_spatula_frame():
    """The IK start configuration puts Pinocchio's tool0 frame, moved 0.1 m along its z axis,
    exactly at eq. 23's command: the attitude convention and the tool frame as documented."""
    arm = control.SpatulaArm(settle=0.0)
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
    arm = control.SpatulaArm(settle=0.0)
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
        log = control.execute(LINE, disturbances=control.Disturbances.reference(), settle=0.3, tail=0.1)
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
        log = control.execute(fast, settle=0.2)
    assert log.slipped and log.max_abs_phi_deg > 45.0


@pytest.mark.parametrize("bad, error, match", [
    (np.zeros((10, 2)), ShapeError, r"expected shape \(K, 3\)"),
    (np.zeros((1, 3)), ShapeError, r"K >= 2"),
    (np.array([[0.0, 0.0, 0.0], [0.0, np.nan, 0.0]]), NonFiniteError, r"row 1 \(z\) is not finite"),
    (np.linspace([0.0, 0.0, 0.0], [0.9, 0.0, 0.0], 100), GenplanError, r"not reachable"),
])
def test_bad_trajectories_raise_before_the_loop(bad, error, match):
    with pytest.raises(error, match=match):
        control.execute(bad, settle=0.0)


def test_bad_configuration_raises():
    with pytest.raises(SettingsError, match=r"disturbances.payload_mass must be finite and in \[0, 100\] kg, got -1"):
        control.execute(GENTLE, disturbances=control.Disturbances(payload_mass=-1.0))
    with pytest.raises(SettingsError, match="disturbances.coulomb must have length 6, got 2"):
        control.execute(GENTLE, disturbances=control.Disturbances(coulomb=[1.0, 2.0]))
    with pytest.raises(SettingsError, match="unknown key 'kp'"):
        _core.SpatulaSimulation(genplan.load("ur5").description, {"controller": {"kp": 1.0}})
    with pytest.raises(GenplanError, match="6-joint"):
        control.execute(GENTLE, robot="panda")
    with pytest.raises(SettingsError, match="settle"):
        control.execute(GENTLE, settle=-1.0)


def test_singularity_mid_run_is_damped_and_reported():
    """Reaching sideways to the edge of the UR5's workspace on its elbow-up branch (y = 0.672 m;
    the branch ends at 0.6727 m, where the elbow is straight): the task Jacobian becomes
    singular, the inverse is damped, the run completes and reports the damped ticks (and the
    elbow's speed just over its rated 3.15 rad/s near the singularity)."""
    arm = control.SpatulaArm(settle=0.0, controller=control.ControllerConfig(singular_det=1e-2))
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
    log = control.execute(traj, settle=0.0, paced=True)
    j = log.jitter
    assert j is not None and {"lateness_p50_us", "lateness_p99_us", "lateness_max_us", "overruns"} <= set(j)
    assert log.lateness.shape == (100,) and np.all(log.lateness >= 0)
    assert j["lateness_p50_us"] <= j["lateness_p99_us"] <= j["lateness_max_us"]
    assert log.us_per_tick >= 990.0  # paced: one tick per millisecond of wall time


def test_deceleration_tail():
    x = np.linspace([0.0, 0.0, 0.0], [0.1, -0.05, -2.0], 500)
    v = (x[-1] - x[-2]) / 1e-3
    out = control.deceleration_tail(x, 0.1)
    assert out.shape == (600, 3) and np.array_equal(out[:500], x)
    vel = np.diff(out, axis=0) / 1e-3
    assert np.allclose(vel[499:], v * (1 - (np.arange(100) + 0.5) / 100)[:, None], atol=1e-9)
    assert np.allclose(out[-1], x[-1] + v * 0.05)
    assert np.array_equal(control.deceleration_tail(x, 0.0), x)
    with pytest.raises(SettingsError, match="duration"):
        control.deceleration_tail(x, -0.1)


# ---------------------------------------------------------------------------------------------
# configuration values and joint limits (issue [hardening], kind 6)
# ---------------------------------------------------------------------------------------------

C, D, S = control.ControllerConfig, control.Disturbances, control.SpatulaSetup


@pytest.mark.parametrize("kwargs, field", [
    ({"controller": C(dt=0.0)}, "controller.dt"),
    ({"controller": C(dt=-1e-3)}, "controller.dt"),
    ({"controller": C(dt=math.nan)}, "controller.dt"),
    ({"controller": C(dt=math.inf)}, "controller.dt"),
    ({"controller": C(dob_cutoff_hz=0.0)}, "controller.dob_cutoff_hz"),
    ({"controller": C(dob_cutoff_hz=-2.0)}, "controller.dob_cutoff_hz"),
    ({"controller": C(gains=control.Gains(kpp=-450.0))}, "controller.gains.kpp"),
    ({"controller": C(gains=control.Gains(kvr=math.nan))}, "controller.gains.kvr"),
    ({"controller": C(max_damping=-0.1)}, "controller.max_damping"),
    ({"controller": C(torque_limit=[100.0] * 5 + [-1.0])}, "controller.torque_limit"),
    ({"disturbances": D(payload_mass=-0.3)}, "disturbances.payload_mass"),
    ({"disturbances": D(payload_mass=101.0)}, "disturbances.payload_mass"),
    ({"disturbances": D(payload_mass=math.inf)}, "disturbances.payload_mass"),
    ({"disturbances": D(payload_com=[0.0, 0.0, 5.0])}, "disturbances.payload_com"),
    ({"disturbances": D(viscous=[-1.0] * 6)}, "disturbances.viscous"),
    ({"disturbances": D(friction_velocity=0.0)}, "disturbances.friction_velocity"),
    ({"setup": S(spatula_mass=500.0)}, "setup.spatula_mass"),
    ({"setup": S(spatula_length=-0.1)}, "setup.spatula_length"),
    ({"pancake": control.PancakeConfig(blade_half_length=0.0)}, "pancake.blade_half_length"),
    ({"limits": control.JointLimits(torque=[150.0] * 5)}, "limits.torque"),
    ({"limits": control.JointLimits(velocity=[3.0] * 5 + [0.0])}, "limits.velocity"),
    ({"limits": control.JointLimits(velocity=[math.nan] * 6)}, "limits.velocity"),
])
def test_bad_configuration_values_raise_settings_errors_naming_the_field(kwargs, field):
    """Checked once, by the native core, before anything runs (SpatulaArm's constructor)."""
    with pytest.raises(SettingsError, match=rf"^settings: {field.replace('.', r'[.]')} "):
        control.SpatulaArm(**kwargs)
    with pytest.raises(SettingsError, match=field.replace(".", "[.]")):
        control.execute(GENTLE, **kwargs)


def test_a_config_value_of_the_wrong_type_names_the_field():
    with pytest.raises(SettingsError, match="config.controller: 'dt'"):
        control.SpatulaArm(controller=C(dt="1ms"))  # type: ignore[arg-type]


def test_default_joint_limits_are_the_urdfs(ur5):
    """The limits every run is checked against are the URDF's, as Pinocchio reads them."""
    limits = control.SpatulaArm(settle=0.0).limits
    assert np.array_equal(limits["torque"], ur5.model.effortLimit)
    assert np.array_equal(limits["velocity"], ur5.model.velocityLimit)
    assert limits["torque"].tolist() == [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]
    own = control.SpatulaArm(settle=0.0, limits=control.JointLimits(velocity=[1.0] * 6)).limits
    assert own["velocity"].tolist() == [1.0] * 6 and np.array_equal(own["torque"], ur5.model.effortLimit)


#: the issue's unsafe trajectory: the command jumps 30 cm sideways after 0.2 s
JUMP = np.zeros((400, 3))
JUMP[200:, 0] = 0.3


def test_a_30_cm_jump_is_flagged_and_warned_about():
    with pytest.warns(control.LimitWarning, match="exceeded the arm's joint limits") as record:
        log = control.execute(JUMP, settle=0.2)
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
        control.execute(JUMP, settle=0.2, strict=True)
    # a speed limit of one's own, torque unchecked
    limits = control.JointLimits(torque=[math.inf] * 6, velocity=[0.5] * 6)
    with pytest.raises(LimitExceededError, match=r"exceeds its velocity limit at t = 0.4\d\d s: .* > 0.500 rad/s"):
        control.SpatulaArm(settle=0.2, limits=limits).execute(JUMP, strict=True)


def test_a_gentle_move_is_within_the_limits_strict_or_not(reference_runs):
    assert not reference_runs["dob"].exceeded_limits and reference_runs["dob"].limit_violation is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", control.LimitWarning)
        log = control.execute(GENTLE, settle=0.2, strict=True)
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
    ({"tail": 10.0, "controller": control.ControllerConfig(dt=1e-6)}, r"^tail: 10.0 s at dt = 1e-06 s is 1e\+07 ticks; "
                                                                      r"a run is limited to 10000000 ticks"),
    ({"settle": 30.0, "controller": control.ControllerConfig(dt=1e-6)}, r"^settle: 30.0 s at dt = 1e-06 s is 3e\+07 ticks"),
])
def test_run_lengths_are_bounded_before_anything_is_allocated(kwargs, match):
    """CTRL-1: tail=1e9 asked numpy for 10^12 samples (MemoryError); settle=1e300 overflowed the
    native config's tick count."""
    with pytest.raises(SettingsError, match=match):
        control.execute(SHORT, **{"settle": 0.0, **kwargs})


def test_the_tail_bound_is_the_documented_one():
    assert control.MAX_TAIL_S == 10.0 and control.MAX_SETTLE_S == 60.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", control.LimitWarning)  # no settle phase: a torque peak at the start
        log = control.execute(SHORT, settle=0.0, tail=control.MAX_TAIL_S)  # the bound itself runs
    assert len(log.t) == 10 + 10_000 and log.motion_end == 10
    with pytest.raises(SettingsError, match=r"^duration must be in \[0, 10\] seconds"):
        control.deceleration_tail(SHORT, 1e9)
    with pytest.raises(SettingsError, match=r"^duration: 1.0 s at dt = 1e-09 s is 1e\+09 ticks"):
        control.deceleration_tail(SHORT, 1.0, dt=1e-9)


def test_the_run_limit_is_the_native_cores():
    """control.MAX_TICKS mirrors MAX_TICKS of rust/core/src/control.rs: a settle phase of
    MAX_TICKS - 1 ticks passes the Python check, and the core refuses it with two trajectory rows
    (before any allocation); one tick more is refused in Python, naming settle."""
    dt = 60.0 / (control.MAX_TICKS - 1)  # 60 s of settle: MAX_TICKS - 1 ticks
    arm = control.SpatulaArm(settle=60.0, controller=control.ControllerConfig(dt=dt))
    assert arm.config["settle_ticks"] == control.MAX_TICKS - 1
    with pytest.raises(GenplanError, match=rf"^a run is limited to {control.MAX_TICKS} ticks; got 2 trajectory rows "
                                           rf"\+ {control.MAX_TICKS - 1} settle ticks"):
        arm.execute(SHORT[:2])
    with pytest.raises(SettingsError, match=rf"^settle: 60.0 s at dt = .* ticks; a run is limited to {control.MAX_TICKS}"):
        control.SpatulaArm(settle=60.0, controller=control.ControllerConfig(dt=60.0 / (control.MAX_TICKS + 1)))


@pytest.mark.parametrize("call, error, match", [
    (lambda: control.execute([["a", "b", "c"]] * 3, settle=0.0), ShapeError, "^trajectory: cannot be read"),
    (lambda: control.execute(SHORT + 0j, settle=0.0), ShapeError, "^trajectory: complex numbers"),
    (lambda: control.execute(SHORT, settle="x"), SettingsError, "^settle: cannot be read"),
    (lambda: control.SpatulaArm(settle=0.0).command_pose("abc"), ShapeError, "^p: cannot be read"),
    (lambda: control.SpatulaArm(settle=0.0).spatula_pose(np.zeros(6) + 1j), ShapeError, "^q: complex numbers"),
    (lambda: control.SpatulaArm(settle=0.0).spatula_pose(np.zeros(5)), ShapeError, r"^q: expected shape \(6,\)"),
    (lambda: control.deceleration_tail(SHORT, "x"), SettingsError, "^duration: cannot be read"),
    (lambda: control.deceleration_tail(SHORT, 0.1, dt="x"), SettingsError, "^dt: cannot be read"),
])
def test_values_that_are_not_real_numbers_name_the_argument(call, error, match):
    """PY-2 / PY-4: numpy's ValueError or TypeError, or the imaginary part dropped."""
    with pytest.raises(error, match=match):
        call()
