"""Reference trajectories of the spatula and the friction-cone angle phi (numpy, no torch).

Conventions (the seq2seq paper, Section 4.1):

* a pose is ``p = [y, z, theta]`` (metres, metres, radians) in the vertical y-z plane; samples are
  ``dt = 1 ms`` apart and a trajectory has ``K = 500`` samples (0.5 s), sample ``k`` at ``t = k dt``;
* ``theta`` is the spatula's inclination, counter-clockwise from the +y axis;
* ``phi`` (eq. 16) is the angle between the spatula's inward normal ``[sin theta, -cos theta]``
  (pointing from the pancake into the spatula) and the resultant ``g - u`` of gravity
  ``g = [0, -9.8]`` and the inertial force per unit mass ``-u``:
  ``phi = wrap(arg(g - u) + pi/2 - theta)``. Level spatula at rest: ``phi = 0``; spatula tilted
  by ``theta`` at rest: ``phi = -theta``, so ``|phi| = |theta|``. The pancake stays while
  ``|phi| < arctan(mu_max)`` (eq. 15, ``mu_max = 1``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_count, as_float_array, as_real
from genplan.errors import NonFiniteError, SettingsError, ShapeError

#: the paper's sampling interval (s) and sequence length
DT = 1e-3
K = 500
#: gravity (m/s^2); g = [0, -G]
G = 9.8
#: static friction coefficient of the paper
MU_MAX = 1.0
#: most samples of a trajectory made here: the longest run of the 1 kHz loop (``MAX_TICKS`` of
#: rust/core/src/control.rs, genplan.control.MAX_TICKS)
MAX_K = 10_000_000

__all__ = ["DT", "K", "G", "MU_MAX", "MAX_K", "s_curve", "s_curve_profile", "linear", "j1_problems", "phi", "wrap_angle"]


def wrap_angle(a: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped to (-pi, pi]."""
    a = as_float_array(a, "a")
    w = np.mod(a + np.pi, 2.0 * np.pi) - np.pi  # [-pi, pi)
    return np.where(w <= -np.pi, w + 2.0 * np.pi, w)


def _pose(name: str, p: ArrayLike) -> NDArray[np.float64]:
    a = as_float_array(p, name)
    if a.shape != (3,):
        raise ShapeError(f"{name} must be a pose [y, z, theta] of shape (3,), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{name} must be finite, got {a.tolist()}")
    return a


def s_curve_profile(K: int = K) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The normalised S-curve ``s(tau)``, ``ds/dtau``, ``d2s/dtau2`` at ``tau = k / (K - 1)``.

    Cycloidal (sine-acceleration) S-curve: ``s = tau - sin(2 pi tau) / (2 pi)``. Velocity and
    acceleration are zero at both ends (smooth start and stop, finite jerk); the acceleration is
    one sine period (positive while speeding up, negative while slowing down). ``K``: an
    integer in [2, :data:`MAX_K`] (else SettingsError).
    """
    K = as_count(K, "K", minimum=2, maximum=MAX_K)
    tau = np.arange(K, dtype=np.float64) / (K - 1)
    w = 2.0 * np.pi
    s = tau - np.sin(w * tau) / w
    ds = 1.0 - np.cos(w * tau)
    d2s = w * np.sin(w * tau)
    s[-1] = 1.0  # exact end point
    return s, ds, d2s


def s_curve(p_start: ArrayLike, p_end: ArrayLike, K: int = K, dt: float = DT) -> NDArray[np.float64]:
    """Positions ``[y, z, theta]`` (shape (K, 3), float64) of an S-curve move from rest to rest.

    The move takes ``(K - 1) * dt`` seconds: sample 0 is exactly ``p_start`` and sample ``K - 1``
    exactly ``p_end``; velocity and acceleration are zero at both ends (see
    :func:`s_curve_profile`). ``theta`` is interpolated as given (no wrapping), so
    ``p_end[2] = pi`` means half a turn counter-clockwise from ``p_start[2] = 0``.
    ``dt`` only sets the duration; positions do not depend on it. Any finite poses work, however
    far apart (no overflow, every sample between the two); ``K``: an integer in
    [2, :data:`MAX_K`].
    """
    a = _pose("p_start", p_start)
    b = _pose("p_end", p_end)
    dt = as_real(dt, "dt", error=SettingsError)
    if not (np.isfinite(dt) and dt > 0):
        raise SettingsError(f"dt must be positive, got {dt}")
    s, _, _ = s_curve_profile(K)
    return _interpolate(a, b, s)


def _interpolate(a: NDArray[np.float64], b: NDArray[np.float64], s: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a + s (b - a)`` (len(s), 3) for ``s`` from 0 to 1, with row 0 exactly ``a``, the last row
    exactly ``b``, and no overflow: where ``b - a`` overflows (finite poses of opposite signs
    beyond 9e307) the columns are ``(1 - s) a + s b``, kept between ``a`` and ``b``."""
    with np.errstate(over="ignore", invalid="ignore"):
        x = a[None, :] + s[:, None] * (b - a)[None, :]
        far = ~np.all(np.isfinite(x), axis=0)
        if far.any():
            x[:, far] = (1.0 - s)[:, None] * a[None, far] + s[:, None] * b[None, far]
            x[:, far] = np.clip(x[:, far], np.minimum(a, b)[far], np.maximum(a, b)[far])
    x[0] = a
    x[-1] = b  # exactly, not a + 1 * (b - a), which rounds when |b| << |a|
    return x


