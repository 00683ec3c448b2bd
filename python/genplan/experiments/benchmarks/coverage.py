"""Coverage of the learned distributions: the GAN paper's Fig. 3 and Fig. 4 claims, as numbers.

    genplan bench coverage --out benches/results/coverage.json [--quick] [--figures DIR]
    genplan bench coverage --no-planar --robots panda --variants default,wgan_gp,diversity \
        --iterations 2000 --seed 1 --out benches/results/coverage_variants.json

1. The planar 2-link robot among circular obstacles (Fig. 3): an unconditional GAN of its
   collision-free configurations with an ensemble of 1 vs 5 generators.
2. Panda and Talos (Fig. 4): the trained conditional GAN with the discriminator, without it, and
   with N_net = 1, each trained here with the same seed and iterations; ``--variants`` picks other
   named GanConfig variants (:data:`VARIANTS`: Wasserstein loss, the mode-seeking term, members
   initialised apart), each row with its training time and the machine's load. With ``--models
   DIR`` each GAN variant is read from ``DIR/<robot>_coverage_<variant>.safetensors`` instead of
   trained, when its card's configuration is the one this run would train (anything else is an
   error naming the file and the fields): the package ships the paper's ablations as ``--quick``
   trains them (:func:`ablation_path`), so ``genplan reproduce --quick`` measures them without
   training.

Metrics, each against held-out valid data the GAN never saw:

* ``cluster_coverage``: k-means (k = 20) clusters of the held-out data; the share of clusters
  that receive at least half of their expected share of samples. Mode collapse shows as low
  coverage.
* ``mmd``: the maximum mean discrepancy (Gaussian kernel, median bandwidth) between samples and
  held-out data, in standardised coordinates. 0 for identical distributions.
* ``valid_rate`` (planar): share of samples that are collision-free; ``projection_success``
  (robots): share of samples that the projector brings onto the manifold.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.cli import args as A
from genplan.experiments.common import machine, save_figure, table, write_json

K_CLUSTERS = 20
#: generator steps per robot variant of ``--quick`` (the shipped ablations' too)
QUICK_ITERATIONS = 1500


# ---------------------------------------------------------------------------------------------
# metrics
# ---------------------------------------------------------------------------------------------


def kmeans(x: NDArray[np.float64], k: int, rng: np.random.Generator, iters: int = 50) -> NDArray[np.float64]:
    """Lloyd's k-means with k-means++ initialisation; returns the centroids (k, d)."""
    centers = [x[rng.integers(len(x))]]
    for _ in range(1, k):
        d2 = np.min(((x[:, None, :] - np.array(centers)[None]) ** 2).sum(-1), axis=1)
        centers.append(x[rng.choice(len(x), p=d2 / d2.sum())])
    c = np.array(centers)
    for _ in range(iters):
        labels = np.argmin(((x[:, None, :] - c[None]) ** 2).sum(-1), axis=1)
        new = np.array([x[labels == j].mean(0) if np.any(labels == j) else c[j] for j in range(k)])
        if np.allclose(new, c):
            break
        c = new
    return c


def cluster_coverage(held_out: NDArray[np.float64], samples: NDArray[np.float64], rng: np.random.Generator,
                     k: int = K_CLUSTERS) -> float:
    """Share of the held-out data's k-means clusters that the samples reach with at least half
    of the cluster's share of the data."""
    c = kmeans(held_out, k, rng)
    data_share = np.bincount(np.argmin(((held_out[:, None] - c[None]) ** 2).sum(-1), 1), minlength=k) / len(held_out)
    sample_share = np.bincount(np.argmin(((samples[:, None] - c[None]) ** 2).sum(-1), 1), minlength=k) / len(samples)
    return float(np.mean(sample_share >= 0.5 * data_share))


