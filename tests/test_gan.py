"""genplan.samplers: data, training mechanics, model files (safetensors + card), samplers, the shipped
models."""

import copy
import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch

import genplan
import genplan.planning
from genplan import projection as P
from genplan.cli import main
from genplan.errors import GenplanError, ModelFileError, NonFiniteError, SettingsError, ShapeError
from genplan.samplers import data as gan_data
from genplan.samplers.base import TARGET_MARGIN, models_dir
from genplan.samplers.gan import default_config, load_model, train
from genplan.samplers.sampler import GanSampler
from tests.model_file_cases import common_cases, tamper


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
    with pytest.raises(ModelFileError, match="is a GAN for robot 'panda', not 'talos'"):
        load_model(talos, weights)
    weights.write_bytes(weights.read_bytes()[:-10])  # truncated
    with pytest.raises(ModelFileError, match="does not match its card"):
        load_model(panda, weights)
    tamper(weights)  # the card now vouches for the truncated file: it does not load
    with pytest.raises(ModelFileError, match="is corrupt"):
        load_model(panda, weights)
    data = json.loads(card.read_text())
    data.pop("weights_sha256")  # before: no hash skipped the check; now it is refused
    card.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match=r"lacks \['weights_sha256'\]: the weights cannot be vouched for"):
        load_model(panda, weights)
    card.write_text("{not json")
    with pytest.raises(ModelFileError, match="card .* is corrupt"):
        load_model(panda, weights)


GAN_CASES = common_cases("generator.weight.0") + [
    ("other_robot", lambda c: c["config"].update(robot="talos"), None, True, "is a GAN for robot 'talos', not 'panda'"),
    ("card_robot", lambda c: c.update(robot="talos"), None, True, "metadata says robot 'panda', its card 'talos'"),
    ("missing_config_key", lambda c: c["config"].pop("n_net"), None, True, r"missing key\(s\) \['n_net'\]"),
    ("config_type", lambda c: c["config"].update(n_net="3"), None, True, "n_net must be int, got '3'"),
    ("config_nan", lambda c: c["config"].update(w_target=float("nan")), None, True, "w_target must be a finite float"),
    ("config_value", lambda c: c["config"].update(noise_dim=0), None, True, "GanConfig.noise_dim must be a positive"),
    ("config_box", lambda c: c["config"].update(target_box=[[1, 1, 1], [0, 0, 0]]), None, True, "target_box"),
    ("config_shape", lambda c: c["config"].update(n_net=4), None, True, r"misshapen tensor\(s\)"),
    ("target_frame", lambda c: c["config"].update(target_frame="nose"), None, True, "target frame 'nose'"),
    ("codec_scale", None, lambda t: t["codec.std"].__setitem__(0, 0.0), True, "codec.std holds a scale <= 0"),
]


@pytest.mark.parametrize("case, card_change, tensor_change, rehash, message", GAN_CASES, ids=[c[0] for c in GAN_CASES])
def test_loader_refuses_what_it_cannot_vouch_for(tiny_panda_model, panda: genplan.Robot, tmp_path, case,
                                                 card_change, tensor_change, rehash, message) -> None:
    """Before: a card without weights_sha256 skipped the hash check and NaN weights loaded; a bad
    card could raise KeyError/TypeError. Now: one ModelFileError naming the file and the problem."""
    weights, _ = tiny_panda_model.save(tmp_path / f"{case}.safetensors")
    load_model(panda, weights)  # the untampered file loads
    tamper(weights, card_change, tensor_change, rehash)
    with pytest.raises(ModelFileError, match=message) as info:
        load_model(panda, weights)
    assert f"{case}.safetensors" in str(info.value) or f"{case}.json" in str(info.value)


def _copy(model):
    """The model with its own generator and card (the robot is shared)."""
    return dataclasses.replace(model, generator=copy.deepcopy(model.generator), card=copy.deepcopy(model.card))


def test_what_cannot_be_loaded_is_not_written(tiny_panda_model, tmp_path) -> None:
    model = _copy(tiny_panda_model)
    with torch.no_grad():
        model.generator.biases[1][0, 0, 0] = float("nan")
    with pytest.raises(ModelFileError, match="cannot write GAN model .* tensor generator.bias.1 holds NaN"):
        model.save(tmp_path / "nan.safetensors")
    model = _copy(tiny_panda_model)
    model.card["bogus"] = 1
    with pytest.raises(ModelFileError, match=r"card keys \['bogus'\] are not part of a GAN card"):
        model.save(tmp_path / "key.safetensors")
    assert not list(tmp_path.iterdir())


