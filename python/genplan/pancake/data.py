"""Training inputs for the seq2seq model: varied smooth spatula trajectories (numpy).

The paper trains on 1,638,400 simulated input trajectories and evaluates on S-curve moves from
the origin to end poses in ``y, z in [-0.1, 0.1] m``, ``theta in [-pi, pi]``. Inputs here are
poses ``[y, z, theta]`` (K = 500 samples at 1 ms) from three families, over a wider range than
the evaluation's so that the latent space covers it with room to spare:

* ``s-curve`` (35 %): S-curve (:func:`~genplan.pancake.trajectories.s_curve_profile`) from a start
  pose to an end pose; in half of them each axis moves over its own sub-interval of the horizon
  (start delay, shorter duration), the other half uses the full horizon like the evaluation;
* ``perturbed`` (25 %): an S-curve plus smooth bumps ``sin(pi tau) sin(n pi tau)``, n = 1..3,
  that vanish with their slope at both ends (detours, overshoots, wiggles of the attitude);
* ``line`` (10 %): constant velocity from start to end (the paper's J2 input, Section 5.2);
* ``feasible`` (30 %): motions that keep the pancake by construction, so that the decoder learns
  to produce them (flips included): a reference from the families above, in half of the cases
  with its rotation moved towards the end and a lift in z added (the shape of a pancake toss),
  is tracked by a P-D law (900 / 60) whose acceleration is projected at every step onto the
  admissible set (``|phi| <= arctan(mu) - 0.05 rad`` and a normal force of at least 1 m/s^2)
  and rolled out with eq. 8; motions that stray more than 0.3 m are drawn again.

Start poses: ``y0, z0 ~ U[-0.05, 0.05]``; ``theta0 = 0`` for 70 %, else ``U[-0.5, 0.5]``.
Moves: ``dy, dz ~ U[-0.2, 0.2]``; end attitude ``U[-1.25 pi, 1.25 pi]``.

Seeded and reproducible; cached on disk as ``.npy`` under ``$GENPLAN_CACHE`` (default
``~/.cache/genplan``) / ``data``; a corrupt cache file is regenerated.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.cache import cache_dir, load_array, save_array
from genplan.errors import SettingsError
from genplan.pancake.trajectories import DT, G, MU_MAX
from genplan.pancake.trajectories import K as K_DEFAULT

#: bump the version when the generator changes (it keys the cache)
GENERATOR_VERSION = 2
CHUNK = 4096

#: ranges of the generator (also written to the model card)
RANGES = {
    "start_yz_m": 0.05,
    "start_theta_rad": 0.5,
    "start_theta_zero_fraction": 0.7,
    "move_yz_m": 0.2,
    "end_theta_rad": 1.25 * np.pi,
    "bump_yz_m": 0.06,
    "bump_theta_rad": 0.8,
    "families": {"s-curve": 0.35, "perturbed": 0.25, "line": 0.1, "feasible": 0.3},
    "feasible": {"kp": 900.0, "kd": 60.0, "margin_rad": 0.05, "n_min": 1.0, "max_excursion_m": 0.3,
                 "retime_fraction": 0.5, "late_max": 0.6, "lift_max_m": 0.15},
}
FAMILIES = tuple(RANGES["families"])


def _key(n: int, seed: int, k: int) -> str:
    desc = json.dumps({"n": n, "seed": seed, "K": k, "version": GENERATOR_VERSION, "ranges": RANGES},
                      sort_keys=True, default=float)
    return hashlib.sha256(desc.encode()).hexdigest()[:16]


def cache_path(n: int, seed: int, k: int = K_DEFAULT) -> Path:
    """Where :func:`input_trajectories` caches its result."""
    return cache_dir() / "data" / f"pancake_inputs_{n}_{seed}_{k}_{_key(n, seed, k)}.npy"


def _s(tau: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cycloidal S-curve on [0, 1], clamped outside."""
    t = np.clip(tau, 0.0, 1.0)
    return t - np.sin(2.0 * np.pi * t) / (2.0 * np.pi)


def _reference_chunk(n: int, rng: np.random.Generator, k: int, fam: NDArray[np.int64]) -> NDArray[np.float64]:
    """Kinematic inputs (families 0 s-curve, 1 perturbed, 2 line) as float64 (n, k, 3)."""
    r = RANGES
    tau = np.arange(k, dtype=np.float64) / (k - 1)
    start = np.zeros((n, 3))
    start[:, :2] = rng.uniform(-r["start_yz_m"], r["start_yz_m"], size=(n, 2))
    tilt = rng.random(n) >= r["start_theta_zero_fraction"]
    start[tilt, 2] = rng.uniform(-r["start_theta_rad"], r["start_theta_rad"], size=int(tilt.sum()))
    end = start.copy()
    end[:, :2] += rng.uniform(-r["move_yz_m"], r["move_yz_m"], size=(n, 2))
    end[:, 2] = rng.uniform(-r["end_theta_rad"], r["end_theta_rad"], size=n)

    # timing of the S-curve per axis: full horizon, or a random sub-interval of at least 40 %
    t0 = np.zeros((n, 3))
    t1 = np.ones((n, 3))
    sub = (rng.random(n) < 0.5) & (fam != 2)
    dur = rng.uniform(0.4, 1.0, size=(n, 3))
    delay = rng.random((n, 3)) * (1.0 - dur)
    t0[sub] = delay[sub]
    t1[sub] = (delay + dur)[sub]
    s = _s((tau[None, :, None] - t0[:, None, :]) / (t1 - t0)[:, None, :])  # (n, k, 3)
    line = np.broadcast_to(tau[None, :, None], s.shape)
    prof = np.where((fam == 2)[:, None, None], line, s)
    x = start[:, None, :] + prof * (end - start)[:, None, :]

    pert = fam == 1
    m = int(pert.sum())
    if m:
        amp = np.array([r["bump_yz_m"], r["bump_yz_m"], r["bump_theta_rad"]])
        orders = np.arange(1, 4)
        coef = rng.uniform(-1.0, 1.0, size=(m, 3, 3)) * amp[None, None, :] / orders[None, :, None]
        basis = np.sin(np.pi * tau)[None, :] * np.sin(np.pi * orders[:, None] * tau[None, :])  # (3, k)
        x[pert] += np.einsum("nbc,bk->nkc", coef, basis)
    return x


