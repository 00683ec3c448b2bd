"""genplan.pancake.data: seeded, cached, varied training inputs over a wider range than the
evaluation's."""

import math

import numpy as np
import pytest

from genplan.errors import SettingsError
from genplan.pancake import data as D


def test_inputs_are_reproducible_cached_and_regenerated_when_corrupt(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path))
    a = D.input_trajectories(300, seed=4, progress=False)
    assert a.shape == (300, 500, 3) and a.dtype == np.float32 and np.all(np.isfinite(a))
    files = list((tmp_path / "data").glob("pancake_inputs_300_4_500_*.npy"))
    assert len(files) == 1
    np.testing.assert_array_equal(a, D.input_trajectories(300, seed=4, progress=False))
    files[0].write_bytes(b"broken")
    np.testing.assert_array_equal(a, D.input_trajectories(300, seed=4, progress=False))
    b = D.input_trajectories(300, seed=5, progress=False, use_cache=False)
    assert not np.allclose(a, b)
    with pytest.raises(SettingsError, match="n must be positive"):
        D.input_trajectories(0)


def test_inputs_cover_more_than_the_evaluation_range() -> None:
    x, fam = D.generate_chunk(4000, np.random.default_rng(0), return_family=True)
    x = x.astype(np.float64)
    share = np.bincount(fam, minlength=4) / len(fam)
    np.testing.assert_allclose(share, list(D.RANGES["families"].values()), atol=0.03)
    move = x[:, -1] - x[:, 0]
    # evaluation: moves of +-0.1 m and end attitudes in [-pi, pi]
    assert move[:, 0].min() < -0.15 and move[:, 0].max() > 0.15
    assert move[:, 1].min() < -0.15 and move[:, 1].max() > 0.15
    assert x[:, -1, 2].min() < -1.1 * math.pi and x[:, -1, 2].max() > 1.1 * math.pi
    # varied shapes: the perturbed ones detour (leave the box spanned by start and end) ...
    lo, hi = np.minimum(x[:, 0], x[:, -1]), np.maximum(x[:, 0], x[:, -1])
    detour = ((x < lo[:, None] - 1e-3) | (x > hi[:, None] + 1e-3)).any((1, 2))
    assert detour[fam == 1].mean() > 0.8 and detour[fam == 0].mean() == 0.0
    # ... the lines move at constant velocity (the J2 input), all others start at rest
    v0 = np.abs(x[:, 1] - x[:, 0]).max(-1) / 1e-3
    v_mid = np.abs(x[:, 251] - x[:, 250]).max(-1) / 1e-3
    assert np.all(np.isclose(v0, v_mid, rtol=1e-3)[fam == 2])
    assert np.all(v0[fam != 2] < 0.5)  # one 1 ms step from rest
    # some start tilted, most level
    assert 0.2 < (np.abs(x[:, 0, 2]) > 1e-6).mean() < 0.4


def test_feasible_family_keeps_the_pancake() -> None:
    from genplan.pancake.physics import f_dyn_np, phi_np, rollout_np

    rng = np.random.default_rng(1)
    ref = np.stack([np.linspace(0, 1, 500)[:, None] * [0.1, 0.0, a] for a in (0.0, 1.0, -3.0, 3.5)])
    p, u = D.track_feasible(ref)
    # the rollout is eq. 8 from rest, and every step is inside the cone with the margin
    for i in range(len(p)):
        x = rollout_np(u[i], np.r_[p[i, 0], 0, 0, 0])
        np.testing.assert_allclose(p[i], x[:, :3], atol=1e-9)
    ph = phi_np(p[..., 2], u)
    assert np.abs(ph).max() <= math.atan(1.0) - 0.05 + 1e-9
    assert np.all(f_dyn_np(ph) == 0)
    # the family in the data: feasible flips included, excursions bounded
    x, fam = D.generate_chunk(400, rng, return_family=True)
    f = x[fam == 3].astype(np.float64)
    assert len(f) > 80
    assert np.abs(f[:, :, :2] - f[:, :1, :2]).max() < 0.3
    assert (np.abs(f[:, -1, 2] - f[:, 0, 2]) > 2.5).mean() > 0.1
