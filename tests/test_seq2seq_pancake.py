"""The pancake model is one configuration of the generic seq2seq method: the shipped weights, loaded
as a genplan.seq2seq model with the pancake's configuration, give the deformations, latent
adjustments (J1, J2, J2Executable; every method and step rule) and training run that genplan.pancake
gave before the method moved (tests/data/pancake_reference.npz, written by
tests/data/make_pancake_reference.py at ba28c80), bit for bit; on a processor whose torch kernels
round otherwise (AVX-512 Intel Xeon), what today's code gave there (pancake_reference_avx512.npz)."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from genplan.pancake.objectives import J1, J2, J2Executable
from genplan.seq2seq import adjust as generic

#: the references: written at ba28c80 (AMD EPYC), and by today's code on an AVX-512 Intel Xeon
#: host, whose MKL and oneDNN kernels give torch other float32 bits (tests/data/make_pancake_reference.py)
REFERENCES = (Path(__file__).parent / "data" / "pancake_reference.npz",
              Path(__file__).parent / "data" / "pancake_reference_avx512.npz")
P_END = np.array([[0.1, -0.1, math.pi], [0.0, 0.1, 0.0], [-0.1, 0.0, -math.pi], [0.05, 0.05, -0.4]])
#: the pancake's defaults at ba28c80 (genplan.pancake.adjustment)
PAPER_LR = {"latent": 200.0, "random-latent": 200.0, "direct-u": 1000.0}
RADIUS = {"latent": 0.02, "random-latent": 0.02, "direct-u": 0.5}
ADAM_LR = {"latent": 0.02, "random-latent": 0.02, "direct-u": 2.0}


@pytest.fixture(scope="module")
def ref(model) -> dict[str, np.ndarray]:
    """The reference written on a processor that gives torch this one's bits: the one whose
    deformation of the same input this machine reproduces exactly (the rest is then compared bit
    for bit against it)."""
    refs = []
    for path in REFERENCES:
        with np.load(path) as z:
            refs.append({k: z[k] for k in z.files})
    np.testing.assert_array_equal(refs[0]["x_in"], refs[1]["x_in"])
    p = model.deform(refs[0]["x_in"])["p"]
    for r in refs:
        if np.array_equal(p, r["deform_p"]):
            return r
    far = ", ".join(f"{path.name}: {np.abs(p - r['deform_p']).max():.3g}" for path, r in zip(REFERENCES, refs))
    pytest.fail(f"this processor reproduces neither reference's deformation (largest differences {far}); "
                f"write one for it with tests/data/make_pancake_reference.py")


@pytest.fixture(scope="module")
def model():
    from genplan.pancake.model import load_model
    from genplan.seq2seq.model import Seq2SeqModel

    m = load_model()
    assert isinstance(m, Seq2SeqModel) and m.config.plant == "spatula"
    return m


def test_the_shipped_model_is_a_generic_model_with_the_pancake_configuration(model) -> None:
    cfg = model.config
    assert (cfg.dim, cfg.axes, cfg.relative, cfg.mirror, cfg.penalty) == (
        3, ("y", "z", "theta"), (True, True, False), (-1.0, 1.0, -1.0), "plant")
    assert cfg.latent_dim == 128 and cfg.K == 500


def test_deformation_is_unchanged(model, ref) -> None:
    d = model.deform(ref["x_in"])
    for k in ("p", "u", "phi", "z"):
        np.testing.assert_array_equal(d[k], ref[f"deform_{k}"], err_msg=k)


@pytest.mark.parametrize("method", ["latent", "random-latent", "direct-u"])
@pytest.mark.parametrize("step", ["gd", "adaptive", "adam"])
def test_j1_adjustment_is_unchanged(model, ref, method, step) -> None:
    lr = ADAM_LR[method] if step == "adam" else PAPER_LR[method]
    r = generic.adjust(model, ref["x_in"], J1(P_END), method=method, updates=5, step=step, seed=3, lr=lr,
                       max_step=RADIUS[method])
    key = f"j1_{method}_{step}"
    np.testing.assert_array_equal(r.objective_history, ref[f"{key}_history"])
    np.testing.assert_array_equal(r.p, ref[f"{key}_p"])
    np.testing.assert_array_equal(r.phi, ref[f"{key}_phi"])


@pytest.mark.parametrize("name, objective", [("j2", J2), ("j2exec", J2Executable)])
def test_j2_adjustment_is_unchanged(model, ref, name, objective) -> None:
    r = generic.adjust(model, ref["x_lin"], objective(), method="latent", updates=8, step="adam", lr=0.02)
    np.testing.assert_array_equal(r.objective_history, ref[f"{name}_history"])
    np.testing.assert_array_equal(r.p, ref[f"{name}_p"])


def test_the_pancake_front_end_gives_the_same_adjustment(model, ref) -> None:
    from genplan.pancake.adjustment import adjust

    r = adjust(ref["x_in"], J1(P_END), "latent", 5, model=model, step="adaptive", seed=3)
    np.testing.assert_array_equal(r.objective_history, ref["j1_latent_adaptive_history"])
    assert r.inside_cone().shape == (4,) and r.max_abs_phi.shape == (4,)


def test_training_is_unchanged(ref) -> None:
    from genplan.pancake.model import default_config, train

    cfg = default_config(trajectories=256, validation=64, epochs=1, batch_size=64, seed=5, data_seed=7)
    trained = train(cfg, progress=False, log_every=1)
    digest = hashlib.sha256()
    for name, t in sorted(trained.net.state_dict().items()):
        digest.update(name.encode() + t.numpy().tobytes())
    assert digest.hexdigest() == str(ref["train_weights_sha256"])
    np.testing.assert_array_equal([e["loss"] for e in trained.card["training"]["loss_log"]], ref["train_loss"])


def test_the_exact_integrator_is_the_recursion_in_any_dimension() -> None:
    from genplan.pancake.physics import rollout_np
    from genplan.seq2seq.plants import integrate

    rng = np.random.default_rng(0)
    u = rng.normal(size=(2, 40, 3))
    p0, v0 = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    p, v = integrate(torch.tensor(u), torch.tensor(p0), torch.tensor(v0), 0.01)
    states = rollout_np(u, np.concatenate([p0, v0], 1), 0.01)
    np.testing.assert_allclose(p.numpy(), states[..., :3], atol=1e-12)
    np.testing.assert_allclose(v.numpy(), states[..., 3:], atol=1e-12)
    u5 = rng.normal(size=(1, 10, 5))
    p5, _ = integrate(torch.tensor(u5), torch.zeros(1, 5, dtype=torch.float64), torch.zeros(1, 5, dtype=torch.float64), 0.1)
    assert p5.shape == (1, 10, 5)
    np.testing.assert_allclose(p5[0, 2].numpy(), 0.1 ** 2 * (1.5 * u5[0, 0] + 0.5 * u5[0, 1]), atol=1e-12)
