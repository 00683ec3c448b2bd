"""genplan.gan: data, training mechanics, model files (safetensors + card), samplers, the shipped
models."""

import json

import numpy as np
import pytest

import genplan
from genplan import projection as P
from genplan.cli import main
from genplan.errors import GenplanError, ModelFileError, SettingsError, ShapeError
from genplan.gan import data as gan_data
from genplan.gan.model import default_config, load_model, models_dir, train
from genplan.gan.sampler import GanSampler


@pytest.fixture(scope="module")
def tiny_panda_model(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("GENPLAN_CACHE", str(cache))
    cfg = default_config("panda", iterations=30, data_size=400, n_net=3, seed=3)
    model = train(cfg, progress=False)
    mp.undo()
    return model


def test_data_is_on_the_manifold_reproducible_and_cached(panda: genplan.Robot, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path))
    a = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    assert a.shape == (300, 7)
    files = list((tmp_path / "data").glob("panda_valid_300_4_*.npy"))
    assert len(files) == 1
    b = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    np.testing.assert_array_equal(a, b)
    files[0].write_bytes(b"broken")  # a corrupt cache is regenerated, not trusted
    c = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    np.testing.assert_array_equal(a, c)
    d = gan_data.valid_configurations(panda, n=300, seed=5, progress=False, use_cache=False)
    assert not np.allclose(a, d)
    # every configuration satisfies the projection task
    res = P.GaussNewtonProjector(panda, P.panda_task("projection")).solve_batch(a)
    assert res.success.all() and (res.iterations == 0).all()
    with pytest.raises(SettingsError, match="n must be positive"):
        gan_data.valid_configurations(panda, n=0)


def test_training_saving_and_loading(tiny_panda_model, panda: genplan.Robot, tmp_path) -> None:
    model = tiny_panda_model
    assert model.card["training"]["iterations"] == 30
    assert len(model.card["training"]["loss_log"]) >= 1
    weights, card = model.save(tmp_path / "m.safetensors")
    assert weights.is_file() and card.is_file()
    assert weights.read_bytes()[:8] != b"\x80\x04\x95" and card.suffix == ".json"  # not a pickle
    loaded = load_model(panda, weights)
    targets = np.random.default_rng(0).uniform(-0.5, 0.5, size=(6, 3))
    a = model.sample(targets, np.random.default_rng(1))
    b = loaded.sample(targets, np.random.default_rng(1))
    np.testing.assert_allclose(a, b, atol=1e-6)
    assert a.shape == (6, 7) and np.all(np.isfinite(a))
    members = loaded.sample_members(targets, np.random.default_rng(1))
    assert members.shape == (3, 6, 7)
    with pytest.raises(ShapeError, match=r"targets: expected finite positions of shape \(n, 3\)"):
        loaded.sample(np.zeros((2, 2)))


def test_model_file_errors(tiny_panda_model, panda: genplan.Robot, talos: genplan.Robot, tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="genplan train gan --robot panda"):
        load_model(panda, tmp_path / "missing.safetensors")
    weights, card = tiny_panda_model.save(tmp_path / "m.safetensors")
    with pytest.raises(ModelFileError, match="is a GAN for 'panda', not 'talos'"):
        load_model(talos, weights)
    weights.write_bytes(weights.read_bytes()[:-10])  # truncated
    with pytest.raises(ModelFileError, match="does not match its card"):
        load_model(panda, weights)
    data = json.loads(card.read_text())
    data.pop("weights_sha256")
    card.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match="corrupt"):
        load_model(panda, weights)
    card.write_text("{not json")
    with pytest.raises(ModelFileError, match="card .* is corrupt"):
        load_model(panda, weights)


def test_samplers(tiny_panda_model, panda: genplan.Robot) -> None:
    gan = GanSampler(panda, tiny_panda_model, seed=0)
    assert gan.sample(5).shape == (5, 7)
    assert gan.sample_for(np.zeros((3, 3))).shape == (3, 7)
    with pytest.raises(GenplanError, match="box: expected"):
        GanSampler(panda, tiny_panda_model, box=[[1, 1, 1], [0, 0, 0]])
    import genplan.gan

    with pytest.raises(AttributeError, match=r"UniformSampler was removed after 0.1.0.*make_sampler\(robot, \"uniform\""):
        genplan.gan.UniformSampler  # noqa: B018


def test_train_command(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "cli.safetensors"
    assert main(["train", "gan", "--robot", "panda", "--seed", "1", "--iterations", "5", "--data-size", "300",
                 "--n-net", "2", "--out", str(out)]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["config"]["n_net"] == 2 and card["config"]["seed"] == 1
    assert "projection_from_samples" in card["evaluation"]
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_shipped_models_load_and_sample_near_the_manifold(name: str) -> None:
    robot = genplan.load(name)
    path = models_dir() / f"{name}_gan.safetensors"
    assert path.is_file(), f"shipped model missing: {path}"
    model = load_model(robot)
    card = model.card
    assert card["config"]["iterations"] >= 10_000 and card["data"]["size"] == 25_000
    assert card["training"]["seconds"] > 0
    sampler = GanSampler(robot, model, seed=0)
    q = sampler.sample(200)
    res = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection")).solve_batch(q)
    assert res.success.mean() >= 0.98
    assert np.median(res.iterations) <= 3


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_native_generator_matches_torch(name: str) -> None:
    """The Rust generator (what the planner samples from) against the torch model, same noise,
    members and targets, in float64."""
    import torch

    robot = genplan.load(name)
    model = load_model(robot)
    native = model.native_sampler(seed=0)
    assert native.nq == robot.nq
    rng = np.random.default_rng(0)
    n = 64
    members = rng.integers(0, model.config.n_net, n)
    noise = rng.standard_normal((n, model.config.noise_dim))
    targets = rng.uniform(-0.5, 0.5, (n, 3))
    q_native = native.generate(members.tolist(), noise, targets)
    with torch.no_grad():
        x = torch.tensor(np.concatenate([noise, targets], 1))
        h = x[:, None, :]
        for i, (w, b) in enumerate(zip(model.generator.weights, model.generator.biases)):
            h = h @ w.double()[members] + b.double()[members]
            if i < len(model.generator.weights) - 1:
                h = torch.relu(h)
        codec = type(model.codec)(robot, model.codec.mean.double().numpy(), model.codec.std.double().numpy())
        codec.mean, codec.std = codec.mean.double(), codec.std.double()
        q_torch = codec.decode(h[:, 0, :]).numpy()
    assert np.abs(q_native - q_torch).max() < 1e-12
    # sampling: targets in the model's box, valid shapes, seeded
    a, b = model.native_sampler(seed=5).sample(20), model.native_sampler(seed=5).sample(20)
    assert a.shape == (20, robot.nq) and np.array_equal(a, b)
    with pytest.raises(GenplanError, match="box"):
        model.native_sampler(box=[[0, 0, 0], [-1, 1, 1]])
    with pytest.raises(GenplanError, match="member 99 out of range"):
        native.generate([99], noise[:1], targets[:1])
