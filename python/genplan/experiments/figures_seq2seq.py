"""PNG figures like the paper's Figs. 5-9 and 11 (matplotlib, Agg backend, imported lazily)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.experiments.common import save_figure
from genplan.pancake.trajectories import DT, MU_MAX

COLORS = {"latent": "tab:blue", "random-latent": "tab:orange", "direct-u": "tab:green", "casadi": "tab:red"}
LABELS = {"latent": "case 1: latent (encoder z)", "random-latent": "case 2: latent (z ~ N(0, I))",
          "direct-u": "case 3: direct U", "casadi": "CasADi + IPOPT"}


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def objective_curves(curves: Mapping[str, tuple[NDArray[np.float64], NDArray[np.float64]]], path: Path,
                     title: str, level: float | None = 1e-3) -> Path:
    """Fig. 5: mean objective (and its 95 % confidence band) against the update count.

    On the log scale a band reaching below zero is drawn down to 1 % of the mean.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, (mean, half) in curves.items():
        it = np.arange(len(mean))
        ax.plot(it, mean, color=COLORS.get(name), label=LABELS.get(name, name))
        lo = np.maximum(mean - half, 0.01 * mean)
        ax.fill_between(it, lo, mean + half, color=COLORS.get(name), alpha=0.2, lw=0)
    if level is not None:
        ax.axhline(level, color="k", ls=":", lw=1, label=f"{level:g}")
    ax.set_yscale("log")
    ax.set_xlabel("update")
    ax.set_ylabel("objective (mean of problems)")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path


def trajectories(p: NDArray[np.float64], phi: NDArray[np.float64], p_end: NDArray[np.float64], path: Path,
                 title: str, mu_max: float = MU_MAX) -> Path:
    """Figs. 6-8: (a) time-position, (b) the y-z plane with targets, (c) phi with the cone band."""
    plt = _plt()
    t = np.arange(p.shape[1]) * DT
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    cmap = plt.get_cmap("viridis", len(p))
    for i in range(len(p)):
        c = cmap(i)
        axes[0].plot(t, p[i, :, 0], color=c, ls="-", lw=1)
        axes[0].plot(t, p[i, :, 1], color=c, ls="--", lw=1)
        axes[1].plot(p[i, :, 0], p[i, :, 1], color=c, lw=1)
        axes[1].plot(p_end[i, 0], p_end[i, 1], "x", color=c, ms=8)
        axes[2].plot(t, np.degrees(phi[i]), color=c, lw=1)
    ax2 = axes[0].twinx()
    for i in range(len(p)):
        ax2.plot(t, p[i, :, 2], color=cmap(i), ls=":", lw=1)
    axes[0].set_xlabel("t [s]")
    axes[0].set_ylabel("y (solid), z (dashed) [m]")
    ax2.set_ylabel("theta (dotted) [rad]")
    axes[0].set_title("(a) time-position")
    axes[1].set_xlabel("y [m]")
    axes[1].set_ylabel("z [m]")
    axes[1].set_aspect("equal", adjustable="datalim")
    axes[1].set_title("(b) y-z plane (x: targets)")
    lim = math.degrees(math.atan(mu_max))
    axes[2].axhspan(-lim, lim, color="tab:blue", alpha=0.15, lw=0)
    axes[2].set_xlabel("t [s]")
    axes[2].set_ylabel("phi [deg]")
    axes[2].set_title("(c) phi (cone: blue band)")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def rmse_bars(rows: Sequence[tuple[str, float, float]], path: Path, title: str) -> Path:
    """Fig. 9: end-pose RMSE per method (position mm, attitude deg), log scale."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(8.5, 3.8))
    names = [r[0] for r in rows]
    x = np.arange(len(rows))
    for ax, col, unit in ((axes[0], 1, "position [mm]"), (axes[1], 2, "attitude [deg]")):
        vals = [max(r[col], 1e-9) for r in rows]
        ax.bar(x, vals, color=[COLORS.get(n, "gray") for n in names])
        ax.set_xticks(x, [n for n in names], rotation=20, fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel(f"end RMSE, {unit}")
        for xi, v in zip(x, vals):
            ax.text(xi, v, f"{v:.3g}", ha="center", va="bottom", fontsize=7)
        ax.grid(alpha=0.3, axis="y", which="both")
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path


def j2_snapshots(snaps: Mapping[int, Mapping[str, NDArray[np.float64]]], path: Path, title: str,
                 v_lim: Sequence[float] = (1.5, 1.5, 4.5), mu_max: float = MU_MAX,
                 labels: Mapping[int, str] | None = None) -> Path:
    """Fig. 11: the J2 trajectory at several updates: pose, velocity (limits dashed), phi, y-z."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    cmap = plt.get_cmap("plasma", len(snaps) + 1)
    names = ("y", "z", "theta")
    styles = ("-", "--", ":")
    for j, (it, s) in enumerate(sorted(snaps.items())):
        c = cmap(j)
        name = (labels or {}).get(it, f"update {it}")
        p, v, ph = s["p"][0], s["v"][0], s["phi"][0]
        t = np.arange(len(p)) * DT
        for a in range(3):
            axes[0, 0].plot(t, p[:, a], color=c, ls=styles[a], lw=1.2,
                            label=name if a == 0 else None)
            axes[0, 1].plot(t, v[:, a], color=c, ls=styles[a], lw=1.2)
        axes[1, 0].plot(t, np.degrees(ph), color=c, lw=1.2, label=name)
        axes[1, 1].plot(p[:, 0], p[:, 1], color=c, lw=1.2, label=name)
    for a in range(3):
        for sgn in (1, -1):
            axes[0, 1].axhline(sgn * v_lim[a], color="gray", ls=styles[a], lw=0.8)
    lim = math.degrees(math.atan(mu_max))
    axes[1, 0].axhspan(-lim, lim, color="tab:blue", alpha=0.15, lw=0)
    axes[0, 0].set_title("pose: y [m] solid, z [m] dashed, theta [rad] dotted")
    axes[0, 1].set_title("velocity (grey: v_lim)")
    axes[1, 0].set_title("phi [deg] (cone: blue band)")
    axes[1, 1].set_title("y-z plane [m]")
    axes[1, 1].set_aspect("equal", adjustable="datalim")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    for ax in (axes[0, 0], axes[0, 1], axes[1, 0]):
        ax.set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title + "  (" + ", ".join(names) + ")")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def time_bars(rows: Sequence[tuple[str, float]], path: Path, title: str) -> Path:
    """Time to a solution per problem (ms), log scale."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    x = np.arange(len(rows))
    vals = [r[1] for r in rows]
    ax.bar(x, vals, color=[COLORS.get(r[0].split(" ")[0], "gray") for r in rows])
    ax.set_xticks(x, [r[0] for r in rows], rotation=15, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("ms per problem")
    for xi, v in zip(x, vals):
        ax.text(xi, v, f"{v:.3g}", ha="center", va="bottom", fontsize=8)
    ax.set_title(title)
    ax.grid(alpha=0.3, axis="y", which="both")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path
