"""genplan.pancake.model: the shipped seq2seq model (the pancake's configuration of the generic
genplan.seq2seq model), its files, the loss, and training mechanics."""

import json
import math

import numpy as np
import pytest
import torch

from genplan.errors import GenplanError, ModelFileError, NonFiniteError, SettingsError, ShapeError
from genplan.pancake import physics as ph
from genplan.pancake.model import default_config, default_path, load_model, start_state, train
from genplan.seq2seq.model import FORMAT, Seq2SeqModel, Seq2SeqNet, nll
from genplan.seq2seq.model import check_trajectories as check_any
from genplan.pancake.trajectories import s_curve
from tests.model_file_cases import common_cases, tamper


@pytest.fixture(scope="module")
def model() -> Seq2SeqModel:
    return load_model()


def test_shipped_model_and_card(model: Seq2SeqModel) -> None:
    path = default_path()
    assert path.read_bytes()[:8] != b"\x80\x04\x95"  # safetensors, not a pickle
    card = json.loads(path.with_suffix(".json").read_text())
    assert card["format"] == FORMAT
    assert card["retrain"].startswith("genplan train seq2seq --seed ")
    assert card["data"]["trajectories"] >= 10_000 and card["data"]["paper_trajectories"] == 1_638_400
    assert card["training"]["seconds"] > 0 and len(card["training"]["loss_log"]) >= 10
    assert card["config"]["hidden"] == 64 and card["config"]["layers"] == 2
    assert len(card["deviations_from_paper"]) >= 5
    ev = card["evaluation"]
    for key in ("held_out_inputs", "paper_27_s_curves"):
        assert 0 < ev[key]["rmse_pos_mm"] < 50 and 0 <= ev[key]["inside_cone_percent"] <= 100
    lat = ev["latent_adjustment_j1_adaptive"]
    assert lat["all_inside_cone"] is True and lat["mean_j1"]["100"] < 1e-3
    assert "latent_adjustment_j1_gd" in ev
    assert model.config.latent_dim == 128


def test_deformation_keeps_the_input_shape_inside_the_cone(model: Seq2SeqModel) -> None:
    x = np.stack([s_curve(np.zeros(3), [0.1, -0.1, 0.0]), s_curve([0.02, 0.0, 0.0], [-0.1, 0.1, 1.0])])
    out = model.deform(x)
    assert out["p"].shape == (2, 500, 3) and out["u"].shape == (2, 500, 3) and out["z"].shape == (2, 128)
    np.testing.assert_allclose(out["p"][:, 0], x[:, 0], atol=1e-6)  # starts at the input's start, at rest
    np.testing.assert_allclose(out["v"][:, 0], 0.0, atol=1e-6)
    assert np.abs(out["phi"]).max() < math.atan(1.0) + 0.05  # (these two inputs are feasible as they are)
    err = np.abs(out["p"] - x).max((1,))
    assert np.all(err[:, :2] < 0.05) and np.all(err[:, 2] < 0.3)  # metres, radians
    assert np.all(out["var_p"][:, 0] == 0) and np.all(out["var_p"][:, 1:] > 0)  # the start is known exactly
    # the output trajectory is the physics' response to the output accelerations (numpy twin)
    for i in range(2):
        xs = ph.rollout_np(out["u"][i], np.r_[x[i, 0], 0, 0, 0])
        np.testing.assert_allclose(out["p"][i], xs[:, :3], atol=2e-5)


def test_translation_invariance_in_y_and_z(model: Seq2SeqModel) -> None:
    x = s_curve(np.zeros(3), [0.05, 0.1, -1.0])
    shift = np.array([0.3, -0.2, 0.0])
    a, b = model.deform(x), model.deform(x + shift)
    np.testing.assert_allclose(a["z"], b["z"], atol=1e-5)
    np.testing.assert_allclose(a["p"] + shift, b["p"], atol=1e-5)


def test_mirror_symmetry(model: Seq2SeqModel) -> None:
    # (y, theta) -> (-y, -theta) maps the physics onto itself: phi changes sign
    x = s_curve([0.01, 0.0, 0.2], [0.08, -0.05, 2.5])
    xm = x * [-1.0, 1.0, -1.0]
    a, b = model.deform(x), model.deform(xm)
    assert model.config.mirror == (-1.0, 1.0, -1.0) and model.config.mirror_axis == 2
    np.testing.assert_allclose(a["z"], b["z"], atol=1e-6)
    np.testing.assert_allclose(a["p"] * [-1.0, 1.0, -1.0], b["p"], atol=1e-6)
    np.testing.assert_allclose(-a["phi"], b["phi"], atol=1e-5)
    u = np.ones((500, 1)) * [3.0, 1.0]
    np.testing.assert_allclose(ph.phi_np(-x[:, 2], u * [-1.0, 1.0]), -ph.phi_np(x[:, 2], u), atol=1e-12)