def mmd(x: NDArray[np.float64], y: NDArray[np.float64], rng: np.random.Generator, n: int = 1500) -> float:
    """Unbiased squared MMD with a Gaussian kernel (bandwidth: median pairwise distance)."""
    import torch

    x = x[rng.choice(len(x), size=min(n, len(x)), replace=False)]
    y = y[rng.choice(len(y), size=min(n, len(y)), replace=False)]
    xt, yt = torch.tensor(x), torch.tensor(y)
    z = torch.cat([xt, yt])
    d = torch.cdist(z, z) ** 2
    sigma2 = torch.median(d[d > 0])
    kern = torch.exp(-d / sigma2)
    m, k = len(x), len(y)
    kxx = (kern[:m, :m].sum() - m) / (m * (m - 1))
    kyy = (kern[m:, m:].sum() - k) / (k * (k - 1))
    kxy = kern[:m, m:].mean()
    return float(kxx + kyy - 2 * kxy)


# ---------------------------------------------------------------------------------------------
# planar 2-link robot (Fig. 3)
# ---------------------------------------------------------------------------------------------

#: circular obstacles (x, y, radius) around a 2-link arm with unit links at the origin
PLANAR_OBSTACLES = np.array([[1.2, 1.0, 0.35], [-1.0, 1.3, 0.4], [-0.6, -1.4, 0.3], [1.4, -0.9, 0.35]])


def planar_collision_free(q: NDArray[np.float64], samples_per_link: int = 20) -> NDArray[np.bool_]:
    """True where neither link of the planar arm touches an obstacle."""
    t = np.linspace(0.0, 1.0, samples_per_link)
    elbow = np.stack([np.cos(q[:, 0]), np.sin(q[:, 0])], -1)
    tip = elbow + np.stack([np.cos(q[:, 0] + q[:, 1]), np.sin(q[:, 0] + q[:, 1])], -1)
    pts = np.concatenate([t[None, :, None] * elbow[:, None], elbow[:, None] + t[None, :, None] * (tip - elbow)[:, None]], 1)
    d = np.linalg.norm(pts[:, :, None, :] - PLANAR_OBSTACLES[None, None, :, :2], axis=-1)
    return np.all(d > PLANAR_OBSTACLES[None, None, :, 2], axis=(1, 2))


def planar_data(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    out = []
    while sum(len(o) for o in out) < n:
        q = rng.uniform(-np.pi, np.pi, size=(4 * n, 2))
        out.append(q[planar_collision_free(q)])
    return np.concatenate(out)[:n]


def train_unconditional(data: NDArray[np.float64], n_net: int, iterations: int, seed: int,
                        noise_dim: int = 2, progress: bool = True) -> Any:
    """An unconditional ensemble GAN (the paper's architecture) on 2-D data; returns a sampler."""
    import torch

    from genplan.samplers.gan import EnsembleGenerator, _mlp

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    real = torch.tensor(data, dtype=torch.float32)
    mean, std = real.mean(0), real.std(0)
    real = (real - mean) / std
    gen = EnsembleGenerator(n_net, noise_dim, (200, 200), 2)
    disc = _mlp([2, 20, 20, 1])
    opt_g = torch.optim.Adam(gen.parameters(), lr=5e-4)
    opt_d = torch.optim.Adam(disc.parameters(), lr=1e-3)
    bce = torch.nn.BCEWithLogitsLoss()
    b = 100
    it = range(iterations)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc=f"planar GAN n_net={n_net}", unit="it", leave=False)
    for _ in it:
        for _ in range(5):
            with torch.no_grad():
                fake = gen(torch.randn(n_net, b, noise_dim)).reshape(-1, 2)[torch.from_numpy(rng.integers(0, n_net * b, b))]
            r = real[torch.from_numpy(rng.integers(0, len(real), b))]
            d_loss = bce(disc(r), torch.ones(b, 1)) + bce(disc(fake), torch.zeros(b, 1))
            opt_d.zero_grad()
            d_loss.backward()
            opt_d.step()
        fake = gen(torch.randn(n_net, b, noise_dim)).reshape(-1, 2)
        g_loss = bce(disc(fake), torch.ones(len(fake), 1))
        opt_g.zero_grad()
        g_loss.backward()
        opt_g.step()

    @torch.no_grad()
    def sample(n: int) -> NDArray[np.float64]:
        out = gen(torch.randn(n_net, n, noise_dim)) * std + mean
        pick = rng.integers(0, n_net, n)
        return out[pick, np.arange(n)].double().numpy()

    return sample


