"""Figures. Every function takes an optional matplotlib ``ax`` and returns the axes it drew on.

This is the only module that imports matplotlib at import time; computing
modules never open a figure.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.axes import Axes


def _axes(ax: Axes | None, **subplot_kw: object) -> Axes:
    """The given axes, or new ones on a new figure."""
    if ax is not None:
        return ax
    _, new = plt.subplots(subplot_kw=subplot_kw or None)
    return new


# === section: CTCR stability charts (issue 3) ===

# === section: spectrum, dominant-root maps (issue 4) ===
def plot_dominant_surface(result: Any, ax: Axes | None = None) -> Axes:
    """Surface of Re(dominant root) over the delay plane with the plane Re s = 0 (paper Fig. dominant).

    ``result`` is a :class:`delayform.spectrum.DominantRootMap`; ``ax``, when
    given, must be a 3-D axes. The stability boundary of the CTCR chart is
    where the surface cuts the black plane.
    """
    import numpy as np

    ax = _axes(ax, projection="3d")
    T1, T2 = np.meshgrid(result.tau1_values, result.tau2_values, indexing="ij")
    ax.plot_surface(T1, T2, result.real, cmap="viridis", linewidth=0, antialiased=True, alpha=0.9)
    ax.plot_surface(T1, T2, np.zeros_like(T1), color="black", alpha=0.35, linewidth=0)
    ax.set_xlabel(r"$\tau_1$ (s)")
    ax.set_ylabel(r"$\tau_2$ (s)")
    ax.set_zlabel(r"Re$(s_{dom})$")
    ax.set_title("Real part of the dominant root")
    return ax


def plot_dominant_contour(result: Any, ax: Axes | None = None, *, levels: int = 20) -> Axes:
    """Contour map of Re(dominant root) over the delay plane (paper Fig. contour).

    The thick black line is Re = 0, the stability boundary; the deepest
    valleys are the fastest-settling delays (delay scheduling).
    """
    ax = _axes(ax)
    T1, T2 = _meshgrid_ij(result.tau1_values, result.tau2_values)
    filled = ax.contourf(T1, T2, result.real, levels=levels, cmap="viridis")
    ax.figure.colorbar(filled, ax=ax, label=r"Re$(s_{dom})$")
    if result.real.min() < 0.0 < result.real.max():
        ax.contour(T1, T2, result.real, levels=[0.0], colors="black", linewidths=2.0)
    ax.set_xlabel(r"$\tau_1$ (s)")
    ax.set_ylabel(r"$\tau_2$ (s)")
    ax.set_title("Contours of Re(dominant root); black: Re = 0")
    return ax


def _meshgrid_ij(a: Any, b: Any) -> tuple[Any, Any]:
    import numpy as np

    return np.meshgrid(a, b, indexing="ij")


# === section: formation and simulation figures (issue 5) ===
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402


def plot_trajectory_xy(traj: Any, ax: Any = None) -> Any:
    """x and y of every agent versus time, two panels (paper Figs. xy1 and xy2).

    ``ax`` is a pair of axes (x panel, y panel) or None for a new figure;
    returns the pair.
    """
    if ax is None:
        _, ax = plt.subplots(2, 1, sharex=True)
    ax_x, ax_y = ax
    for i in range(traj.n):
        label = f"agent {traj.labels[i]}" if traj.labels else f"agent {i}"
        ax_x.plot(traj.times, traj.positions[:, i, 0], lw=1, label=label)
        ax_y.plot(traj.times, traj.positions[:, i, 1], lw=1)
    ax_x.set_ylabel("x")
    ax_y.set_ylabel("y")
    ax_y.set_xlabel("time (s)")
    ax_x.set_title(f"{traj.model}, (tau1, tau2) = ({traj.tau1:g}, {traj.tau2:g})")
    if traj.n <= 12:
        ax_x.legend(fontsize="small", ncol=2)
    return ax_x, ax_y


def _heading_marks(traj: Any, k: int, length: float) -> Any:
    """Segments from each robot along its heading at sample k (the paper's short blue lines)."""
    p = traj.positions[k]
    d = np.column_stack([np.cos(traj.headings[k]), np.sin(traj.headings[k])]) * length
    return np.stack([p, p + d], axis=1)


def plot_trajectory_traces(traj: Any, ax: Axes | None = None, *, snapshots: int = 6) -> Axes:
    """Paths in the plane with heading marks at ``snapshots`` instants (paper Fig. traces)."""
    from matplotlib.collections import LineCollection

    ax = _axes(ax)
    for i in range(traj.n):
        ax.plot(traj.positions[:, i, 0], traj.positions[:, i, 1], lw=0.8, color="0.6")
    extent = float(np.ptp(traj.positions.reshape(-1, 2), axis=0).max()) or 1.0
    for k in np.linspace(0, traj.times.size - 1, max(snapshots, 2)).round().astype(int):
        ax.add_collection(LineCollection(_heading_marks(traj, k, 0.04 * extent), colors="tab:blue"))
        ax.plot(traj.positions[k, :, 0], traj.positions[k, :, 1], "k.", ms=3)
    final = traj.positions[-1]
    ax.plot(final[:, 0], final[:, 1], "o", mfc="none", color="tab:red", label="final")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"traces, (tau1, tau2) = ({traj.tau1:g}, {traj.tau2:g})")
    return ax


def save_trajectory_gif(traj: Any, path: Any, *, frames: int = 80, fps: int = 15) -> Any:
    """Animated GIF of the robots moving into formation (matplotlib PillowWriter); returns the path."""
    from pathlib import Path

    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.collections import LineCollection

    path = Path(path)
    fig, ax = plt.subplots(figsize=(4, 4))
    pts = traj.positions.reshape(-1, 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * float((hi - lo).max() or 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    length = 0.04 * float((hi - lo).max() or 1.0)
    dots = ax.plot([], [], "o", ms=4, color="tab:red")[0]
    marks = LineCollection([], colors="tab:blue")
    ax.add_collection(marks)
    title = ax.set_title("")
    samples = np.linspace(0, traj.times.size - 1, max(frames, 2)).round().astype(int)

    def draw(k: int) -> list[Any]:
        dots.set_data(traj.positions[k, :, 0], traj.positions[k, :, 1])
        marks.set_segments(_heading_marks(traj, k, length))
        title.set_text(f"t = {traj.times[k]:.1f} s")
        return [dots, marks, title]

    anim = FuncAnimation(fig, draw, frames=samples, blit=False)
    anim.save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path