def test_nll_is_the_gaussian_log_density() -> None:
    from scipy.stats import norm

    rng = np.random.default_rng(0)
    p_in = torch.tensor(rng.normal(size=(2, 7, 3)))
    p_out = torch.tensor(rng.normal(size=(2, 7, 3)))
    var = torch.tensor(rng.uniform(0.1, 2, size=(2, 7, 3)))
    r = ph.Rollout(p=p_out, v=p_out, u=p_out, phi=p_out[..., 0], var_p=var)
    d = np.array(ph.D_SCALE)
    ref = -norm.logpdf(d * p_in.numpy(), d * p_out.numpy(), d * np.sqrt(var.numpy() + 1e-8)).sum((1, 2))
    np.testing.assert_allclose(nll(p_in, r, 1e-8, torch.tensor(d)).numpy(), ref, rtol=1e-10)


def test_save_load_round_trip_and_bad_files(model: Seq2SeqModel, tmp_path) -> None:
    w, c = model.save(tmp_path / "m.safetensors")
    loaded = load_model(w)
    x = s_curve(np.zeros(3), [0.1, 0.1, math.pi])
    np.testing.assert_allclose(loaded.deform(x)["p"], model.deform(x)["p"], atol=1e-7)
    with pytest.raises(FileNotFoundError, match="genplan train seq2seq --seed 0"):
        load_model(tmp_path / "missing.safetensors")
    # a replaced or corrupt weight file is refused
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"not a safetensors file")
    bad.with_suffix(".json").write_text(c.read_text())
    with pytest.raises(ModelFileError, match="does not match its card"):
        load_model(bad)
    tamper(bad)  # a card that vouches for a file that is not safetensors
    with pytest.raises(ModelFileError, match="is corrupt"):
        load_model(bad)
    card = json.loads(c.read_text())
    card.pop("weights_sha256")  # before: no hash skipped the check; now it is refused
    bad.with_suffix(".json").write_text(json.dumps(card))
    with pytest.raises(ModelFileError, match=r"bad.json lacks \['weights_sha256'\]"):
        load_model(bad)
    bad.with_suffix(".json").write_text("{broken")
    with pytest.raises(ModelFileError, match="card .* is corrupt"):
        load_model(bad)
    # weights that do not fit the card's architecture
    tamper(w, lambda c: c["config"].update(hidden=32))
    with pytest.raises(ModelFileError, match=r"does not fit its card: misshapen tensor\(s\)"):
        load_model(w)


@pytest.fixture(scope="module")
def tiny_model() -> Seq2SeqModel:
    """An untrained small model (hidden 8): what the loader tests save and tamper with."""
    torch.manual_seed(0)
    cfg = default_config(hidden=8)
    return Seq2SeqModel(cfg, Seq2SeqNet(cfg), {"description": "tiny test model"})


SEQ_CASES = common_cases("encoder.weight_ih_l0") + [
    ("missing_config_key", lambda c: c["config"].pop("hidden"), None, True, r"missing key\(s\) \['hidden'\]"),
    ("config_type", lambda c: c["config"].update(hidden="8"), None, True, "hidden must be int, got '8'"),
    ("config_tuple", lambda c: c["config"].update(out_scale=[1.0, 2.0]), None, True, "out_scale needs one value per axis"),
    ("config_nan", lambda c: c["config"].update(dt=float("nan")), None, True, "dt must be a finite float"),
    ("config_value", lambda c: c["config"].update(decoder_stride=3), None, True, "divisible by decoder_stride"),
    ("config_range", lambda c: c["config"].update(logvar_max=-20.0), None, True, "logvar_max must be a finite number"),
    ("config_shape", lambda c: c["config"].update(hidden=16), None, True, r"misshapen tensor\(s\)"),
]


@pytest.mark.parametrize("case, card_change, tensor_change, rehash, message", SEQ_CASES, ids=[c[0] for c in SEQ_CASES])
def test_loader_refuses_what_it_cannot_vouch_for(tiny_model: Seq2SeqModel, tmp_path, case, card_change, tensor_change,
                                                 rehash, message) -> None:
    """Every way a seq2seq file cannot be vouched for: one ModelFileError naming the file."""
    w, _ = tiny_model.save(tmp_path / f"{case}.safetensors")
    load_model(w)  # the untampered file loads
    tamper(w, card_change, tensor_change, rehash)
    with pytest.raises(ModelFileError, match=message) as info:
        load_model(w)
    assert f"{case}.safetensors" in str(info.value) or f"{case}.json" in str(info.value)


def test_what_cannot_be_loaded_is_not_written(tiny_model: Seq2SeqModel, tmp_path) -> None:
    net = Seq2SeqNet(tiny_model.config)
    net.load_state_dict(tiny_model.net.state_dict())
    with torch.no_grad():
        net.head.bias[0] = float("inf")
    with pytest.raises(ModelFileError, match="cannot write seq2seq model .* tensor head.bias holds NaN or inf"):
        Seq2SeqModel(tiny_model.config, net).save(tmp_path / "inf.safetensors")
    with pytest.raises(ModelFileError, match=r"card keys \['bogus'\] are not part of a seq2seq card"):
        Seq2SeqModel(tiny_model.config, tiny_model.net, {"bogus": 1}).save(tmp_path / "key.safetensors")
    assert not list(tmp_path.iterdir())


