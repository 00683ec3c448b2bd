"""genplan.control: the 1 kHz loop for any fixed-base robot (genplan.execute).

The settings classes (defined once in Rust: defaults, immutability, errors naming the field), a
joint trajectory followed in joint and task space, the disturbance observer against an unknown
payload and joint friction, resampling of another rate, the log (shapes, save, plot), limits
(the reference's inverse-dynamics torques, saturation, strict), the executed motion checked
against a collision world and a task, continuous joints, Ctrl-C, bad input refused before the
run with typed errors naming the field, the deprecated spatula names, and ``genplan.execute``
exported lazily.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
import warnings

import numpy as np
import pytest

import genplan
from genplan import control
from genplan.control import ControllerSettings, Disturbances, JointLimits, Payload
from genplan.errors import (InvalidTrajectoryError, LimitExceededError, NonFiniteError, SettingsError, ShapeError,
                            UnknownNameError)
from genplan.trajectory import Trajectory
from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency

A = np.array([0.0, -0.4, 0.0, -2.2, 0.0, 1.9, 0.8])
B = np.array([0.6, 0.1, -0.3, -1.7, 0.2, 2.1, 0.4])


def quintic(a: np.ndarray, b: np.ndarray, seconds: float, rate: float = 1000.0) -> Trajectory:
    """A smooth rest-to-rest joint motion (quintic time law) sampled at ``rate``."""
    t = np.arange(int(round(seconds * rate)) + 1) / rate
    s = t / seconds
    p = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
    dp = (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / seconds
    ddp = (60 * s - 180 * s ** 2 + 120 * s ** 3) / seconds ** 2
    d = b - a
    return Trajectory(t=t, q=a + p[:, None] * d, qd=dp[:, None] * d, qdd=ddp[:, None] * d,
                      joint_names=tuple(genplan.load("panda").joint_names), rate_hz=rate, robot="panda")


MOTION = quintic(A, B, 1.0)
#: a 0.6 kg load 10 cm in front of the hand the controller does not know, with friction and offsets
UNKNOWN = Disturbances(coulomb=[1.5] * 4 + [0.3] * 3, viscous=[1.0] * 4 + [0.2] * 3,
                       offset=[0.8, -0.8, 0.6, -0.6, 0.15, -0.15, 0.1],
                       payload=Payload(mass=0.6, com=[0.0, 0.0, 0.1], link="panda_hand"))


# ---------------------------------------------------------------------------------------------
# settings
# ---------------------------------------------------------------------------------------------

def test_settings_are_typed_immutable_and_defined_once():
    c = ControllerSettings()
    assert c.kp == [450.0] * 3 + [700.0] * 3 and c.kv == [60.0] * 3 + [90.0] * 3  # the paper's
    assert c.dob and c.dob_cutoff_hz == 2.0 and c.dt == 1e-3 and c.acceleration_feedforward
    assert not ControllerSettings.paper().acceleration_feedforward
    assert ControllerSettings.paper().replace(acceleration_feedforward=True, singular_det=1e-2) == c
    with pytest.raises(AttributeError):
        c.dt = 2e-3  # type: ignore[misc]
    assert pickle.loads(pickle.dumps(c)) == c
    d = Disturbances(payload=Payload(mass=0.6))
    assert d.payload == Payload(mass=0.6) and d.payload.link is None
    assert pickle.loads(pickle.dumps(d)) == d
    assert JointLimits().policy == "saturate" and JointLimits(policy="stop").policy == "stop"
    assert set(ControllerSettings.fields) >= {"space", "frame", "axes", "kp", "kv", "joint_kp", "posture_kp", "dob"}


@pytest.mark.parametrize("make, match", [
    (lambda: ControllerSettings(dt=0.0), r"^settings: controller\.dt must be finite and > 0"),
    (lambda: ControllerSettings(dt="1ms"), r"^ControllerSettings\.dt: expected a number, got '1ms'"),
    (lambda: ControllerSettings(kp=[1.0] * 5), r"^ControllerSettings\.kp: expected 6 numbers, got 5"),
    (lambda: ControllerSettings(kv=[60.0] * 5 + [-1.0]), r"controller\.kv element 5 must be >= 0"),
    (lambda: ControllerSettings(axes=[1, 1, 1, 1, 1, 0.5]), r"controller\.axes element 5 must be 0 \(free\) or 1"),
    (lambda: ControllerSettings(space="cartesian"), r"ControllerSettings\.space: expected one of 'joint', 'task'"),
    (lambda: ControllerSettings(kq=1.0), r"ControllerSettings: unknown setting 'kq'"),
    (lambda: Disturbances(coulomb=[-1.0]), r"disturbances\.coulomb element 0 must be >= 0"),
    (lambda: Disturbances(payload=1.0), r"Disturbances\.payload: expected a Payload or None"),
    (lambda: Payload(mass=-0.1), r"payload\.mass must be finite and in \[0, 100\] kg"),
    (lambda: Payload(inertia=[[1, 2, 0], [0, 1, 0], [0, 0, 1]]), r"payload\.inertia must be symmetric"),
    (lambda: Payload(inertia=np.eye(2)), r"Payload\.inertia\[0\]: expected 3 numbers"),
    (lambda: JointLimits(policy="clip"), r"JointLimits\.policy: expected one of 'log', 'saturate', 'stop'"),
    (lambda: JointLimits(torque=[0.0]), r"limits\.torque element 0 must be > 0"),
])
def test_bad_settings_are_settings_errors_naming_the_field(make, match):
    with pytest.raises(SettingsError, match=match):
        make()


# ---------------------------------------------------------------------------------------------
# execution
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("space", ["joint", "task"])
def test_a_joint_trajectory_is_followed_in_joint_and_task_space(panda, space):
    log = control.execute(panda, MOTION, controller=ControllerSettings(space=space, frame="hand"), settle=0.2)
    n = 200 + len(MOTION)
    assert log.t.shape == (n,) and log.q.shape == (n, 7) and log.error_joint.shape == (n, 7)
    assert log.rotation.shape == (n, 3, 3) and log.tau_dis_hat.shape == (n, 7) and log.compute.shape == (n,)
    assert (log.motion_start, log.motion_end) == (200, n)
    # the nominal model is the plant: with the feed-forward, what is left is the zero-order hold
    # of the torque over a tick (the reference's acceleration changes within it)
    # (in task space the joints follow their reference through the weaker null-space posture term)
    assert log.max_tracking_error_mm < 0.05 and log.max_joint_error < (1e-4 if space == "joint" else 1e-3)
    assert log.executable and not log.exceeded_limits and log.summary["saturated_ticks"] == 0
    # the tool frame is the hand's, where the plan puts it
    hand = panda.link_poses(log.q_ref[-1], ["panda_hand"])[0]
    assert np.allclose(log.position_cmd[-1], hand[:3, 3], atol=1e-12)
    assert log.meta["frame"] == "panda_hand" and log.realtime_factor > 1.0


def test_the_dob_cuts_the_tool_error_of_an_unknown_load_and_friction_by_three(panda):
    with_dob = control.execute(panda, MOTION, controller=ControllerSettings(frame="hand"), disturbances=UNKNOWN)
    without = control.execute(panda, MOTION, controller=ControllerSettings(frame="hand", dob=False), disturbances=UNKNOWN)
    assert without.max_tracking_error_mm > 3.0 * with_dob.max_tracking_error_mm, \
        (with_dob.max_tracking_error_mm, without.max_tracking_error_mm)
    assert without.max_tracking_error_deg > 3.0 * with_dob.max_tracking_error_deg
    # the estimate converged in the settle phase: nothing left unexplained at rest
    k = with_dob.motion_start - 1
    assert np.allclose(with_dob.tau_dis_hat[k], with_dob.tau_dis[k], atol=0.02 * np.abs(with_dob.tau_dis[k]).max())
    # a load the controller knows is compensated by its model instead
    known = control.execute(panda, MOTION, controller=ControllerSettings(frame="hand", dob=False),
                            payload=UNKNOWN.payload.replace(link="hand"))  # a role works as the link
    assert known.max_tracking_error_mm < 0.05 and known.meta["payloads"][0]["link"] == "panda_hand"


def test_another_rate_is_resampled_and_the_same_rate_used_as_it_is(panda):
    coarse = quintic(A, B, 1.0, rate=100.0)
    t, q, qd, qdd = control.joint_reference(panda, coarse, 1e-3)
    assert len(t) == 1001 and np.isclose(t[-1], 1.0)
    # Hermite through the samples' velocities: exact at the samples, close to the motion between
    assert np.allclose(q[::10], coarse.q, atol=1e-12)
    assert np.allclose(q, MOTION.q, atol=2e-5) and np.allclose(qd, MOTION.qd, atol=2e-3)
    t2, q2, qd2, qdd2 = control.joint_reference(panda, MOTION, 1e-3)
    assert q2 is MOTION.q and qdd2 is MOTION.qdd
    # (t, q) arrays alone: a clamped spline (at rest at both ends)
    t3, q3, qd3, _ = control.joint_reference(panda, (coarse.t, coarse.q), 1e-3)
    assert np.allclose(qd3[0], 0.0) and np.allclose(q3[-1], B)
    log = control.execute(panda, coarse, settle=0.0)
    assert len(log.t) == 1001 and log.max_joint_error < 1e-3


def test_the_log_is_saved_atomically_and_plotted(panda, tmp_path):
    log = control.execute(panda, MOTION, disturbances=UNKNOWN, settle=0.1)
    path = log.save(tmp_path / "log.npz")
    with np.load(path) as z:
        assert np.array_equal(z["tau"], log.tau) and np.array_equal(z["error_position"], log.error_position)
        import json

        meta = json.loads(str(z["meta"]))
    assert meta["summary"]["max_error_position"] == log.summary["max_error_position"]
    assert meta["robot"] == "panda" and meta["disturbances"]["payload"]["mass"] == 0.6
    assert [p.name for p in tmp_path.iterdir()] == ["log.npz"]  # no temporary left
    png = log.plot(tmp_path / "log.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(UnknownNameError, match=r"path: a log is written as \.npz"):
        log.save(tmp_path / "log.json")


# ---------------------------------------------------------------------------------------------
# limits, collisions, the task
# ---------------------------------------------------------------------------------------------

def test_limits_reference_torques_saturation_and_strict(panda):
    # limits 20 % over the reference's own inverse-dynamics torques: it fits, an unknown load does not
    dyn = genplan._core.Dynamics.from_description(panda.description)
    needed = np.max([np.abs(dyn.rnea(q, qd, qdd)) for q, qd, qdd in zip(MOTION.q, MOTION.qd, MOTION.qdd)], axis=0)
    weak = JointLimits(torque=(1.2 * needed + 1.0).tolist())
    heavy = Disturbances(payload=Payload(mass=3.0))
    with pytest.warns(control.LimitWarning, match="exceeded the joint limits"):
        log = control.execute(panda, MOTION, disturbances=heavy, limits=weak, settle=0.2)
    assert log.reference_over is None and log.reference_torque_ratio < 1.0
    assert log.summary["saturated_ticks"] > 0 and np.all(np.abs(log.tau) <= weak.torque)
    assert log.summary["max_torque_ratio"] > 1.0 and not log.executable
    with pytest.warns(control.LimitWarning, match=r"exceeded the joint limits in \d+ ticks \(log\)"):
        log = control.execute(panda, MOTION, disturbances=heavy, limits=weak.replace(policy="log"), settle=0.2)
    assert log.summary["saturated_ticks"] == 0 and np.any(np.abs(log.tau) > weak.torque)
    with pytest.raises(LimitExceededError, match=r"^run stopped \(strict=True\): joint '.*' exceeds its torque limit"):
        control.execute(panda, MOTION, disturbances=heavy, limits=weak, settle=0.2, strict=True)
    # a reference that needs more torque than the limits: warned, or refused before the run
    tiny = JointLimits(torque=(0.5 * needed + 0.1).tolist(), policy="log")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = control.execute(panda, MOTION, limits=tiny, settle=0.0)
    messages = [str(w.message) for w in caught if issubclass(w.category, control.LimitWarning)]
    assert messages[0].startswith("the trajectory's inverse-dynamics torques exceed the torque limits")
    assert messages[1].startswith("the run exceeded the joint limits")
    assert log.reference_over is not None and log.reference_torque_ratio > 1.0 and not log.executable
    with pytest.raises(LimitExceededError, match=r"^trajectory refused \(strict=True\): its inverse-dynamics torques"):
        control.execute(panda, MOTION, limits=tiny, strict=True)


def test_the_executed_motion_is_checked_against_the_scene_and_the_task(panda):
    world = panda.collision_world()
    hand = panda.link_poses(MOTION.q[500], ["panda_hand"])[0][:3, 3]
    world.add_box("in_the_way", [0.05, 0.05, 0.05], hand)
    with pytest.warns(control.CollisionWarning, match="the executed motion collides at t = "):
        log = control.execute(panda, MOTION, world=world, settle=0.0)
    assert log.collided and log.in_collision[500] and not log.executable
    # the Panda task (hand level, yaw free): this motion turns the hand, so its residual is large
    log = control.execute(panda, MOTION, task="panda_projection", settle=0.0)
    assert set(log.residuals) == set(log.tolerances) and not log.within_tolerance


def test_continuous_joints_are_executed_on_their_circle():
    kinova = genplan.load("kinova")
    assert kinova.nq > kinova.nv
    rng = np.random.default_rng(0)
    q0 = kinova.random_configurations(1, rng)[0]
    t = np.linspace(0.0, 2.0, 21)
    x = control.joint_values(kinova, np.vstack([q0, q0]))[0]
    angles = x + 0.1 * np.sin(np.pi * t / 2.0)[:, None] * (np.arange(kinova.nv) % 2)
    q = control.from_joint_values(kinova, angles)
    log = control.execute(kinova, (t, q), settle=0.1)
    circles = [np.hypot(log.q[:, i], log.q[:, i + 1]) for i in kinova.continuous]
    assert np.allclose(circles, 1.0, atol=1e-12)
    assert log.max_joint_error < 1e-4 and log.error_joint.shape == (len(log.t), kinova.nv)


def test_ctrl_c_interrupts_a_long_run(panda):
    long = quintic(A, B, 60.0)
    assert ctrl_c_latency(lambda: control.execute(panda, long, settle=0.0)) < MAX_LATENCY_S


# ---------------------------------------------------------------------------------------------
# bad input: typed errors naming the field, before the run
# ---------------------------------------------------------------------------------------------

def jump() -> Trajectory:
    q = MOTION.q.copy()
    q[400:, 1] += 0.05  # 0.05 rad in one tick: 50 rad/s
    return MOTION.replace(q=q)


@pytest.mark.parametrize("args, kwargs, error, match", [
    ((np.linspace(0, 1, 5), np.zeros((5, 6))), {}, ShapeError, r"^trajectory\.q: expected shape \(7,\) or \(n, 7\)"),
    ((np.linspace(0, 1, 5), np.full((5, 7), np.nan)), {}, NonFiniteError, r"^trajectory\.q: element \(0, 0\)"),
    ((np.array([0.0, 0.2, 0.1]), np.zeros((3, 7))), {}, ShapeError, r"^trajectory\.t: times must increase"),
    ("jump", {}, InvalidTrajectoryError, r"^trajectory\.q: sample 400 \(t = 0\.400 s\): joint 'panda_joint2' moves "
                                        r"0\.05\d* in one tick .* cannot follow"),
    ("motion", {"controller": ControllerSettings(frame="flange")}, UnknownNameError,
     r"^controller\.frame: robot 'panda' has no frame 'flange'"),
    ("motion", {"payload": Payload(mass=1.0, link="gripper")}, UnknownNameError, r"^payload\.link: robot 'panda'"),
    ("motion", {"controller": {"dt": 1e-3}}, SettingsError, r"^controller: expected a ControllerSettings"),
    ("motion", {"settle": 61.0}, SettingsError, r"^settle must be in \[0, 60\] seconds"),
    ("motion", {"dt": -1.0}, SettingsError, r"controller\.dt must be finite and > 0"),
    ("other_robot", {}, ShapeError, r"^trajectory: made for the joints \['shoulder_pan_joint'"),
    ("outside", {}, InvalidTrajectoryError, r"^trajectory\.q: sample 0 \(t = 0\.000 s\): joint 'panda_joint4' at "
                                           r"0\.5\d* is outside its range"),
])
def test_bad_input_is_refused_before_the_run(panda, ur5, args, kwargs, error, match):
    if args == "jump":
        traj = jump()
    elif args == "motion":
        traj = MOTION
    elif args == "other_robot":
        traj = MOTION.replace(joint_names=tuple(ur5.joint_names))
    elif args == "outside":
        q = MOTION.q.copy()
        q[:, 3] = 0.5
        traj = MOTION.replace(q=q)
    else:
        traj = args
    with pytest.raises(error, match=match):
        control.execute(panda, traj, **kwargs)


def test_a_floating_base_robot_is_refused(talos):
    with pytest.raises(genplan.errors.GenplanError, match="floating base"):
        control.execute(talos, (np.zeros(1), np.zeros((1, talos.nq))))


# ---------------------------------------------------------------------------------------------
# the API around it
# ---------------------------------------------------------------------------------------------

def test_genplan_execute_is_exported_lazily():
    code = ("import sys, genplan; assert 'genplan.control' not in sys.modules; "
            "from genplan import execute; import genplan.control as c; assert execute is c.execute")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_spatula_names_here_are_deprecated_aliases():
    from genplan.pancake import control as pc
    from genplan.pancake.trajectories import s_curve

    with pytest.warns(DeprecationWarning, match="use genplan.pancake.control.SpatulaArm"):
        assert control.SpatulaArm is pc.SpatulaArm
    with pytest.warns(DeprecationWarning, match=r"reference\(\) is deprecated"):
        ref = control.Disturbances.reference()
    assert ref == pc.reference_disturbances()
    with pytest.warns(DeprecationWarning, match="ControllerSettings"):
        config = control.ControllerConfig(dob=False, gains=control.Gains(kpp=400.0))
    assert config == pc.PAPER_CONTROLLER.replace(dob=False, kp=[400.0] * 3 + [700.0] * 3)
    with pytest.warns(DeprecationWarning, match="genplan.pancake.control.execute"):
        log = control.execute(s_curve([0, 0, 0], [0.06, 0.02, -0.4]), settle=0.2)
    assert isinstance(log, pc.SpatulaLog) and not log.slipped


def test_integrity_rerun_a_run_too_long_to_log_is_refused_before_allocating(panda, monkeypatch):
    """A 9000 s trajectory made a log of 10 GB (and aborted the interpreter under a memory
    limit): the log's size (genplan._execution.log_bytes, exact for every array of a run) and the
    reference's are bounded by MAX_RUN_BYTES before the run; a longer run is a SettingsError
    naming the trajectory's duration and the bound, raised before the reference or the native
    simulation is made."""
    import genplan._execution as E

    log = control.execute(panda, MOTION, settle=0.1)
    arrays = [getattr(log, k) for k in E.ARRAYS if getattr(log, k, None) is not None]
    in_collision = len(log.t)  # one flag per tick with a world
    assert sum(a.nbytes for a in arrays) + in_collision == E.log_bytes(len(log.t), panda.nq, panda.nv)
    assert control.MAX_RUN_BYTES == E.MAX_RUN_BYTES == 2**30

    def no_run(*args, **kwargs):
        pytest.fail("the run started")

    monkeypatch.setattr(control._core, "Simulation", no_run)
    q0 = panda.q_default
    with pytest.raises(SettingsError, match=r"^trajectory: 9000 s at dt = 0\.001 s and a settle phase of 500 ticks is "
                                            r"9000501 ticks, whose log and reference take 7\.\d\d GiB, more than the "
                                            r"1\.00 GiB a run may take"):
        control.execute(panda, (np.array([0.0, 9000.0]), np.array([q0, q0])))
    longest = E.MAX_RUN_BYTES // E.run_bytes(1, panda.nq, panda.nv)
    with pytest.raises(SettingsError, match=r"more than the 1\.00 GiB"):  # one tick beyond the bound
        control.joint_reference(panda, (np.array([0.0, longest * 1e-3]), np.array([q0, q0])), 1e-3)
    t, *_ = control.joint_reference(panda, (np.array([0.0, (longest - 1) * 1e-3]), np.array([q0, q0])), 1e-3)
    assert len(t) == longest  # at the bound: made