def run_planar(iterations: int, seed: int, figures: Path | None, progress: bool) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    train_set, held_out = planar_data(5000, rng), planar_data(5000, rng)
    out: dict[str, Any] = {"obstacles": PLANAR_OBSTACLES.tolist(), "train_size": 5000, "held_out_size": 5000,
                           "iterations": iterations}
    samples = {}
    for n_net in (1, 5):
        t0 = time.perf_counter()
        sampler = train_unconditional(train_set, n_net, iterations, seed, progress=progress)
        s = sampler(5000)
        samples[n_net] = s
        out[f"n_net_{n_net}"] = {
            "cluster_coverage": cluster_coverage(held_out, s, np.random.default_rng(seed)),
            "mmd": mmd(held_out, s, np.random.default_rng(seed)),
            "valid_rate": float(planar_collision_free(s).mean()),
            "train_s": time.perf_counter() - t0,
        }
    if figures is not None:
        _plot_planar(held_out, samples, figures / "coverage_planar.png")
        out["figure"] = str(figures / "coverage_planar.png")
    return out


def _plot_planar(held_out: NDArray[np.float64], samples: dict[int, NDArray[np.float64]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    ax = axes[0]
    ax.set_title("2-link arm among obstacles")
    for x, y, r in PLANAR_OBSTACLES:
        ax.add_patch(plt.Circle((x, y), r, color="0.4"))
    for q in held_out[:: len(held_out) // 12]:
        e = np.array([np.cos(q[0]), np.sin(q[0])])
        t = e + np.array([np.cos(q[0] + q[1]), np.sin(q[0] + q[1])])
        ax.plot([0, e[0], t[0]], [0, e[1], t[1]], "-", color="tab:red", alpha=0.5)
    ax.set_xlim(-2.2, 2.2)
    ax.set_ylim(-2.2, 2.2)
    ax.set_aspect("equal")
    for ax, (n_net, s) in zip(axes[1:], samples.items()):
        ax.scatter(held_out[:, 0], held_out[:, 1], s=2, c="tab:red", alpha=0.3, label="valid (held out)")
        ax.scatter(s[:2000, 0], s[:2000, 1], s=4, c="tab:blue", marker="x", alpha=0.5, label="GAN samples")
        ax.set_title(f"N_net = {n_net}")
        ax.set_xlabel("q1 (rad)")
        ax.set_ylabel("q2 (rad)")
        ax.set_xlim(-np.pi, np.pi)
        ax.set_ylim(-np.pi, np.pi)
        ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# Panda and Talos (Fig. 4)
# ---------------------------------------------------------------------------------------------


#: the named variants ``--variants`` picks from: GanConfig overrides of the robot's default
#: (genplan.samplers.gan.default_config), or, with ``"family": "flow"``, FlowConfig overrides of the
#: flow sampler's (genplan.samplers.flow.default_config), or with ``"family": "distill"`` those of a
#: student (genplan.samplers.flow.distill) whose ``teacher`` is another variant's label, or with
#: ``"family": "shipped"`` the shipped GAN itself. The first three are the paper's ablations (Fig. 4).
VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "no_discriminator": {"use_discriminator": False},
    "n_net_1": {"n_net": 1},
    "wgan_gp": {"loss": "wgan_gp"},
    "diversity": {"w_diversity": 1.0},
    "diversity_low": {"w_diversity": 0.2},
    "data_init": {"member_init": "data"},
    "wgan_gp_diversity": {"loss": "wgan_gp", "w_diversity": 1.0},
    "diversity_data_init": {"w_diversity": 1.0, "member_init": "data"},
    "wgan_gp_data_init": {"loss": "wgan_gp", "member_init": "data"},
    "flow": {"family": "flow"},
    "flow_pure": {"family": "flow", "w_cost": 0.0, "steps": 8},
    "flow_pure_small": {"family": "flow", "w_cost": 0.0, "steps": 4, "hidden": (128, 128, 128)},
    # a one-step student of the variant named by "teacher" (trained in the same run, or first), for
    # three times the run's iterations
    "flow_distilled": {"family": "distill", "teacher": "flow_pure", "steps": 1, "w_cost": 0.0, "iterations_factor": 3},
    # the robot's shipped GAN (models/<robot>_gan.safetensors), measured as it is, not trained
    "shipped_gan": {"family": "shipped"},
}
#: the variants of the shipped coverage.json (the paper's ablations)
PAPER_VARIANTS = ("default", "no_discriminator", "n_net_1")


def variant_list(text: str) -> list[str]:
    """``--variants``: comma-separated names of :data:`VARIANTS`."""
    names = [v.strip() for v in text.split(",") if v.strip()]
    unknown = [v for v in names if v not in VARIANTS]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"expected comma-separated variants among {', '.join(VARIANTS)}, got {text!r}")
    return list(dict.fromkeys(names))


def variant_config(robot: str, label: str, **settings: Any) -> tuple[str, Any, dict[str, Any]]:
    """``(family, config, overrides)`` of variant ``label`` of :data:`VARIANTS` for ``robot``, with
    ``settings`` (iterations, seed) applied: a GanConfig, or a FlowConfig for ``"family": "flow"``."""
    from genplan.samplers.gan import default_config

    overrides = dict(VARIANTS[label])
    family = overrides.pop("family", "gan")
    factor = overrides.pop("iterations_factor", 1)
    if "iterations" in settings:
        settings = {**settings, "iterations": settings["iterations"] * factor}
    if family in ("flow", "distill"):
        from genplan.samplers.flow import default_config as flow_config

        return family, flow_config(robot, **settings, **overrides), overrides
    return family, default_config(robot, **settings, **overrides), overrides


def ablation_path(model_dir: Path, robot: str, label: str) -> Path:
    """The file of variant ``label`` of ``robot`` in a ``--models`` folder."""
    return model_dir / f"{robot}_coverage_{label}.safetensors"


def read_variant(robot: Any, label: str, cfg: Any, model_dir: Path) -> Any:
    """The GAN of variant ``label`` from the folder ``model_dir`` (:func:`ablation_path`), refused
    unless its card's configuration is ``cfg``, the one this run would train: a ModelFileError
    naming the file and each field that differs."""
    from genplan.errors import ModelFileError
    from genplan.samplers.gan import load_model

    path = ablation_path(model_dir, robot.name, label)
    model = load_model(robot, path)
    want, have = dataclasses.asdict(cfg), dataclasses.asdict(model.config)
    differ = [f"{k}={have[k]!r} (this run: {want[k]!r})" for k in want if have[k] != want[k]]
    if differ:
        raise ModelFileError(f"{path} was trained with {', '.join(differ)}: not variant '{label}' of this run; "
                             f"leave --models out to train it, or retrain the file: `{model.card['command']}`")
    return model


def run_robot(name: str, iterations: int, seed: int, figures: Path | None, progress: bool,
              threads: int | None = None, variants: "tuple[str, ...] | list[str]" = PAPER_VARIANTS,
              on_variant: "Callable[[dict[str, Any]], None] | None" = None,
              model_dir: Path | None = None) -> dict[str, Any]:
    """Train each of ``variants`` on ``name`` (a GAN variant read from the folder ``model_dir``
    instead, when given: :func:`read_variant`) and measure it; ``on_variant(results so far)`` after each (to
    checkpoint a long run)."""
    from genplan import projection as P
    import genplan
    from genplan.samplers.base import Codec
    from genplan.samplers.data import valid_configurations
    from genplan.samplers.gan import DISC_MIN_STD, default_config, train

    robot = genplan.load(name)
    data = valid_configurations(robot, 25_000, 0, progress=progress)
    held_out = valid_configurations(robot, 3000, 1000 + seed, progress=progress)
    targets = robot.frame_positions(held_out, default_config(name).target_frame)
    feats_ref = Codec.features(robot, held_out)
    scale = np.maximum(feats_ref.std(0), 0.05)
    ref = feats_ref / scale
    free = feats_ref.std(0) > DISC_MIN_STD  # features the constraints do not pin (Talos: all but the left arm)
    out: dict[str, Any] = {"iterations": iterations, "held_out_size": len(held_out), "seed": seed}
    projected = {}
    solver = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection"))
    models: dict[str, Any] = {}

    def trained(label: str) -> tuple[Any, float, float]:
        """Variant ``label``'s model (a distilled one's teacher trained first unless this run has
        it, its seconds then counted too), its training seconds (a model read from a file: its
        card's) and the load when it started."""
        from genplan.samplers import flow
        from genplan.samplers.gan import load_model

        family, cfg, _ = variant_config(name, label, iterations=iterations, seed=seed)
        load_start = os.getloadavg()[0]
        t0 = time.perf_counter()
        model: Any
        if family == "distill":
            teacher = models[cfg.teacher] if cfg.teacher in models else trained(cfg.teacher)[0]
            model = flow.distill(cfg, teacher, progress=progress, threads=threads)
        elif family == "shipped":
            model = load_model(robot)
        elif family == "gan" and model_dir is not None:
            model = read_variant(robot, label, cfg, model_dir)
        else:
            trainer: Callable[..., Any] = flow.train if family == "flow" else train
            model = trainer(cfg, data=data, progress=progress, threads=threads)
        from_file = family == "shipped" or (family == "gan" and model_dir is not None)
        train_s = float(model.card["training"]["seconds"]) if from_file else time.perf_counter() - t0
        models[label] = model
        return model, train_s, load_start

    for label in variants:
        family, cfg, overrides = variant_config(name, label, iterations=iterations, seed=seed)
        model, train_s, load_start = trained(label)
        if family == "shipped":
            cfg = model.config  # the shipped model's, not a default's
        rng = np.random.default_rng(seed)
        q = model.sample(targets, rng, threads=threads)  # one sample per held-out target: same conditioning
        res = solver.solve_batch(q)
        s = Codec.features(robot, q) / scale
        out[label] = {
            "cluster_coverage": cluster_coverage(ref, s, np.random.default_rng(seed)),
            "mmd": mmd(ref, s, np.random.default_rng(seed)),
            "projection_success": float(res.success.mean()),
            "projection_steps_mean": float(res.iterations[res.success].mean()) if res.success.any() else None,
            **({"teacher": cfg.teacher} if family == "distill" else {}),
            **({"train_s_from": "the shipped model's card"} if family == "shipped" else {}),
            **({"model_file": ablation_path(model_dir, name, label).name, "train_s_from": "the model file's card",
                "model_command": model.card["command"]} if family == "gan" and model_dir is not None else {}),
            **(member_diagnostics(model, targets, ref, scale, free, seed) if family in ("gan", "shipped")
               else {"mmd_free_features": mmd(ref[:, free], s[:, free], np.random.default_rng(seed))}),
            "native_sample_us": native_sample_us(model, seed),
            "train_s": train_s,
            "load_average_1min_start_end": [load_start, os.getloadavg()[0]],
            "overrides": overrides,
            "family": family,
            "config": {k: v for k, v in dataclasses.asdict(cfg).items()
                       if k in ("n_net", "use_discriminator", "iterations", "hidden", "steps", "w_cost", "pairs", *overrides)},
        }
        projected[label] = s
        if on_variant is not None:
            on_variant(out)
        if progress:
            r = out[label]
            members = f" (members {np.mean(r['member_coverage']):.2f})" if "member_coverage" in r else ""
            spread = f", noise spread {r['noise_spread']:.3f}" if "noise_spread" in r else ""
            print(f"{name} {label}: coverage {r['cluster_coverage']:.2f}{members}, "
                  f"MMD {r['mmd']:.4f} (free features {r['mmd_free_features']:.4f}){spread}, "
                  f"native {r['native_sample_us']:.1f} us/sample, projects "
                  f"{r['projection_success']:.3f} in {r['projection_steps_mean']} steps, trained in {train_s:.0f} s",
                  flush=True)
    if figures is not None:
        # the paper's ablations keep their figure's name; other variant sets get their own
        figure = figures / f"coverage_{name}{'' if tuple(variants) == PAPER_VARIANTS else '_variants'}.png"
        _plot_robot(name, ref, projected, figure)
        out["figure"] = str(figure)
    return out


def native_sample_us(model: Any, seed: int, n: int = 4096, repeats: int = 5) -> float:
    """Median microseconds per configuration of the model's native sampler (what the planner
    calls), ``n`` configurations per call, one thread."""
    sampler = model.native_sampler(seed=seed)
    sampler.sample(256)  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        sampler.sample(n)
        times.append((time.perf_counter() - t0) / n * 1e6)
    return float(np.median(times))


def member_diagnostics(model: Any, targets: NDArray[np.float64], ref: NDArray[np.float64],
                       scale: NDArray[np.float64], free: NDArray[np.bool_], seed: int,
                       n_targets: int = 100, draws: int = 16) -> dict[str, Any]:
    """Why a GAN's coverage is what it is, against the held-out features ``ref`` (scaled by
    ``scale``) of the held-out ``targets``:

    * ``member_coverage``: each ensemble member's own cluster coverage (one sample per target);
    * ``noise_spread``: how much a member's output moves with its noise, for a fixed target: the
      standard deviation over ``draws`` noise vectors, averaged over the first ``n_targets``
      targets, the members and the free features, relative to the held-out data's standard
      deviation (0: the member ignores its noise);
    * ``mmd_free_features``: the MMD over the features the constraints leave free (``free``), so a
      constant offset in the pinned ones (Talos' left arm) does not hide the distribution's match.
    """
    from genplan.samplers.base import Codec

    robot = model.robot
    rng = np.random.default_rng(seed)
    members = model.sample_members(targets, rng)  # (n_net, n, nq)
    per_member = [cluster_coverage(ref, Codec.features(robot, m) / scale, np.random.default_rng(seed)) for m in members]
    t = np.repeat(targets[:n_targets], draws, axis=0)
    q = model.sample_members(t, rng)  # (n_net, n_targets * draws, nq)
    f = np.stack([Codec.features(robot, m) / scale for m in q]).reshape(len(q), -1, draws, ref.shape[1])
    spread = float(f.std(2)[..., free].mean() / ref[:, free].std(0).mean())
    s = Codec.features(robot, model.sample(targets, np.random.default_rng(seed))) / scale
    return {"member_coverage": per_member, "noise_spread": spread,
            "mmd_free_features": mmd(ref[:, free], s[:, free], np.random.default_rng(seed))}


def _plot_robot(name: str, ref: NDArray[np.float64], samples: dict[str, NDArray[np.float64]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mean = ref.mean(0)
    _, _, vt = np.linalg.svd(ref - mean, full_matrices=False)
    proj = vt[:2].T
    fig, axes = plt.subplots(1, len(samples), figsize=(4.3 * len(samples), 4.2), sharex=True, sharey=True,
                             squeeze=False)
    axes = axes[0]
    r2 = (ref - mean) @ proj
    for ax, (label, s) in zip(axes, samples.items()):
        s2 = (s - mean) @ proj
        ax.scatter(r2[:, 0], r2[:, 1], s=2, c="tab:red", alpha=0.3, label="valid (held out)")
        ax.scatter(s2[:, 0], s2[:, 1], s=3, c="tab:blue", marker="x", alpha=0.4, label="samples")
        ax.set_title(f"{name}: {label.replace('_', ' ')}")
        ax.set_xlabel("principal component 1")
        ax.legend(loc="upper right", fontsize=7)
    axes[0].set_ylabel("principal component 2")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="fewer iterations (planar 1,500, robots 1,500)")
    p.add_argument("--variants", type=variant_list, default=list(PAPER_VARIANTS), metavar="A,B,...",
                   help=f"GAN variants trained per robot (default: the paper's {','.join(PAPER_VARIANTS)}; "
                        f"among {', '.join(VARIANTS)}); another set than the default writes "
                        "coverage_<robot>_variants.png")
    p.add_argument("--iterations", type=A.positive_int, default=None,
                   help="generator steps per robot variant (default 10,000, --quick 1,500)")
    p.add_argument("--no-planar", action="store_true", help="skip the planar 2-link robot")
    p.add_argument("--robots", nargs="*", default=["panda", "talos"], choices=["panda", "talos"])
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--figures", type=A.output_folder, default="benches/results",
                   help="folder for the PNG figures (created if missing)")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")
    p.add_argument("--threads", type=A.positive_int, default=1,
                   help="torch threads (default 1, see `genplan train gan --help`)")
    p.add_argument("--models", type=A.existing_folder, default=None, metavar="DIR",
                   help="read each GAN variant from DIR/<robot>_coverage_<variant>.safetensors instead of training "
                        "it; its card's configuration must be the one this run would train (the package's "
                        "models folder holds the paper's ablations as --quick --seed 0 trains them)")


def main(args: argparse.Namespace) -> int:
    import torch

    torch.set_num_threads(args.threads)
    planar_it = 1500 if args.quick else 5000
    robot_it = args.iterations or (QUICK_ITERATIONS if args.quick else 10_000)
    payload: dict[str, Any] = {"benchmark": "coverage", "quick": args.quick, "machine": machine(),
                               "k_clusters": K_CLUSTERS, "threads": args.threads, "variants": args.variants,
                               "models": None if args.models is None else str(args.models)}
    if not args.no_planar:
        payload["planar"] = run_planar(planar_it, args.seed, args.figures, True)
    for name in args.robots:
        def checkpoint(part: dict[str, Any], name: str = name) -> None:
            """Written after each variant too: a long run interrupted keeps what it measured."""
            write_json(args.out, {**payload, name: {**part, "partial": True}})

        payload[name] = run_robot(name, robot_it, args.seed, args.figures, True, threads=args.threads,
                                  variants=args.variants, on_variant=checkpoint, model_dir=args.models)
    rows = [["planar", f"N_net={k}", payload["planar"][f"n_net_{k}"]["cluster_coverage"],
             payload["planar"][f"n_net_{k}"]["mmd"], f"valid {payload['planar'][f'n_net_{k}']['valid_rate']:.3f}", "", "", ""]
            for k in (1, 5) if "planar" in payload]
    for name in args.robots:
        for label in args.variants:
            r = payload[name][label]
            steps = r["projection_steps_mean"]
            rows.append([name, label, r["cluster_coverage"], r["mmd"],
                         f"projects {r['projection_success']:.3f}, steps {'-' if steps is None else f'{steps:.2f}'}",
                         f"{r['native_sample_us']:.1f}", f"{r['train_s']:.0f}",
                         f"{r['load_average_1min_start_end'][0]:.1f}"])
    print(table(["setup", "variant", "cluster coverage", "MMD", "quality", "native us/sample", "train s", "load"], rows))
    write_json(args.out, payload)
    return 0