def test_shipped_card_vouches_for_its_weights() -> None:
    import hashlib

    card = json.loads(default_path().with_suffix(".json").read_text())
    assert card["weights_sha256"] == hashlib.sha256(default_path().read_bytes()).hexdigest()


def test_deform_refuses_what_it_cannot_vouch_for(model: Seq2SeqModel, tiny_model: Seq2SeqModel) -> None:
    """Before: an input offset by 1e200 (finite in float64, inf in the model's float32) deformed
    to NaN without an error. Now: poses beyond MAX_ABS are refused up front, and a non-finite
    deformation raises, naming the input."""
    x = s_curve(np.zeros(3), [0.1, 0.0, -1.0])
    with pytest.raises(GenplanError, match=r"x_in: element \(0, 0, 0\) is 1e\+200, beyond 10000"):
        model.deform(x + [1e200, 0.0, 0.0])
    assert np.all(np.isfinite(model.deform(x + [5e3, 0.0, 0.0])["p"]))
    net = Seq2SeqNet(tiny_model.config)
    net.load_state_dict(tiny_model.net.state_dict())
    with torch.no_grad():
        net.head.bias[0] = float("nan")  # an in-memory model gone bad (a file like it is refused)
    with pytest.raises(FloatingPointError, match=r"the deformation of x_in\[0\] is not finite"):
        Seq2SeqModel(tiny_model.config, net).deform(x)


def check_trajectories(x):
    """The model's input check for the pancake's (500, 3) poses."""
    return check_any(x, 500, 3)


def test_input_checks() -> None:
    with pytest.raises(ShapeError, match=r"shape \(500, 3\) or \(batch, 500, 3\)"):
        check_trajectories(np.zeros((500, 2)))
    with pytest.raises(ShapeError, match=r"shape"):
        check_trajectories(np.zeros((2, 499, 3)))
    x = np.zeros((2, 500, 3))
    x[1, 7, 2] = np.nan
    with pytest.raises(NonFiniteError, match=r"NaN or inf \(first at index \(1, 7, 2\)\)"):
        check_trajectories(x)
    # an empty batch is a batch (finding PY-8 of tests/test_fuzz_inputs.py); strings and complex
    # numbers are not poses (PY-2, PY-4)
    assert check_trajectories(np.zeros((0, 500, 3))).shape == (0, 500, 3)
    with pytest.raises(ShapeError, match="^x_in: complex numbers"):
        check_trajectories(np.zeros((500, 3)) + 1j)
    with pytest.raises(ShapeError, match="^x_in: cannot be read"):
        check_trajectories([["a", "b", "c"]] * 500)
    with pytest.raises(SettingsError, match="divisible by decoder_stride"):
        Seq2SeqNet(default_config(decoder_stride=3))


def test_training_mechanics(tmp_path) -> None:
    from genplan.pancake.data import generate_chunk

    data = generate_chunk(64, np.random.default_rng(0))
    cfg = default_config(trajectories=64, batch_size=32, epochs=1, validation=32, threads=1, seed=3)
    m = train(cfg, data=data, progress=False, log_every=1)
    log = m.card["training"]["loss_log"]
    assert [e["step"] for e in log] == [1, 2] and all(math.isfinite(e["loss"]) for e in log)
    assert m.card["data"]["trajectories"] == 64 and m.card["training"]["validation_log"][0]["epoch"] == 1
    m2 = train(cfg, data=data, progress=False, log_every=1)  # seeded: the same weights
    for (k, a), b in zip(m.net.state_dict().items(), m2.net.state_dict().values()):
        torch.testing.assert_close(a, b, msg=k)
    x = torch.as_tensor(data[:2])
    z, out = m.forward(x)
    assert z.shape == (2, 128) and out.p.shape == (2, 500, 3)
    np.testing.assert_allclose(start_state(x)[:, :3].numpy(), data[:2, 0])
    with pytest.raises(ShapeError, match="training data must have shape"):
        train(cfg, data=data[:, :100], progress=False)


def test_integrity_1_retraining_commands_name_an_out_outside_the_package(tmp_path, monkeypatch) -> None:
    """The shipped card's command and a missing file's error name --out; never the package's
    own models folder (training there is refused: genplan.cli.args.model_output)."""
    from genplan.model_files import inside_package
    from genplan.pancake.model import retrain_command

    card = json.loads(default_path().with_suffix(".json").read_text())
    assert card["retrain"].endswith(" --out pancake_seq2seq.safetensors")
    with pytest.raises(FileNotFoundError, match=rf"train it with `genplan train seq2seq --seed 0 --out {tmp_path}/m.safetensors`"):
        load_model(tmp_path / "m.safetensors")
    missing = default_path().with_name("gone.safetensors")
    assert inside_package(missing) and retrain_command(out=missing) == "genplan train seq2seq --seed 0 --out pancake_seq2seq.safetensors"
    cfg = default_config(trajectories=600, epochs=2, data_seed=5)
    assert retrain_command(cfg, tmp_path / "x.safetensors", data_seed=True) == (
        f"genplan train seq2seq --seed 0 --trajectories 600 --epochs 2 --data-seed 5 --out {tmp_path}/x.safetensors")
