"""genplan.samplers.flow: the conditional flow-matching sampler (training, files, native twin, use in
planning and IK through the GAN's entry points)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import genplan
from genplan import _core
from genplan.errors import GenplanError, ModelFileError, SettingsError
from genplan.planning import Planner, environment, make_sampler
from genplan.samplers.flow import FlowConfig, FlowModel, FlowNet, default_config, distill, load_flow, train
from genplan.samplers.loading import load_sampler_model as load_model
from genplan.samplers.sampler import GanSampler

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


@pytest.fixture(scope="module")
def tiny_flow(tmp_path_factory) -> FlowModel:
    cache = tmp_path_factory.mktemp("cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("GENPLAN_CACHE", str(cache))
    cfg = default_config("panda", iterations=40, data_size=400, hidden=(32, 32), steps=3, cost_batch=16, seed=2)
    model = train(cfg, progress=False)
    mp.undo()
    return model


def test_training_writes_a_card_and_the_file_loads_as_the_same_model(tiny_flow, panda, tmp_path) -> None:
    log = tiny_flow.card["training"]["loss_log"]
    assert log[0]["iteration"] == 0 and log[-1]["iteration"] == 39
    assert all(np.isfinite(e["flow_matching"]) and e["constraint"] > 0 for e in log)  # cost terms were on
    weights, card = tiny_flow.save(tmp_path / "f.safetensors")
    assert json.loads(card.read_text())["format"] == "genplan-flow/1"
    # the one loader of model files reads the card's format and returns the flow
    loaded = load_model(panda, weights, task="panda_ik")
    assert isinstance(loaded, FlowModel) and loaded.config == tiny_flow.config
    t = np.array([[0.4, 0.1, 0.5], [0.3, -0.2, 0.6], [0.5, 0.0, 0.3]])
    np.testing.assert_array_equal(loaded.sample(t, 7), tiny_flow.sample(t, 7))
    with pytest.raises(ModelFileError, match="is a flow for task 'panda_ik', not 'panda_projection'"):
        load_flow(panda, weights, task="panda_projection")


def test_a_corrupt_or_foreign_flow_file_is_refused(tiny_flow, talos, tmp_path) -> None:
    weights, card = tiny_flow.save(tmp_path / "f.safetensors")
    with pytest.raises(ModelFileError, match="is a flow for robot 'panda', not 'talos'"):
        load_model(talos, weights)
    data = bytearray(weights.read_bytes())
    data[-3] ^= 0xFF
    weights.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match="does not match its card"):
        load_model("panda", weights)
    with pytest.raises(FileNotFoundError, match="genplan train"):
        load_flow("panda", tmp_path / "missing.safetensors")


def test_config_is_validated_before_work() -> None:
    for bad in ({"steps": 0}, {"cost_batch": -1}, {"hidden": (8, -1)}, {"w_cost": -1.0}, {"lr": 0.0},
                {"w_cost": float("nan")}, {"target_box": ((0, 0, 0), (1, 1))}):
        with pytest.raises(SettingsError, match="FlowConfig"):
            default_config("panda", **bad)
    assert isinstance(default_config("panda"), FlowConfig)


def test_euler_integration_of_the_field() -> None:
    """integrate() is the explicit Euler sum the native sampler mirrors."""
    net = FlowNet(2, (8,))
    x0, c = torch.randn(5, 2), torch.randn(5, 3)
    x = x0.clone()
    for k in range(4):
        x = x + 0.25 * net(x, torch.full((5, 1), k * 0.25), c)
    torch.testing.assert_close(net.integrate(x0, c, 4), x)


@pytest.mark.parametrize("robot_name", ["panda", "talos"])
def test_native_sampler_matches_torch(robot_name: str, tmp_path, monkeypatch) -> None:
    """The Rust forward pass (float32 matrix products, codec in float64, free-flyer quaternion)
    against torch on the same noise and targets."""
    robot = genplan.load(robot_name)
    torch.manual_seed(0)
    cfg = default_config(robot, hidden=(24, 16), steps=3)
    dim = robot.nq - int(robot.floating_base)
    from genplan.samplers.base import Codec

    codec = Codec(robot, np.linspace(-0.3, 0.3, dim), np.linspace(0.2, 0.9, dim))
    model = FlowModel(cfg, robot, FlowNet(dim, cfg.hidden), codec, torch.tensor([0.2, -0.1, 0.6]),
                      torch.tensor([0.3, 0.4, 0.2]))
    rng = np.random.default_rng(1)
    targets = rng.uniform(*np.asarray(cfg.target_box), size=(300, 3))  # > one native block of 256
    z = rng.standard_normal((300, dim))
    native = model.native_sampler(seed=0)
    np.testing.assert_allclose(native.generate(z, targets), model.generate(z, targets), atol=2e-5)
    assert native.nq == robot.nq
    q = native.sample(50)
    assert q.shape == (50, robot.nq) and np.isfinite(q).all()
    if robot.floating_base:
        np.testing.assert_allclose(np.linalg.norm(q[:, 3:7], axis=1), 1.0, atol=1e-12)
    # the same seed and calls give the same samples, bit for bit; the same stream in one call or in
    # two (float32 matrix products of another batch size may round the last bits differently)
    a = model.native_sampler(seed=4).sample(10)
    np.testing.assert_array_equal(a, model.native_sampler(seed=4).sample(10))
    s = model.native_sampler(seed=4)
    np.testing.assert_allclose(a, np.concatenate([s.sample(4), s.sample(6)]), rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="expected noise"):
        native.generate(z[:, :-1], targets)


def test_native_constructor_refuses_bad_shapes() -> None:
    w = [np.zeros((7, 11), np.float32)]
    b = [np.zeros(7, np.float32)]
    args = (3, [0.0] * 3, [1.0] * 3, [0.0] * 7, [1.0] * 7, False, [0.0] * 3, [1.0] * 3)
    _core.FlowSampler(w, b, *args)
    with pytest.raises(ValueError, match="first layer takes 10 inputs"):
        _core.FlowSampler([np.zeros((7, 10), np.float32)], b, *args)
    with pytest.raises(ValueError, match="one bias per weight"):
        _core.FlowSampler(w, [], *args)
    with pytest.raises(ValueError, match="target standardisation"):
        _core.FlowSampler(w, b, 3, [0.0] * 3, [0.0, 1.0, 1.0], *args[3:])
    with pytest.raises(ValueError, match="target box"):
        _core.FlowSampler(w, b, *args[:-2], [0.0] * 3, [float("nan")] * 3)


def test_targets_outside_the_model_region_are_refused(tiny_flow) -> None:
    with pytest.raises(GenplanError, match="lies outside the region this model answers for"):
        tiny_flow.sample([[9.0, 0.0, 0.0]])
    with pytest.raises(GenplanError, match="box"):
        tiny_flow.native_sampler(box=[[9.0, 0.0, 0.0], [10.0, 1.0, 1.0]])


def test_a_flow_plans_samples_and_warm_starts_ik_where_a_gan_does(tiny_flow, panda) -> None:
    """make_sampler, the hybrid mixture, GanSampler and solve_ik take a flow model."""
    for kind in ("gan", "hybrid", "adaptive"):
        s = make_sampler(panda, kind, seed=0, gan_model=tiny_flow)
        assert s is not None
    native = make_sampler(panda, "gan", seed=0, gan_model=tiny_flow)
    assert isinstance(native, _core.FlowSampler)
    py = GanSampler(panda, tiny_flow, seed=3)
    assert py.sample(5).shape == (5, 7) and py.sample_for([[0.4, 0.0, 0.5]]).shape == (1, 7)
    env = environment("panda_shelf")
    query = env.queries(panda, n=1, seed=0)[0]
    planner = Planner(panda, world=env.world(panda), sampler="gan", gan_model=tiny_flow, seed=0)
    result = planner.plan(query.start, query.goals)
    assert result.success and result.stats.samples > 0
    targets = panda.link_poses(np.asarray(query.goals)[:3], [panda.frames["hand"]])[:, 0, :3, 3]
    ik = genplan.solve_ik(panda, "panda_ik", targets, init="gan", model=tiny_flow, time_budget_s=0.05)
    assert ik.success.all()


@pytest.fixture(scope="module")
def tiny_student(tiny_flow, tmp_path_factory) -> FlowModel:
    mp = pytest.MonkeyPatch()
    mp.setenv("GENPLAN_CACHE", str(tmp_path_factory.mktemp("cache")))
    cfg = default_config("panda", iterations=300, data_size=400, hidden=(32, 32), steps=1, w_cost=0.0, pairs=2000,
                         seed=3, teacher="tiny_teacher.safetensors")
    student = distill(cfg, tiny_flow, progress=False, log_every=100)
    mp.undo()
    return student


def test_a_distilled_student_learns_its_teachers_map_in_one_step(tiny_flow, tiny_student) -> None:
    """The student (one Euler step, started from the teacher's weights) moves towards the
    teacher's samples for noise and targets it was not trained on."""
    assert tiny_student.config.steps == 1 and tiny_student.codec is tiny_flow.codec
    log = tiny_student.card["training"]["loss_log"]
    assert log[-1]["held_out_mse"] < 0.5 * log[0]["held_out_mse"]
    rng = np.random.default_rng(11)
    t = rng.uniform(*np.asarray(tiny_flow.config.target_box), size=(500, 3))
    z = rng.standard_normal((500, tiny_flow.codec.dim))
    ref = tiny_flow.generate(z, t)
    untrained = FlowModel(tiny_student.config, tiny_flow.robot, tiny_flow.net, tiny_flow.codec, tiny_flow.target_mean,
                          tiny_flow.target_std)  # the teacher's field in one step: where the student started
    gap = lambda m: float(np.mean((m.generate(z, t) - ref) ** 2))  # noqa: E731
    assert gap(tiny_student) < 0.5 * gap(untrained)
    teacher = tiny_student.card["training"]["teacher"]
    assert teacher["file"] == "tiny_teacher.safetensors" and teacher["steps"] == 3
    assert "--distill-from tiny_teacher.safetensors" in tiny_student.card["command"]


def test_a_student_file_loads_and_samples_natively_as_one_pass(tiny_student, panda, tmp_path) -> None:
    import os

    umask = os.umask(0o022)
    try:
        weights, card = tiny_student.save(tmp_path / "s.safetensors")
    finally:
        os.umask(umask)
    # written under temporary names and renamed (none left), readable by others as the umask allows
    assert sorted(f.name for f in tmp_path.iterdir()) == ["s.json", "s.safetensors"]
    assert weights.stat().st_mode & 0o777 == card.stat().st_mode & 0o777 == 0o644
    loaded = load_model(panda, weights)
    assert isinstance(loaded, FlowModel) and loaded.config == tiny_student.config
    t = np.array([[0.4, 0.1, 0.5], [0.3, -0.2, 0.6]])
    z = np.random.default_rng(0).standard_normal((2, loaded.codec.dim))
    np.testing.assert_allclose(loaded.native_sampler(seed=0).generate(z, t), tiny_student.generate(z, t), atol=2e-5)


def test_distillation_refuses_a_teacher_of_other_settings_before_work(tiny_flow) -> None:
    base = {"iterations": 5, "hidden": (32, 32), "steps": 1, "w_cost": 0.0, "pairs": 10}
    with pytest.raises(SettingsError, match="FlowConfig.data_size is 25000, the teacher's 400"):
        distill(default_config("panda", **base), tiny_flow, progress=False)
    with pytest.raises(SettingsError, match="FlowConfig.robot is 'talos', the teacher's 'panda'"):
        distill(default_config("talos", data_size=400, **base), tiny_flow, progress=False)
    with pytest.raises(SettingsError, match="FlowConfig.pairs"):
        default_config("panda", pairs=0)
    with pytest.raises(SettingsError, match="FlowConfig.pairs is 10: a student needs at least 100 pairs"):
        distill(default_config("panda", data_size=400, **base), tiny_flow, progress=False)


def test_train_flow_cli_card_command_retrains_the_same_file(tmp_path, capsys, monkeypatch) -> None:
    """The card's command names every setting given, the seed and the file: run again, it rewrites
    that file with the same weights (and not the robot's shipped flow)."""
    from genplan.cli import main

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "f.safetensors"
    assert main(["train", "flow", "--robot", "panda", "--seed", "2", "--iterations", "5", "--data-size", "300",
                 "--hidden", "16", "--steps", "2", "--eval-targets", "5", "--threads", "1", "--out", str(out)]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["command"] == (f"genplan train flow --robot panda --seed 2 --iterations 5 --hidden 16 --steps 2 "
                               f"--data-size 300 --out {out}")
    first = card["weights_sha256"]
    out.unlink()
    argv = card["command"].split()[1:]
    assert main([*argv, "--eval-targets", "5", "--threads", "1"]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["weights_sha256"] == first
    capsys.readouterr()


def test_train_flow_cli_distils_only_from_a_flow_of_its_robot(tiny_flow, tmp_path, capsys, monkeypatch) -> None:
    from genplan.cli import main

    weights, _ = tiny_flow.save(tmp_path / "teacher.safetensors")
    assert main(["train", "flow", "--robot", "panda", "--pairs", "10", "--out", str(tmp_path / "s")]) == 2
    assert "--pairs: only with --distill-from" in capsys.readouterr().err
    assert main(["train", "flow", "--robot", "talos", "--distill-from", str(weights), "--out",
                 str(tmp_path / "s")]) != 0
    assert "is a flow for robot 'panda', not 'talos'" in capsys.readouterr().err
    assert main(["train", "flow", "--robot", "panda", "--distill-from", str(weights), "--data-size", "50",
                 "--out", str(tmp_path / "s")]) == 2
    assert "--data-size: a student's data are its teacher's" in capsys.readouterr().err
    from genplan.samplers.base import models_dir

    assert main(["train", "flow", "--robot", "panda", "--distill-from", str(models_dir() / "panda_gan.safetensors"),
                 "--out", str(tmp_path / "s")]) == 2
    assert "a teacher is a flow file (genplan train flow), this is a GAN's" in capsys.readouterr().err
    assert not (tmp_path / "s.safetensors").exists()


def test_the_shipped_talos_flow_and_its_teacher(talos) -> None:
    """models/talos_flow.safetensors: a one-step student whose card names the shipped teacher (its
    hash too), whose retraining commands the README or docs/ document, and whose samples project onto the
    Talos manifold; the native twin matches torch."""
    from pathlib import Path

    from genplan import projection as P
    from genplan.samplers.base import models_dir
    from genplan.samplers.flow import shipped_path

    student = load_model(talos, shipped_path(talos))
    assert isinstance(student, FlowModel) and student.config.steps == 1
    teacher_info = student.card["training"]["teacher"]
    teacher = load_flow(talos, models_dir() / Path(teacher_info["file"]).name)
    assert teacher_info["weights_sha256"] == teacher.card["weights_sha256"] and teacher.config.steps == 8
    root = Path(__file__).resolve().parents[1]
    readme = "\n".join(p.read_text() for p in [root / "README.md", *sorted((root / "docs").glob("*.md"))])
    for card, path in ((student.card, shipped_path(talos)), (teacher.card, models_dir() / Path(teacher_info["file"]).name)):
        assert card["command"].split(" --")[0] in readme and "--distill-from models/talos_flow_teacher" in readme
        # the card's command rewrites this very file: its --out, or the shipped place by default
        words = card["command"].split()
        written = Path(words[words.index("--out") + 1]) if "--out" in words else Path("models") / shipped_path(talos).name
        assert written.name == path.name, card["command"]
    rng = np.random.default_rng(0)
    t = rng.uniform(*np.asarray(student.config.target_box), size=(64, 3))
    z = rng.standard_normal((64, student.codec.dim))
    q = student.generate(z, t)
    np.testing.assert_allclose(student.native_sampler(seed=0).generate(z, t), q, atol=2e-5)
    res = P.GaussNewtonProjector(talos, P.paper_task(talos, "projection")).solve_batch(q)
    assert res.success.all()


def test_integrity_4_a_flow_is_matched_to_its_robots_kinematics(tiny_flow, panda, tmp_path) -> None:
    """A flow file records the kinematic hash of its robot: an xArm7 robot file named "panda" is
    refused, naming both robots; the Panda under another name is not."""
    erd = "package://example-robot-data/robots"
    (tmp_path / "panda.toml").write_text(f'urdf = "{erd}/xarm_description/urdf/xarm7.urdf"\n[frames]\nhand = "link_eef"\n')
    xarm = genplan.load(tmp_path / "panda.toml")
    (tmp_path / "mine.toml").write_text((genplan.robots.PRESETS_DIR / "panda.toml").read_text())
    mine = genplan.load(tmp_path / "mine.toml")
    assert xarm.name == "panda" and mine.name == "mine" and mine.kinematic_hash == panda.kinematic_hash
    weights, card = tiny_flow.save(tmp_path / "f.safetensors")
    assert json.loads(card.read_text())["robot_kinematic_hash"] == panda.kinematic_hash
    with pytest.raises(ModelFileError, match=rf"is a flow for robot 'panda', not 'panda' \(robot file {tmp_path}/panda.toml\): "
                                             "the active joints or the kinematic chain between them differ"):
        load_model(xarm, weights)
    with pytest.raises(ModelFileError, match=r"^the flow is for robot 'panda' \(preset\), not 'panda' \(robot file "):
        GanSampler(xarm, tiny_flow)
    assert np.isfinite(GanSampler(mine, load_model(mine, weights), seed=0).sample(2)).all()