def test_config_is_validated_before_work() -> None:
    for field, value in (("iterations", -1), ("n_net", 0), ("seed", -1), ("lr_gen", 0.0), ("w_target", float("inf"))):
        with pytest.raises(SettingsError, match=f"GanConfig.{field} must be"):
            default_config("panda", **{field: value})


def test_shipped_cards_vouch_for_their_weights() -> None:
    import hashlib

    for name in ("panda", "talos"):
        path = models_dir() / f"{name}_gan.safetensors"
        card = json.loads(path.with_suffix(".json").read_text())
        assert card["weights_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()


def test_sample_for_refuses_targets_it_cannot_vouch_for(tiny_panda_model, panda: genplan.Robot) -> None:
    """Before: a target of 1e200 gave all-NaN configurations (float32 overflow), 1e6 gave joint
    angles of 1e6 rad. Now: targets are validated up front, farther than TARGET_MARGIN outside
    the model's target box are refused (not clipped), naming the row."""
    gan = GanSampler(panda, tiny_panda_model, seed=0)
    lim = tiny_panda_model.target_limits()
    box = np.asarray(tiny_panda_model.config.target_box)
    np.testing.assert_allclose(lim, [box[0] - TARGET_MARGIN, box[1] + TARGET_MARGIN])
    ok = np.array([box[0] - 0.9 * TARGET_MARGIN, box[1] + 0.9 * TARGET_MARGIN, [0.3, 0.0, 0.5]])
    assert np.all(np.isfinite(gan.sample_for(ok)))
    with pytest.raises(GenplanError, match=re.escape("targets: row 1 [1e+200, 0.0, 0.5] lies outside the region")):
        gan.sample_for([[0.3, 0.0, 0.5], [1e200, 0.0, 0.5]])
    with pytest.raises(GenplanError, match="row 0 .* lies outside"):
        gan.sample_for([box[1] + [1.1 * TARGET_MARGIN, 0, 0]])
    with pytest.raises(NonFiniteError, match=r"row 1 is not"):
        gan.sample_for([[0.3, 0.0, 0.5], [np.nan, 0.0, 0.5]])
    with pytest.raises(ShapeError, match=r"shape \(n, 3\)"):
        gan.sample_for(np.zeros(3))
    with pytest.raises(ShapeError, match="cannot be read"):
        gan.sample_for([["a", "b", "c"]])
    assert gan.sample_for(np.zeros((0, 3))).shape == (0, 7)
    with pytest.raises(GenplanError, match="box: row 1 .* lies outside"):
        GanSampler(panda, tiny_panda_model, box=[[0, 0, 0], [5, 0, 0]])
    with pytest.raises(SettingsError, match="n must be a non-negative integer"):
        gan.sample(-1)
    with pytest.raises(GenplanError, match="box: row 1 .* lies outside"):
        tiny_panda_model.native_sampler(box=[[0, 0, 0], [5, 0, 0]])


def test_non_finite_samples_raise(tiny_panda_model, panda: genplan.Robot) -> None:
    """An in-memory model whose weights overflow: the torch sampler names the target row, the
    native one is refused before sampling (its output is bounded by interval arithmetic)."""
    model = _copy(tiny_panda_model)
    with torch.no_grad():
        for w in model.generator.weights:
            w.mul_(1e25)
    with pytest.raises(NonFiniteError, match=r"GAN sample for target row 0 \[0.3, 0.0, 0.5\] is not finite"):
        model.sample([[0.3, 0.0, 0.5]], 0)
    # natively (float64) those weights still give finite samples
    assert np.all(np.isfinite(GanSampler(panda, model).native(seed=0).sample(50)))
    # a deep generator of huge float32 weights overflows float64 too: refused before sampling
    from genplan.samplers.gan import EnsembleGenerator

    deep = dataclasses.replace(model.config, gen_hidden=(16,) * 10)
    gen = EnsembleGenerator(deep.n_net, deep.noise_dim + 3, deep.gen_hidden, 7)
    with torch.no_grad():
        for w in gen.weights:
            w.fill_(1e30)
    deep_model = dataclasses.replace(model, config=deep, generator=gen)
    with pytest.raises(NonFiniteError, match="not bounded in float64"):
        GanSampler(panda, deep_model).native()
    with pytest.raises(NonFiniteError, match="target row 0"):
        deep_model.sample([[0.3, 0.0, 0.5]])
    nan_codec = _copy(tiny_panda_model)
    nan_codec.codec = copy.copy(nan_codec.codec)
    nan_codec.codec.mean = nan_codec.codec.mean.clone()
    nan_codec.codec.mean[0] = float("nan")  # the native core does not check the codec: Python does
    with pytest.raises(NonFiniteError, match="not bounded in float64"):
        nan_codec.native_sampler()
    # the bound holds for the real model: native samples stay inside it
    bound = tiny_panda_model.feature_bound()
    assert np.isfinite(bound)
    native = tiny_panda_model.native_sampler(seed=1)
    assert np.abs(native.sample(2000)).max() <= bound


def test_samplers(tiny_panda_model, panda: genplan.Robot) -> None:
    gan = GanSampler(panda, tiny_panda_model, seed=0)
    assert gan.sample(5).shape == (5, 7)
    assert gan.sample_for(np.zeros((3, 3))).shape == (3, 7)
    with pytest.raises(GenplanError, match="box: expected"):
        GanSampler(panda, tiny_panda_model, box=[[1, 1, 1], [0, 0, 0]])


def _unchunked(sampler: GanSampler, n: int) -> tuple[np.ndarray, np.random.Generator]:
    """What GanSampler.sample(n) computed before it ran in chunks: targets, then the model's
    unchunked sample (python/genplan/samplers/gan.py), from one stream."""
    t = sampler.rng.uniform(sampler.box[0], sampler.box[1], size=(n, 3))
    return sampler.model.sample(t, sampler.rng), sampler.rng


@pytest.mark.parametrize("n", [0, 1, 5, 2048, 2049, 4095])
def test_chunked_sampling_is_the_unchunked_sampling(panda: genplan.Robot, n: int) -> None:
    """Below 2 * CHUNK_ROWS rows: one chunk, bit for bit the unchunked call, leaving the
    generator where it left it."""
    import genplan.samplers.sampler as S

    assert S.CHUNK_ROWS == 2048
    chunked = GanSampler(panda, seed=3)
    q = chunked.sample(n)
    ref, rng = _unchunked(GanSampler(panda, seed=3), n)
    assert q.shape == (n, 7) and np.array_equal(q, ref)
    assert chunked.rng.bit_generator.state == rng.bit_generator.state
    targets = np.random.default_rng(9).uniform(chunked.box[0], chunked.box[1], size=(n, 3))
    assert np.array_equal(chunked.sample_for(targets), chunked.model.sample(targets, rng))


def test_chunking_keeps_the_random_stream(panda: genplan.Robot, monkeypatch) -> None:
    """Many chunks: the same targets, noise and members as one unchunked call (the random stream
    is the same); the float32 products of a chunk may round the last bit differently, ~1e-6."""
    import genplan.samplers.sampler as S

    monkeypatch.setattr(S, "CHUNK_ROWS", 7)
    for n in (14, 15, 300):
        chunked = GanSampler(panda, seed=5)
        q = chunked.sample(n)
        ref, rng = _unchunked(GanSampler(panda, seed=5), n)
        assert chunked.rng.bit_generator.state == rng.bit_generator.state
        np.testing.assert_allclose(q, ref, rtol=0, atol=1e-5)
        assert np.array_equal(GanSampler(panda, seed=5).sample(n), q)  # deterministic, bit for bit
    monkeypatch.setattr(S, "CHUNK_ROWS", 2048)
    with pytest.raises(SettingsError, match=f"n must be at most {S.MAX_SAMPLES} per call"):
        GanSampler(panda, seed=0).sample(S.MAX_SAMPLES + 1)
    with pytest.raises(ShapeError, match="^targets: complex numbers"):
        GanSampler(panda, seed=0).sample_for(np.zeros((2, 3)) + 1j)


@pytest.mark.parametrize("after", [0.2, 1.0], ids=["drawing", "evaluating"])
def test_ctrl_c_interrupts_a_long_torch_sampling(panda: genplan.Robot, after: float) -> None:
    """Within 0.5 s of the signal, while the noise is drawn (the first ~0.2 s) or the generator
    evaluated (uninterrupted: about 10 s on an idle 2-core machine)."""
    from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency

    sampler = GanSampler(panda, seed=0)
    assert ctrl_c_latency(lambda: sampler.sample(200_000), after=after) < MAX_LATENCY_S


def test_train_command(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "cli.safetensors"
    assert main(["train", "gan", "--robot", "panda", "--seed", "1", "--iterations", "5", "--data-size", "300",
                 "--n-net", "2", "--loss", "wgan_gp", "--w-diversity", "1", "--member-init", "data", "--out", str(out)]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["config"]["n_net"] == 2 and card["config"]["seed"] == 1 and card["config"]["task"] == "panda_ik"
    assert (card["config"]["loss"], card["config"]["w_diversity"], card["config"]["member_init"]) == ("wgan_gp", 1.0, "data")
    assert card["command"] == ("genplan train gan --robot panda --seed 1 --iterations 5 --n-net 2 --data-size 300 "
                               f"--loss wgan_gp --w-diversity 1.0 --member-init data --out {out}")
    ev = card["evaluation"]
    for init in ("gan", "uniform"):
        for kind in ("projection", "ik"):
            assert 0 <= ev[init][kind]["success_rate"] <= 100
    # uniform starts on the Panda's projection manifold: the solver succeeds (Table I: 100 %)
    assert ev["uniform"]["projection"]["success_rate"] >= 95 and ev["uniform"]["projection"]["steps_star"] > 1
    assert card["task"]["name"] == "panda_ik"
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


def test_a_robot_with_continuous_joints_trains_and_samples_on_the_circle(tmp_path, monkeypatch) -> None:
    """Kinova's three continuous joints are [cos, sin] features: the trained model's torch and
    native samples put every pair on the unit circle, the native generator equals the torch one
    (float64, 1e-12) and the samples project onto the committed upright-tool task."""
    import torch

    from genplan.samplers.base import Codec

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    robot = genplan.load("kinova")
    task_file = Path(__file__).parents[1] / "examples" / "kinova" / "upright_tool.toml"
    out = tmp_path / "kinova.safetensors"
    assert main(["train", "gan", "--robot", "kinova", "--task", str(task_file), "--iterations", "20", "--n-net", "2",
                 "--data-size", "300", "--eval-targets", "10", "--out", str(out), "--seed", "1"]) == 0
    model = load_model(robot, out, task=task_file)
    assert model.codec.continuous == robot.continuous == [0, 4, 7]
    targets = np.random.default_rng(0).uniform([0.3, -0.3, 0.15], [0.5, 0.3, 0.4], (64, 3))
    q = model.sample(targets, 0)
    native = model.native_sampler(seed=0)
    rng = np.random.default_rng(1)
    members = rng.integers(0, model.config.n_net, len(targets))
    noise = rng.standard_normal((len(targets), model.config.noise_dim))
    q_native = native.generate(members.tolist(), noise, targets)
    for qq in (q, q_native, native.sample(50)):
        pairs = np.stack([qq[:, [i, i + 1]] for i in robot.continuous], 1)
        np.testing.assert_allclose(np.linalg.norm(pairs, axis=-1), 1.0, atol=1e-6)
    with torch.no_grad():
        h = torch.tensor(np.concatenate([noise, targets], 1))[:, None, :]
        for i, (w, b) in enumerate(zip(model.generator.weights, model.generator.biases)):
            h = h @ w.double()[members] + b.double()[members]
            if i < len(model.generator.weights) - 1:
                h = torch.relu(h)
        codec = Codec(robot, model.codec.mean.double().numpy(), model.codec.std.double().numpy())
        codec.mean, codec.std = codec.mean.double(), codec.std.double()
        q_torch = codec.decode(h[:, 0, :]).numpy()
    assert np.abs(q_native - q_torch).max() < 1e-12
    task = P.load_task(task_file, robot)
    res = P.GaussNewtonProjector(robot, P.manifold_task(task, robot)).solve_batch(q)
    assert res.success.mean() >= 0.9


def test_gan_targets_refuse_complex_strings_and_none(panda: genplan.Robot) -> None:
    """GanModel.check_targets reads targets through genplan._arrays: no silent drop of an
    imaginary part, no NaN from None (issue [hardening], kind 2)."""
    from genplan.errors import ShapeError
    from genplan.samplers.base import models_dir
    from genplan.samplers.gan import load_model

    model = load_model(panda, models_dir() / "panda_gan.safetensors")
    for bad, message in [(np.zeros((2, 3)) + 1j, "complex"), ("abc", "cannot be read"), (None, "None is not a number")]:
        with pytest.raises(ShapeError, match=f"targets: .*{message}"):
            model.check_targets(bad)


# -- the coverage remedies: Wasserstein loss with gradient penalty, mode seeking, members apart


def test_gradient_penalty_is_taken_on_interpolates() -> None:
    from genplan.samplers.gan import gradient_penalty

    class HalfSquare(torch.nn.Module):  # critic 0.5 |x|^2: its gradient at x is x
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return 0.5 * (x * x).sum(-1, keepdim=True)

    real, fake = torch.tensor([[2.0, 0.0], [0.0, 3.0]]), torch.zeros(2, 2)
    eps = torch.tensor([[0.25], [1.0]])
    # interpolates (0.5, 0) and (0, 3): gradient norms 0.5 and 3, penalties 0.25 and 4
    assert float(gradient_penalty(HalfSquare(), real, fake, eps).detach()) == pytest.approx((0.25 + 4.0) / 2)


def test_gradient_penalty_drives_the_critics_gradient_norm_to_one() -> None:
    from genplan.samplers.gan import _mlp, gradient_penalty

    torch.manual_seed(0)
    critic = _mlp([4, 32, 32, 1])
    with torch.no_grad():
        for p in critic.parameters():
            p.mul_(4.0)  # steep at first: gradient norms far above 1
    real, fake = torch.randn(256, 4) + 2.0, torch.randn(256, 4)

    def norms() -> torch.Tensor:
        x = (0.5 * real + 0.5 * fake).requires_grad_(True)
        (g,) = torch.autograd.grad(critic(x).sum(), x)
        return g.norm(dim=-1)

    assert float((norms() - 1).abs().mean()) > 1.0
    opt = torch.optim.Adam(critic.parameters(), lr=5e-3)
    for _ in range(300):
        loss = gradient_penalty(critic, real, fake, torch.rand(len(real), 1))
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float((norms() - 1).abs().mean()) < 0.2 and abs(float(norms().median()) - 1) < 0.05


def test_mode_seeking_loss_penalises_a_generator_that_ignores_its_noise() -> None:
    from genplan.samplers.gan import EnsembleGenerator, mode_seeking_loss

    z_a, z_b = torch.randn(2, 64, 3), torch.randn(2, 64, 3)
    same = torch.ones(2, 64, 5)
    assert float(mode_seeking_loss(same, same, z_a, z_b)) == pytest.approx(1e5)  # 1 / eps: collapsed
    assert float(mode_seeking_loss(z_a, z_b, z_a, z_b)) == pytest.approx(1.0, rel=1e-4)  # outputs as spread as noise
    # a generator that starts near-deterministic spreads its outputs when trained on the term
    torch.manual_seed(0)
    gen = EnsembleGenerator(2, 3 + 1, (16,), 5)
    with torch.no_grad():
        gen.weights[0][:, :3].mul_(0.01)  # the noise inputs barely count
    x = torch.zeros(2, 64, 1)

    def spread() -> float:
        with torch.no_grad():
            return float((gen(torch.cat([z_a, x], -1)) - gen(torch.cat([z_b, x], -1))).abs().mean())

    before = spread()
    opt = torch.optim.Adam(gen.parameters(), lr=1e-2)
    for _ in range(100):
        za, zb = torch.randn(2, 64, 3), torch.randn(2, 64, 3)
        loss = mode_seeking_loss(gen(torch.cat([za, x], -1)), gen(torch.cat([zb, x], -1)), za, zb)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert spread() > 10 * before


def test_spread_members_picks_rows_apart() -> None:
    from genplan.samplers.gan import spread_members

    centers = torch.tensor([[-5.0, 0.0], [5.0, 0.0], [0.0, 5.0], [0.0, -5.0]])
    feats = torch.cat([c + 0.1 * torch.randn(50, 2) for c in centers])
    picked = spread_members(feats, 4, np.random.default_rng(0))
    nearest = torch.cdist(picked, centers).argmin(1)
    assert sorted(nearest.tolist()) == [0, 1, 2, 3]  # one member per cluster


def test_coverage_options_train_round_trip_and_old_cards_default(panda: genplan.Robot, tmp_path, monkeypatch) -> None:
    from genplan.samplers.gan import GanConfig

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    cfg = default_config("panda", iterations=6, data_size=200, n_net=3, seed=2, loss="wgan_gp", gp_weight=5.0,
                         w_diversity=0.5, member_init="data")
    model = train(cfg, progress=False)
    log = model.card["training"]["loss_log"][-1]
    assert log["mode_seeking"] > 0 and np.isfinite(log["d_loss"])
    weights, card = model.save(tmp_path / "m.safetensors")
    loaded = load_model(panda, weights)
    assert loaded.config == cfg
    assert json.loads(card.read_text())["config"]["loss"] == "wgan_gp"
    # the native sampler runs it: same architecture
    assert np.isfinite(loaded.native_sampler(seed=0).sample(4)).all()
    # cards written before the options: the paper's values
    shipped = load_model(panda).config
    assert (shipped.loss, shipped.w_diversity, shipped.member_init) == ("bce", 0.0, "uniform")
    assert {"loss", "gp_weight", "w_diversity", "member_init"} <= GanConfig.ADDED_FIELDS
    for field, value in (("loss", "hinge"), ("member_init", "zeros"), ("w_diversity", -1.0), ("gp_weight", float("nan"))):
        with pytest.raises(SettingsError, match=f"GanConfig.{field} must be"):
            default_config("panda", **{field: value})


# --------------------------------------------------------------------------------------------
# A model is matched to a robot by its kinematics, not by its name
# --------------------------------------------------------------------------------------------

REPO = Path(__file__).resolve().parents[1]
ERD = "package://example-robot-data/robots"


def _robot_file(tmp_path, name: str, urdf: str, *, srdf: str | None = None, collision_urdf: str | None = None,
                locked: str = "", frames: str = 'hand = "panda_hand"', extra: str = "") -> genplan.Robot:
    """A robot file of one's own in ``tmp_path`` (``name``.toml), loaded."""
    path = tmp_path / f"{name}.toml"
    text = f'name = "{name}"\nurdf = "{urdf}"\n'
    text += "".join(f'{k} = "{v}"\n' for k, v in (("srdf", srdf), ("collision_urdf", collision_urdf)) if v)
    path.write_text(text + locked + extra + f"\n[frames]\n{frames}\n")
    return genplan.load(path)


def _panda_file(tmp_path, name: str = "panda", urdf: str | None = None, collision_urdf: str | None = None,
                locked: str = 'locked_joints = ["panda_finger_joint1", "panda_finger_joint2"]\n'
                              'reference_state = "default"\n') -> genplan.Robot:
    return _robot_file(tmp_path, name, urdf or f"{ERD}/panda_description/urdf/panda.urdf",
                       srdf=f"{ERD}/panda_description/srdf/panda.srdf",
                       collision_urdf=collision_urdf or f"{ERD}/panda_description/urdf/panda_collision.urdf",
                       locked=locked)


def test_integrity_4_another_robot_named_panda_is_refused_naming_both(panda: genplan.Robot, tmp_path) -> None:
    """Before: the Panda GAN loaded for an xArm7 robot file named "panda" (its name was all that
    was compared) and every sample lay outside the xArm7's limits."""
    from genplan.errors import ModelFileError

    xarm = _robot_file(tmp_path, "panda", f"{ERD}/xarm_description/urdf/xarm7.urdf",
                       srdf=f"{ERD}/xarm_description/srdf/xarm7.srdf", frames='hand = "link_eef"')
    assert xarm.name == panda.name and xarm.kinematic_hash != panda.kinematic_hash
    shipped = models_dir() / "panda_gan.safetensors"
    for load in (lambda: load_model(xarm), lambda: GanSampler(xarm), lambda: GanSampler(xarm, shipped)):
        with pytest.raises(ModelFileError) as info:
            load()
        message = str(info.value)
        assert message.startswith(f"{shipped} is a GAN for robot 'panda', not 'panda' (robot file {tmp_path / 'panda.toml'})")
        assert "kinematic hash" in message and panda.kinematic_hash[:12] in message and xarm.kinematic_hash[:12] in message
    # a model in memory: the robot it was made for against the one given
    with pytest.raises(ModelFileError, match=r"^the GAN is for robot 'panda' \(preset\), not 'panda' \(robot file "):
        GanSampler(xarm, load_model(panda))


def test_integrity_4_the_match_ignores_the_name_and_locked_joints_off_the_chain(panda: genplan.Robot, tmp_path) -> None:
    """A Panda with its fingers locked open, or under another name, keeps the Panda GAN; a Panda
    whose joint 1 has other limits does not."""
    from genplan.errors import ModelFileError

    open_fingers = _panda_file(tmp_path, "panda",
                               locked="locked_joints = { panda_finger_joint1 = 0.04, panda_finger_joint2 = 0.04 }\n"
                                      'reference_state = "default"\n')
    assert open_fingers.locked_joints == {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}
    renamed = _panda_file(tmp_path, "my_panda")
    shipped = models_dir() / "panda_gan.safetensors"
    for robot in (open_fingers, renamed):
        assert robot.kinematic_hash == panda.kinematic_hash
        model = load_model(robot, shipped)
        assert model.robot is robot and np.isfinite(GanSampler(robot, model, seed=0).sample(3)).all()
    for name in ("panda", "panda_collision"):  # the kinematic and the collision URDF: one tree
        urdf = (genplan.robots.robots_dir() / "panda_description" / "urdf" / f"{name}.urdf").read_text()
        assert urdf.count('lower="-2.8973"') >= 1
        (tmp_path / f"narrow_{name}.urdf").write_text(urdf.replace('lower="-2.8973"', 'lower="-2.5"', 1))
    narrow = _panda_file(tmp_path, "panda", urdf=str(tmp_path / "narrow_panda.urdf"),
                         collision_urdf=str(tmp_path / "narrow_panda_collision.urdf"))
    assert narrow.kinematic_hash != panda.kinematic_hash
    with pytest.raises(ModelFileError, match="is a GAN for robot 'panda', not 'panda'"):
        load_model(narrow, shipped)


def test_integrity_4_a_card_without_the_hash_loads_with_one_warning(tiny_panda_model, panda: genplan.Robot,
                                                                    talos: genplan.Robot, tmp_path) -> None:
    """A card written before the hash existed: matched by name, with a ModelCardWarning emitted
    once per file."""
    import warnings

    from genplan.errors import ModelFileError
    from genplan.model_files import ModelCardWarning

    weights, card = tiny_panda_model.save(tmp_path / "old.safetensors")
    assert json.loads(card.read_text())["robot_kinematic_hash"] == panda.kinematic_hash
    tamper(weights, lambda c: c.pop("robot_kinematic_hash"))
    with pytest.warns(ModelCardWarning, match=f"{card} records no robot kinematic hash"):
        load_model(panda, weights)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_model(panda, weights)  # once
    with pytest.raises(ModelFileError, match="is a GAN for robot 'panda', not 'talos'"):
        load_model(talos, weights)
    tamper(weights, lambda c: c.update(robot_kinematic_hash="not a hash"))
    with pytest.raises(ModelFileError, match="robot_kinematic_hash must be 64 lowercase hex digits"):
        load_model(panda, weights)


def test_integrity_rerun_a_card_without_a_task_is_matched_to_its_shipped_task(panda: genplan.Robot,
                                                                                talos: genplan.Robot, tmp_path) -> None:
    """Before: the shipped GAN cards record no task, so a task file named panda_ik with other terms
    (the hand's orientation axes, another frame) was accepted for the Panda GAN and the planner
    sampled a manifold other than the task's. A card without a task is matched to the shipped
    task of its task name, as a card recording its task is."""
    shipped = models_dir() / "panda_gan.safetensors"
    assert "task" not in json.loads(shipped.with_suffix(".json").read_text())
    text = (P.TASKS_DIR / "panda_ik.toml").read_text()
    same = tmp_path / "same.toml"
    same.write_text(text)
    for task in ("panda_ik", same, P.panda_task("ik")):  # the shipped task, by name, as a copy, as a Task
        assert load_model(panda, shipped, task=task).config.task_name == "panda_ik"
    assert load_model(talos, models_dir() / "talos_gan.safetensors", task="talos_ik").config.task_name == "talos_ik"
    assert text.count("axes = [1, 1, 0]") == 1 and text.count('frame = "hand"') == 2
    orient = tmp_path / "t_orient.toml"
    orient.write_text(text.replace("axes = [1, 1, 0]", "axes = [1, 0, 1]"))
    tcp = tmp_path / "t_tcp.toml"
    tcp.write_text(text.replace('frame = "hand"', 'frame = "panda_link8"'))
    for task in (orient, tcp):
        assert P.load_task(task, panda).name == "panda_ik"
        with pytest.raises(ModelFileError, match=r"is a GAN for another task 'panda_ik' than the one given \(same "
                                                 r"name, other terms"):
            load_model(panda, shipped, task=task)
        with pytest.raises(ModelFileError, match="same name, other terms"):
            genplan.planning.plan(panda, task, sampler="gan", model=shipped)
    # a card recording neither a task nor a shipped task's name: the terms it was trained for are unknown
    weights, _ = load_model(panda, shipped).save(tmp_path / "old.safetensors")
    tamper(weights, lambda c: c["config"].update(task="mine"))
    mine = tmp_path / "mine.toml"
    mine.write_text(text.replace('name = "panda_ik"', 'name = "mine"'))
    with pytest.raises(ModelFileError, match="records no task, and 'mine' .* is not a shipped task"):
        load_model(panda, weights, task=mine)


SHIPPED = [("panda_gan", "panda"), ("talos_gan", "talos"), ("talos_flow", "talos"), ("talos_flow_teacher", "talos"),
           ("xarm7/upright_cup_gan", str(REPO / "examples" / "xarm7" / "xarm7.toml")),
           ("kinova/upright_tool_gan", "kinova"),
           ("baxter/tray_gan", str(REPO / "examples" / "baxter" / "baxter_tray.toml"))]


@pytest.mark.parametrize("name, robot", SHIPPED, ids=[s[0] for s in SHIPPED])
def test_integrity_4_shipped_cards_record_their_robots_kinematics(name: str, robot: str) -> None:
    """Each shipped card records the kinematic hash of the robot it was trained for, its weights
    unchanged (their sha256 is the card's), and loads without a warning."""
    import hashlib
    import warnings

    from genplan.samplers.loading import load_sampler_model

    rob = genplan.load(robot)
    path = (REPO / "examples" if "/" in name else models_dir()) / f"{name}.safetensors"
    card = json.loads(path.with_suffix(".json").read_text())
    assert card["robot_kinematic_hash"] == rob.kinematic_hash
    assert card["weights_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_sampler_model(rob, path)
    # the card's command retrains it: the options it names are the command's, the data's share in
    # the condition box recorded as the model was trained (cards before the option: none)
    command = card["command"].split()
    assert command[:3] == ["genplan", "train", card.get("kind", "gan") if "flow" not in name else "flow"]
    in_box = card.get("config", {}).get("data_in_box")
    if command[2] == "gan" and "/" in name:
        assert f"--data-in-box {in_box or 0:g}" in card["command"] or (in_box == 0.5 and "--data-in-box" not in command)


def test_integrity_7_a_task_without_a_condition_target_trains_evaluates_and_writes_its_card(
        panda: genplan.Robot, tmp_path, monkeypatch) -> None:
    from tests.test_projection import _no_target_task

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    f = _no_target_task(tmp_path)
    out = tmp_path / "m.safetensors"
    assert main(["train", "gan", "--robot", "panda", "--task", str(f), "--iterations", "3", "--n-net", "2",
                 "--data-size", "200", "--eval-targets", "10", "--out", str(out)]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    term = next(t for t in card["task"]["primary"] if t["name"] == "hand_position")
    assert "target" not in term and card["evaluation"]["targets"] == 10
    model = load_model(panda, out, task=f)  # the card's task is the file's
    assert model.sample(np.array([[0.5, 0.0, 0.6]]), 0).shape == (1, 7)


def test_integrity_7_training_checks_every_use_of_the_task_before_any_work(panda: genplan.Robot, monkeypatch) -> None:
    from genplan.errors import TaskFileError

    class Elbow(P.CustomTerm):  # a Python term defined in a function: solvable, but no card can import it
        def dim(self) -> int:
            return 1

        def residual(self, q):
            return q[:, 3:4] + 1.5

        def jacobian(self, q):
            jac = np.zeros((len(q), 1, 7))
            jac[:, 0, 3] = 1.0
            return jac

    task = P.panda_task("ik")
    task = dataclasses.replace(task, name="elbow_ik", secondary=(*task.secondary, Elbow(name="elbow")))

    def no_work(*args, **kwargs):
        pytest.fail("training started work before the task was checked")

    monkeypatch.setattr(gan_data, "valid_configurations", no_work)
    cfg = default_config(panda, task, iterations=3, data_size=100, n_net=2)
    with pytest.raises(TaskFileError, match="term 'elbow'.*Elbow is defined inside a function"):
        train(cfg, robot=panda, task=task, progress=False)


def test_integrity_2_a_changed_data_cache_is_regenerated_not_trusted(panda: genplan.Robot, tmp_path,
                                                                     monkeypatch) -> None:
    import hashlib

    from genplan.cache import hash_path

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path))
    ref = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    path = gan_data.cache_path(panda, 300, 4)
    raw = bytearray(path.read_bytes())
    header = len(raw) - ref.nbytes
    raw[header + 8 * 5: header + 8 * 6] = np.float64(-47.0).tobytes()  # joint 5 of row 0 at -47 rad
    path.write_bytes(bytes(raw))
    with pytest.warns(RuntimeWarning, match="do not match their sha256"):
        again = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    np.testing.assert_array_equal(again, ref)
    # the file and its hash both changed: the rows are checked against the joint limits on read
    path.write_bytes(bytes(raw))
    hash_path(path).write_text(hashlib.sha256(bytes(raw)).hexdigest())
    with pytest.warns(RuntimeWarning, match=r"1 row outside the joint limits \(row 0: q\[5\] = -47"):
        again = gan_data.valid_configurations(panda, n=300, seed=4, progress=False)
    np.testing.assert_array_equal(again, ref)
    # a cache file without its hash (written before hashes were kept) is regenerated
    hash_path(path).unlink()
    np.testing.assert_array_equal(gan_data.valid_configurations(panda, n=300, seed=4, progress=False), ref)
    assert hash_path(path).is_file()
