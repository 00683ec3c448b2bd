"""genplan.pancake.model: the shipped seq2seq model, its files, the loss, and training mechanics."""

import json
import math

import numpy as np
import pytest
import torch

from genplan.errors import ModelFileError, NonFiniteError, SettingsError, ShapeError
from genplan.pancake import physics as ph
from genplan.pancake.model import (
    FORMAT, Seq2SeqModel, Seq2SeqNet, check_trajectories, default_config, default_path, load_model, nll,
    start_state, train,
)
from genplan.pancake.trajectories import s_curve


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
    assert model.config.mirror_canonical
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
    np.testing.assert_allclose(nll(p_in, r, 1e-8).numpy(), ref, rtol=1e-10)


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
    card = json.loads(c.read_text())
    card.pop("weights_sha256")
    bad.with_suffix(".json").write_text(json.dumps(card))
    with pytest.raises(ModelFileError, match="is corrupt"):
        load_model(bad)
    bad.with_suffix(".json").write_text("{broken")
    with pytest.raises(ModelFileError, match="card .* is corrupt"):
        load_model(bad)
    # weights that do not fit the card's architecture
    card["config"]["hidden"] = 32
    w.with_suffix(".json").write_text(json.dumps(card))
    with pytest.raises(ModelFileError, match="does not fit its card"):
        load_model(w)


def test_input_checks() -> None:
    with pytest.raises(ShapeError, match=r"shape \(500, 3\) or \(batch, 500, 3\)"):
        check_trajectories(np.zeros((500, 2)))
    with pytest.raises(ShapeError, match=r"shape"):
        check_trajectories(np.zeros((2, 499, 3)))
    x = np.zeros((2, 500, 3))
    x[1, 7, 2] = np.nan
    with pytest.raises(NonFiniteError, match=r"NaN or inf \(first at index \(1, 7, 2\)\)"):
        check_trajectories(x)
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