def linear(p_start: ArrayLike, p_end: ArrayLike, K: int = K) -> NDArray[np.float64]:
    """Constant-velocity move (K, 3) from ``p_start`` (sample 0) to ``p_end`` (sample K - 1).

    The paper's input for J2 (Section 5.2): "a uniform linear motion with constant velocity from
    the initial position to the end position". It starts and stops abruptly.
    """
    a = _pose("p_start", p_start)
    b = _pose("p_end", p_end)
    K = as_count(K, "K", minimum=2, maximum=MAX_K)
    tau = np.arange(K, dtype=np.float64) / (K - 1)
    return _interpolate(a, b, tau)


def j1_problems() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The seq2seq paper's 27 J1 problems (Section 4.3): the S-curve inputs (27, K, 3) from the
    origin at rest and their end poses (27, 3), y, z in {-0.1, 0, 0.1} m, theta in {-pi, 0, pi},
    grouped by theta."""
    yz = (-0.1, 0.0, 0.1)
    p_end = np.array([[y, z, t] for t in (-np.pi, 0.0, np.pi) for y in yz for z in yz])
    x_in = np.stack([s_curve(np.zeros(3), pe) for pe in p_end])
    return x_in, p_end


def phi(theta: ArrayLike, acc: ArrayLike, g: float = G) -> NDArray[np.float64]:
    """The friction-cone angle of eq. 16 (radians, wrapped to (-pi, pi]), vectorised.

    ``theta`` has shape ``S`` and ``acc`` shape ``S + (2,)`` or ``S + (3,)`` (``[a_y, a_z(,
    a_theta)]``; ``a_theta`` is ignored), with numpy broadcasting over ``S``. Returns
    ``wrap(atan2(-g - a_z, -a_y) + pi/2 - theta)``: 0 for a level spatula at rest, ``-theta`` for
    a spatula tilted by ``theta`` at rest. The pancake stays while ``|phi| < arctan(mu_max)``.

    Refused, naming the argument: values that are not real numbers and shapes that do not
    broadcast (:class:`~genplan.errors.ShapeError`), NaN or inf in ``theta``, ``[a_y, a_z]`` or
    ``g`` (:class:`~genplan.errors.NonFiniteError`).
    """
    th = as_float_array(theta, "theta")
    u = as_float_array(acc, "acc")
    g = as_real(g, "g")
    if u.ndim < 1 or u.shape[-1] not in (2, 3):
        raise ShapeError(f"acc must have a last axis of 2 ([a_y, a_z]) or 3 ([a_y, a_z, a_theta]), got shape {u.shape}")
    try:
        shape = np.broadcast_shapes(th.shape, u.shape[:-1])
    except ValueError:
        raise ShapeError(f"theta of shape {th.shape} and acc of shape {u.shape} do not broadcast: theta takes "
                         f"acc's leading shape {u.shape[:-1]} (or one that broadcasts with it)") from None
    _check_finite("theta", th)
    _check_finite("acc", u[..., :2])
    if not np.isfinite(g):
        raise NonFiniteError(f"g must be finite, got {g}")
    th_flat = np.ascontiguousarray(np.broadcast_to(th, shape).reshape(-1))
    u_flat = np.ascontiguousarray(np.broadcast_to(u[..., :2], (*shape, 2)).reshape(-1, 2))
    # one definition of eq. 16: the 1 kHz loop's (rust/core/src/control.rs, `phi`); the torch
    # twin in pancake/physics.py (differentiable) is cross-checked against it in the tests
    return np.asarray(_core.pancake_phi(th_flat, u_flat, g)).reshape(shape)


def _check_finite(name: str, a: NDArray[np.float64]) -> None:
    if not np.all(np.isfinite(a)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise NonFiniteError(f"{name}: element {idx} is not finite ({a[idx]})")