def track_feasible(ref: NDArray[np.float64], dt: float = DT) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Track reference poses (n, k, 3) with accelerations kept inside the friction cone.

    P-D law on all three axes; the translational acceleration is projected onto the admissible
    set at every step (resultant ``g - u`` within ``arctan(mu) - margin`` of the spatula's normal,
    normal component at least ``n_min``); the attitude acceleration is free. Returns the
    positions and accelerations (n, k, 3) of the rollout (eq. 8, from the first pose at rest).
    """
    f = RANGES["feasible"]
    n, k, _ = ref.shape
    vref = np.gradient(ref, dt, axis=1)
    aref = np.gradient(vref, dt, axis=1)
    p = ref[:, 0].copy()
    v = np.zeros((n, 3))
    P = np.empty_like(ref)
    U = np.empty_like(ref)
    tanm = math.tan(math.atan(MU_MAX) - f["margin_rad"])
    for i in range(k):
        P[:, i] = p
        ud = aref[:, i] + f["kp"] * (ref[:, i] - p) + f["kd"] * (vref[:, i] - v)
        sn, cs = np.sin(p[:, 2]), np.cos(p[:, 2])
        fy, fz = -ud[:, 0], -G - ud[:, 1]
        nf = np.maximum(fy * sn - fz * cs, f["n_min"])
        tf = np.clip(fy * cs + fz * sn, -tanm * nf, tanm * nf)
        u = np.stack([-(tf * cs + nf * sn), -G - (tf * sn - nf * cs), ud[:, 2]], 1)
        U[:, i] = u
        p = p + dt * v + 0.5 * dt * dt * u
        v = v + dt * u
    return P, U


def _feasible_chunk(n: int, rng: np.random.Generator, k: int) -> NDArray[np.float64]:
    f = RANGES["feasible"]
    tau = np.arange(k, dtype=np.float64) / (k - 1)
    out: list[NDArray[np.float64]] = []
    have = 0
    while have < n:
        m = max(8, int(1.4 * (n - have)))
        fam = rng.choice(3, size=m, p=[0.5, 0.35, 0.15])
        ref = _reference_chunk(m, rng, k, fam)
        re = rng.random(m) < f["retime_fraction"]
        late = rng.uniform(0.0, f["late_max"], size=m)
        th0, th1 = ref[:, 0, 2], ref[:, -1, 2]
        retimed = th0[:, None] + (th1 - th0)[:, None] * _s((tau[None] - late[:, None]) / (1.0 - late[:, None]))
        ref[re, :, 2] = retimed[re]
        lift = rng.uniform(0.0, f["lift_max_m"], size=m) * re
        ref[:, :, 1] += lift[:, None] * np.sin(np.pi * tau)[None] ** 2
        P, _ = track_feasible(ref)
        ok = np.abs(P[:, :, :2] - P[:, :1, :2]).max((1, 2)) < f["max_excursion_m"]
        out.append(P[ok][: n - have])
        have += int(min(ok.sum(), n - have))
    return np.concatenate(out)


def generate_chunk(n: int, rng: np.random.Generator, k: int = K_DEFAULT,
                   return_family: bool = False) -> Any:
    """``n`` input trajectories (n, k, 3) float32 from ``rng`` (see the module docstring).

    With ``return_family`` also the family index of each (into :data:`FAMILIES`).
    """
    fam = rng.choice(len(FAMILIES), size=n, p=list(RANGES["families"].values()))
    x = np.empty((n, k, 3))
    kin = fam < 3
    x[kin] = _reference_chunk(int(kin.sum()), rng, k, fam[kin])
    nf = int((~kin).sum())
    if nf:
        x[~kin] = _feasible_chunk(nf, rng, k)
    x32 = x.astype(np.float32)
    return (x32, fam) if return_family else x32


def input_trajectories(n: int, seed: int = 0, k: int = K_DEFAULT, use_cache: bool = True,
                       progress: bool = True) -> NDArray[np.float32]:
    """``n`` input trajectories (n, k, 3) float32, reproducible from ``seed`` and cached."""
    if n < 1:
        raise SettingsError(f"n must be positive, got {n}")
    if k < 2:
        raise SettingsError(f"k must be at least 2, got {k}")
    path = cache_path(n, seed, k)
    cached = load_array(path, (n, k, 3), np.float32) if use_cache else None
    if cached is not None:
        return cached
    rng = np.random.default_rng(seed)
    out = np.empty((n, k, 3), dtype=np.float32)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc="pancake inputs", unit="traj")
    for i in range(0, n, CHUNK):
        m = min(CHUNK, n - i)
        out[i:i + m] = generate_chunk(m, rng, k)
        if bar is not None:
            bar.update(m)
    if bar is not None:
        bar.close()
    if use_cache:
        save_array(path, out)
    return out
