"""Figures. Every function takes an optional matplotlib ``ax`` and returns the axes it drew on.

This is the only module that imports matplotlib at import time; computing
modules never open a figure. It is a leaf of the package: it imports no
other delayform module but the file helper :mod:`delayform._files` (every
file is written complete or not at all) and reads the results it draws by their attributes,
so every result's ``.plot()`` may call it without an import cycle (data flow
topology -> factors -> analysis -> design -> simulation -> report stays one
way; ``tests/test_architecture.py`` checks it).
"""

from __future__ import annotations

import re
import warnings

import matplotlib.pyplot as plt
from matplotlib.axes import Axes


def _axes(ax: Axes | None, **subplot_kw: object) -> Axes:
    """The given axes, or new ones on a new figure."""
    if ax is not None:
        return ax
    _, new = plt.subplots(subplot_kw=subplot_kw or None)
    return new


# === section: CTCR stability charts ===
from collections.abc import Mapping, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from delayform._files import atomic_path  # noqa: E402


def stability_chart(
    smap: Any,
    ax: Axes | None = None,
    points: Mapping[str, tuple[float, float]] | None = None,
    *,
    resolution: int = 400,
    shade: str = "0.78",
    kernel_color: str = "red",
    offspring_color: str = "blue",
) -> Axes:
    """The CTCR stability chart of a :class:`~delayform.analysis.ctcr.stability_map.StabilityMap` (paper, Fig. 3).

    Kernel curves red, offspring curves blue (Definitions "Kernel curves" and
    "Offspring curves"), the stable region (NU = 0) shaded, and optional
    labelled delay pairs such as the paper's points a-e
    (:data:`delayform.analysis.ctcr.stability_map.PAPER_POINTS`).

    Parameters
    ----------
    smap
        The map to draw.
    ax
        Axes to draw on; new ones when None.
    points
        Label -> (tau1, tau2) to mark.
    resolution
        Grid cells per axis used to shade the stable region.

    Returns
    -------
    Axes
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    ax = _axes(ax)
    t1 = (np.arange(resolution) + 0.5) * smap.tau1_max / resolution
    t2 = (np.arange(resolution) + 0.5) * smap.tau2_max / resolution
    stable = smap.is_stable(t1[None, :], t2[:, None]).astype(float)
    handles: list[Any] = []
    many = len(smap.curves) > _MANY_CURVES
    # many curves (a large team) would cover the chart: thinner, translucent lines, the stable
    # region drawn over them and its boundary outlined, so the reader still sees it
    width = 0.9 if not many else max(0.15, 0.9 * (_MANY_CURVES / len(smap.curves)) ** 0.5)
    alpha = 1.0 if not many else 0.35
    for kernel, color, label in ((False, offspring_color, "offspring curves"), (True, kernel_color, "kernel curves")):
        lines = [np.column_stack([c.tau1, c.tau2]) for c in smap.curves if c.is_kernel == kernel]
        if lines:
            ax.add_collection(LineCollection(lines, colors=color, linewidths=width, alpha=alpha, zorder=1))
            handles.append(Line2D([], [], color=color, lw=1.2, label=f"{label} ({len(lines)})"))
    if stable.any():
        ax.contourf(t1, t2, stable, levels=[0.5, 1.5], colors=[shade], alpha=0.85 if many else 1.0,
                    zorder=2 if many else 0)  # fmt: skip
        if many and not stable.all():
            ax.contour(t1, t2, stable, levels=[0.5], colors="black", linewidths=0.8, zorder=3)
        handles.insert(0, Patch(facecolor=shade, edgecolor="black" if many else shade, label="stable (NU = 0)"))
    for name, (a, b) in (points or {}).items():
        ax.plot([a], [b], "ko", ms=4, zorder=4)
        ax.annotate(f"{name}", (a, b), xytext=(4, 4), textcoords="offset points", fontweight="bold", zorder=4)
    ax.set_xlim(0.0, smap.tau1_max)
    ax.set_ylim(0.0, smap.tau2_max)
    ax.set_xlabel(r"$\tau_1$ (s), position delay")
    ax.set_ylabel(r"$\tau_2$ (s), velocity delay")
    ax.set_title("CTCR stability chart (shaded: stable)")
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize="small", framealpha=0.9)
    return ax


#: above this many crossing curves the chart thins its lines and draws the stable region on top
_MANY_CURVES = 150


class MissingGlyphWarning(UserWarning):
    """A label has characters the figure font cannot draw; they show as empty boxes.

    One warning per saved figure, listing the characters, instead of one
    matplotlib "Glyph ... missing" warning per character and format (the
    command line prints it as one line).
    """


#: matplotlib's message for a character its fonts lack: "Glyph 28450 (...) missing from font(s) DejaVu Sans."
_GLYPH_MISSING = re.compile(r"Glyph (\d+) .*missing from font")


def savefig_noting_glyphs(fig: Figure, tmp: object, *, where: str, **kwargs: object) -> None:
    """``fig.savefig(tmp, **kwargs)``, the missing-glyph warnings gathered into one.

    ``tmp`` is a temporary path of :func:`delayform._files.atomic_path` or an
    in-memory buffer: this function never writes a user's file directly.

    The default font, DejaVu Sans (shipped with matplotlib), covers Latin,
    Greek, Cyrillic and most symbols; other scripts (CJK, emoji) are not in any
    font matplotlib ships, so the text is kept and the user is told once.
    Other warnings pass through unchanged.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fig.savefig(tmp, **kwargs)  # type: ignore[arg-type]
    missing: list[str] = []
    for w in caught:
        match = _GLYPH_MISSING.search(str(w.message))
        if match:
            missing.append(chr(int(match.group(1))))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if missing:
        chars = "".join(dict.fromkeys(missing))
        warnings.warn(MissingGlyphWarning(
            f"the figure font (DejaVu Sans) has no glyph for {chars!r}; in {where} they are drawn as empty boxes"
        ), stacklevel=3)  # fmt: skip


def save_figure(
    fig_or_ax: Figure | Axes, path_stem: str | Path, *, formats: Sequence[str] = ("png", "svg"), dpi: int = 150
) -> list[Path]:
    """Save a figure (or the figure of an axes) as ``path_stem.<fmt>`` for each format.

    Parent directories are created. Returns the written paths, in ``formats`` order.
    Characters of a label the font lacks give one :class:`MissingGlyphWarning`.
    """
    fig = fig_or_ax if isinstance(fig_or_ax, Figure) else fig_or_ax.figure
    stem = Path(path_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    tight = None  # the padded box of the figure as the first format drew it
    for fmt in formats:
        path = stem.with_name(f"{stem.name}.{fmt}")
        with atomic_path(path) as tmp:
            if tight is None:
                savefig_noting_glyphs(fig, tmp, where=f"{stem.name}.*", format=fmt, dpi=dpi, bbox_inches="tight")
            else:
                # one format is enough to find the missing glyphs: the others would repeat them
                with warnings.catch_warnings():
                    warnings.filterwarnings("ignore", message="Glyph .* missing from font")
                    fig.savefig(tmp, format=fmt, dpi=dpi, bbox_inches=tight)
        paths.append(path)
        if tight is None and len(formats) > 1:
            # a "tight" save draws the figure twice (once to lay it out and find its box, once to
            # render); the other formats take that box, padded as savefig pads it, and draw once
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Glyph .* missing from font")
                tight = fig.get_tightbbox().padded(plt.rcParams["savefig.pad_inches"])
    return paths


# === section: spectrum, dominant-root maps ===
def plot_dominant_surface(result: Any, ax: Axes | None = None) -> Axes:
    """Surface of Re(dominant root) over the delay plane with the plane Re s = 0 (paper, Fig. 8).

    ``result`` is a :class:`delayform.analysis.roots.dominant.DominantRootMap`; ``ax``, when
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
    ax.set_zlabel(r"Re$(s_{dom})$ (1/s)")
    ax.set_title("Real part of the dominant root")
    return ax


def plot_dominant_contour(result: Any, ax: Axes | None = None, *, levels: int = 20) -> Axes:
    """Contour map of Re(dominant root) over the delay plane (paper, Fig. 9).

    The thick black line is Re = 0, the stability boundary; the deepest
    valleys are the fastest-settling delays (delay scheduling).
    """
    ax = _axes(ax)
    T1, T2 = _meshgrid_ij(result.tau1_values, result.tau2_values)
    filled = ax.contourf(T1, T2, result.real, levels=levels, cmap="viridis")
    ax.figure.colorbar(filled, ax=ax, label=r"Re$(s_{dom})$ (1/s)")
    if result.real.min() < 0.0 < result.real.max():
        ax.contour(T1, T2, result.real, levels=[0.0], colors="black", linewidths=2.0)
    ax.set_xlabel(r"$\tau_1$ (s)")
    ax.set_ylabel(r"$\tau_2$ (s)")
    ax.set_title("Contours of Re(dominant root); black: Re = 0")
    return ax


def _meshgrid_ij(a: Any, b: Any) -> tuple[Any, Any]:
    import numpy as np

    return np.meshgrid(a, b, indexing="ij")


# === section: formation and simulation figures ===
from typing import Any  # noqa: E402



def agent_colors(n: int) -> Any:
    """``n`` distinguishable colours: tab10 up to 10 agents, tab20 up to 20, then a continuous map."""
    if n <= 10:
        return plt.get_cmap("tab10")(np.arange(n))
    if n <= 20:
        return plt.get_cmap("tab20")(np.arange(n))
    return plt.get_cmap("turbo")(np.linspace(0.05, 0.95, n))


def _agent_names(traj: Any) -> list[str]:
    """People count from 1: agent i (index i - 1), whatever the topology's labels."""
    return [f"agent {i + 1}" for i in range(traj.n)]


def plot_trajectory_xy(traj: Any, ax: Any = None) -> Any:
    """x and y of every agent versus time, two panels (paper, Figs. 5 and 7).

    ``ax`` is a pair of axes (x panel, y panel) or None for a new figure;
    returns the pair. Agents are numbered from 1; with up to 20 agents the
    legend sits to the right of the panels, never over the curves.
    """
    if ax is None:
        _, ax = plt.subplots(2, 1, sharex=True)
    ax_x, ax_y = ax
    colors = agent_colors(traj.n)
    names = _agent_names(traj)
    for i in range(traj.n):
        ax_x.plot(traj.times, traj.positions[:, i, 0], lw=1, color=colors[i], label=names[i])
        ax_y.plot(traj.times, traj.positions[:, i, 1], lw=1, color=colors[i])
    ax_x.set_ylabel("x (m)")
    ax_y.set_ylabel("y (m)")
    ax_y.set_xlabel("time (s)")
    ax_x.set_title(f"{traj.model}, (tau1, tau2) = ({traj.tau1:g}, {traj.tau2:g}) s")
    if traj.n <= 20:
        ax_x.legend(fontsize="small", ncol=1 if traj.n <= 10 else 2, loc="upper left",
                    bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # fmt: skip
    return ax_x, ax_y


def _heading_marks(traj: Any, k: int, length: float) -> Any:
    """Segments from each robot along its heading at sample k (the paper's short blue lines)."""
    p = traj.positions[k]
    d = np.column_stack([np.cos(traj.headings[k]), np.sin(traj.headings[k])]) * length
    return np.stack([p, p + d], axis=1)


def plot_trajectory_traces(traj: Any, ax: Axes | None = None, *, snapshots: int = 6) -> Axes:
    """Paths in the plane with heading marks at ``snapshots`` instants (paper, Fig. 6).

    Grey lines are the paths; black dots the positions at the snapshot
    times, each with a short blue line along the robot's heading; open red
    circles the final positions. The legend says so.
    """
    from matplotlib.collections import LineCollection

    ax = _axes(ax)
    for i in range(traj.n):
        ax.plot(traj.positions[:, i, 0], traj.positions[:, i, 1], lw=0.8, color="0.6",
                label="paths" if i == 0 else None)  # fmt: skip
    extent = float(np.ptp(traj.positions.reshape(-1, 2), axis=0).max()) or 1.0
    ks = np.unique(np.linspace(0, traj.times.size - 1, max(snapshots, 2)).round().astype(int))
    for j, k in enumerate(ks):
        ax.add_collection(LineCollection(_heading_marks(traj, k, 0.04 * extent), colors="tab:blue",
                                         label="heading" if j == 0 else None))  # fmt: skip
        ax.plot(traj.positions[k, :, 0], traj.positions[k, :, 1], "k.", ms=3,
                label="positions at " + ", ".join(f"{traj.times[q]:.3g}" for q in ks) + " s" if j == 0 else None)  # fmt: skip
    final = traj.positions[-1]
    ax.plot(final[:, 0], final[:, 1], "o", mfc="none", color="tab:red", label=f"final (t = {traj.times[-1]:.4g} s)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"paths, (tau1, tau2) = ({traj.tau1:g}, {traj.tau2:g}) s")
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return ax


def plot_commands(commands: Any, ax: Any = None, *, max_lines: int = 10) -> Any:
    """Speed, turn rate and wheel speeds of each robot over time, with the limits dashed.

    ``commands`` is a :class:`delayform.simulation.RobotCommands`; ``ax`` three
    axes (speed, turn rate, wheels) or None for a new figure. Up to
    ``max_lines`` robots are drawn one line each (numbered from 1); larger
    teams are drawn as the band between the smallest and largest value over
    the robots. Returns the three axes.
    """
    if ax is None:
        _, ax = plt.subplots(3, 1, sharex=True, figsize=(7.0, 7.5))
    ax_v, ax_w, ax_wheel = ax
    t = commands.times
    n = commands.speed.shape[1]
    lim = commands.robot
    colors = agent_colors(n)
    panels = (
        (ax_v, [commands.speed], lim.max_speed, "v (m/s)"),
        (ax_w, [commands.turn_rate], lim.max_turn_rate, r"$\omega$ (rad/s)"),
        (ax_wheel, [commands.wheel_left, commands.wheel_right], lim.max_wheel_speed, "wheel speed (rad/s)"),
    )
    for axis, series, limit, label in panels:
        for s_idx, values in enumerate(series):
            style = "-" if s_idx == 0 else ":"
            if n <= max_lines:
                for i in range(n):
                    name = f"robot {i + 1}" if axis is ax_v else None
                    axis.plot(t, values[:, i], style, lw=0.9, color=colors[i], label=name)
            else:
                axis.fill_between(t, values.min(axis=1), values.max(axis=1), color="tab:blue", alpha=0.3,
                                  label=f"range over {n} robots" if axis is ax_v else None)  # fmt: skip
        # drawn for ideal robots too: they show where the ideal commands exceed a real robot
        axis.axhline(limit, color="k", ls="--", lw=0.8, label="limit" if axis is ax_v else None)
        axis.axhline(-limit, color="k", ls="--", lw=0.8)
        # a value far beyond the limit (an ideal turn at v ~ 0) would flatten the rest
        finite = np.concatenate([np.abs(v[np.isfinite(v)]) for v in series])
        top = min(float(finite.max(initial=0.0)), 5.0 * limit)
        axis.set_ylim(-1.1 * max(top, limit), 1.1 * max(top, limit))
        axis.set_ylabel(label)
    ax_wheel.set_xlabel("time (s)")
    ax_wheel.set_title("solid: left wheel, dotted: right wheel", fontsize="small")
    kind = "with limits (saturated)" if commands.limited else "ideal robots (limits drawn for reference)"
    ax_v.set_title(f"Commands, {kind}")
    ax_v.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return ax_v, ax_w, ax_wheel


def save_trajectory_gif(traj: Any, path: Any, *, frames: int = 80, fps: int = 15) -> Any:
    """Animated GIF of the robots moving into formation (Pillow, looping); returns the path.

    The axes, ticks and labels are drawn once; each frame restores them and
    draws only what moves (the robots, their heading marks and the time in the
    title), as matplotlib's blitting does, instead of redrawing the whole
    figure for every frame (80 full redraws were a quarter of ``delayform paper``).
    """
    from pathlib import Path

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from PIL import Image

    path = Path(path)
    fig, ax = plt.subplots(figsize=(4, 4))
    try:
        canvas = FigureCanvasAgg(fig)  # pixels to read back, whatever backend pyplot uses
        pts = traj.positions.reshape(-1, 2)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.05 * float((hi - lo).max() or 1.0)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        length = 0.04 * float((hi - lo).max() or 1.0)
        dots = ax.plot([], [], "o", ms=4, color="tab:red", animated=True)[0]
        marks = LineCollection([], colors="tab:blue", animated=True)
        ax.add_collection(marks)
        title = ax.set_title("", animated=True)
        samples = np.linspace(0, traj.times.size - 1, max(frames, 2)).round().astype(int)
        canvas.draw()  # everything but the animated artists
        background = canvas.copy_from_bbox(fig.bbox)
        images = []
        for k in samples:
            canvas.restore_region(background)
            dots.set_data(traj.positions[k, :, 0], traj.positions[k, :, 1])
            marks.set_segments(_heading_marks(traj, k, length))
            title.set_text(f"t = {traj.times[k]:.1f} s")
            for artist in (dots, marks, title):  # as a full draw orders them: by zorder, then as added
                ax.draw_artist(artist)
            images.append(Image.frombuffer("RGBA", canvas.get_width_height(), bytes(canvas.buffer_rgba()), "raw", "RGBA", 0, 1))
        with atomic_path(path) as tmp:
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    finally:
        plt.close(fig)
    return path


# === section: imperfect networks and Monte Carlo ===
def plot_error_bands(
    times: Any, quantiles: Any, q: Sequence[float], ax: Axes | None = None, *, title: str = ""
) -> Axes:
    """Quantile bands of the formation error over time (log scale).

    ``quantiles`` is ``(len(q), S)``; pairs ``q[i], q[-1 - i]`` are shaded,
    a middle quantile (odd ``len(q)``) is drawn as a line.
    """
    ax = _axes(ax)
    floor = 1e-12  # a log axis cannot show an error of exactly zero
    k = len(q)
    for i in range(k // 2):
        lo, hi = np.maximum(quantiles[i], floor), np.maximum(quantiles[k - 1 - i], floor)
        ax.fill_between(times, lo, hi, color="tab:blue", alpha=0.15 + 0.2 * i, lw=0,
                        label=f"{100 * q[i]:g}-{100 * q[k - 1 - i]:g} %")  # fmt: skip
    if k % 2:
        ax.plot(times, np.maximum(quantiles[k // 2], floor), color="tab:blue", lw=1.5, label=f"{100 * q[k // 2]:g} % (median)")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("formation error (m)")
    if title:
        ax.set_title(title, fontsize="medium")
    ax.legend(fontsize="small")
    return ax


def plot_histograms(panels: Sequence[tuple[str, Any]], axes: Any = None) -> Any:
    """One histogram per ``(label, values)`` panel; non-finite values are counted in the title."""
    if axes is None:
        _, axes = plt.subplots(1, len(panels), figsize=(4.0 * len(panels), 3.2))
    for ax, (label, values) in zip(np.atleast_1d(axes), panels, strict=True):
        values = np.asarray(values, dtype=np.float64)
        finite = values[np.isfinite(values)]
        if finite.size:
            ax.hist(finite, bins=min(30, max(5, finite.size // 3)), color="tab:blue", alpha=0.8)
        missing = values.size - finite.size
        ax.set_xlabel(label)
        ax.set_ylabel("runs")
        if missing:
            ax.set_title(f"{missing} of {values.size} runs did not settle", fontsize="small")
    return axes


def plot_metric_against(
    x: Any, median: Any, low: Any, high: Any, ax: Axes | None = None, *, label: str = "", xlabel: str = "", ylabel: str = ""
) -> Axes:
    """A metric's median against a swept parameter, with a band from ``low`` to ``high``."""
    ax = _axes(ax)
    line = ax.plot(x, median, "o-", lw=1.5, label=label)[0]
    ax.fill_between(x, low, high, color=line.get_color(), alpha=0.2, lw=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if label:
        ax.legend(fontsize="small")


def _cell_edges(centres: Any) -> Any:
    """Edges of cells centred on sorted ``centres`` (a single centre gets a cell of +-5 %, at least 0.01)."""
    import numpy as np

    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        half = max(0.05 * abs(c[0]), 0.01)
        return np.array([c[0] - half, c[0] + half])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])


def plot_metric_grid(
    tau1: Any, tau2: Any, values: Any, ax: Axes | None = None, *, label: str = "", title: str = ""
) -> Axes:
    """A metric over a grid of delays, ``values[i, j]`` at ``(tau1[i], tau2[j])``; infinite cells grey.

    Infinite values (runs that did not settle) are drawn grey and named in the legend.
    """
    import numpy as np

    ax = _axes(ax)
    z = np.asarray(values, dtype=float)
    finite = np.isfinite(z)
    x, y = (np.maximum(_cell_edges(t), 0.0) for t in (tau1, tau2))  # delays are not negative
    if not finite.all():
        ax.pcolormesh(x, y, np.where(finite, np.nan, 1.0).T, cmap="Greys", vmin=0.0, vmax=3.0)
        ax.plot([], [], "s", color="0.67", label="median run did not settle")
        ax.legend(fontsize="small", loc="upper right")
    if finite.any():
        mesh = ax.pcolormesh(x, y, np.where(finite, z, np.nan).T, cmap="viridis", shading="flat")
        ax.figure.colorbar(mesh, ax=ax, label=label)
    ax.set_xlabel("tau1 (s)")
    ax.set_ylabel("tau2 (s)")
    if title:
        ax.set_title(title, fontsize="small")
    return ax


# === section: gain plane ===
def plot_gain_plane(
    result: Any, ax: Axes | None = None, points: Mapping[str, tuple[float, float]] | None = None,
    *, levels: int = 20,
) -> Axes:
    """Contour map of the spectral abscissa over the gains (P, D), like the paper's Fig. 9 for delays.

    Filled contours of Re(dominant root) over a
    :class:`~delayform.design.gains.GainPlaneMap`, the stable region's edge
    (the zero level) in black, the exact curves with an imaginary root
    (D-decomposition, when the map has them) dashed red, the designed gains
    as a star and other labelled gains as dots.

    Parameters
    ----------
    result
        The map to draw (``P_values``, ``D_values``, ``abscissa``, ``chosen``).
    ax
        Axes to draw on; new ones when None.
    points
        Label -> (P, D) to mark, e.g. the paper's gains.
    levels
        Number of contour levels.

    Returns
    -------
    Axes
    """
    ax = _axes(ax)
    P, D = np.asarray(result.P_values), np.asarray(result.D_values)
    A = np.asarray(result.abscissa, dtype=float)
    top = float(np.nanmax(A))
    shown = np.minimum(A, max(0.5 * abs(float(np.nanmin(A))), min(top, 0.5)))  # keep the stable side readable
    filled = ax.contourf(P, D, shown.T, levels=levels, cmap="viridis")
    ax.figure.colorbar(filled, ax=ax, label=r"Re $s_{dom}$ (1/s)")
    if np.nanmin(A) < 0.0 < np.nanmax(A):
        ax.contour(P, D, A.T, levels=[0.0], colors="k", linewidths=1.4)
    curves = [c for c in getattr(result, "boundary", ()) if len(c) > 1]
    if curves:  # the exact curves with an imaginary root; the stable region's edge lies on them
        ax.add_collection(LineCollection(curves, colors="red", linewidths=0.8, linestyles="--",
                                         label="imaginary root (exact)"))
    if result.chosen is not None:
        ax.plot([result.chosen[0]], [result.chosen[1]], marker="*", color="red", ms=14, mec="k", ls="none",
                label="designed gains")
    for name, (p, d) in (points or {}).items():
        ax.plot([p], [d], "wo", ms=5, mec="k")
        ax.annotate(name, (p, d), xytext=(4, 4), textcoords="offset points", color="w", fontweight="bold")
    ax.set_xlabel("P (position gain)")
    ax.set_ylabel("D (velocity gain)")
    delays = np.asarray(result.delays)
    where = (f"(tau1, tau2) = ({delays[0, 0]:g}, {delays[0, 1]:g}) s" if delays.shape[0] == 1
             else f"worst of {delays.shape[0]} delay pairs")
    ax.set_title(f"Spectral abscissa over the gains, {where}; black: Re = 0")
    ax.set_xlim(P[0], P[-1])
    ax.set_ylim(D[0], D[-1])
    if result.chosen is not None or curves:
        ax.legend(loc="upper right", fontsize="small")
    return ax


# === section: the eigenvalue plane and certificates for classes of teams ===
def lambda_region_plot(
    region: Any, ax: Axes | None = None, eigenvalues: Any = None, *, radius: float = 1.6, resolution: int = 301
) -> Axes:
    """The stable region of the eigenvalue plane (shaded), its boundary ``L(j omega)``, the unit disc.

    ``region`` is a :class:`delayform.analysis.plane.region.LambdaRegion`; the
    optional ``eigenvalues`` of a team's C are marked green where stable and
    red where not (the centroid eigenvalue 1 as a black square).

    Parameters
    ----------
    region
        The region to draw.
    ax
        Axes to draw on; new ones when None.
    eigenvalues
        Complex eigenvalues to mark, or None.
    radius
        Half-width of the drawn square of the lam plane.
    resolution
        Grid points per axis used to shade the region.

    Returns
    -------
    Axes
    """
    ax = _axes(ax)
    x = np.linspace(-radius, radius, resolution)
    z = x[None, :] + 1j * x[:, None]
    stable = region.is_stable(z).astype(float)
    ax.contourf(x, x, stable, levels=[0.5, 1.5], colors=["0.8"])
    curve = region.boundary(radius * 1.5)
    ax.plot(curve.real, curve.imag, color="tab:red", lw=0.9, label=r"boundary $L(j\omega)$")
    phi = np.linspace(0.0, 2.0 * np.pi, 361)
    ax.plot(np.cos(phi), np.sin(phi), color="0.3", lw=0.8, ls="--", label="unit disc")
    if eigenvalues is not None:
        lam = np.asarray(eigenvalues, dtype=complex)
        centroid = np.abs(lam - 1.0) <= 1e-9
        ok = region.is_stable(lam)
        ax.plot(lam[ok & ~centroid].real, lam[ok & ~centroid].imag, "o", color="tab:green", ms=4, label="eigenvalue, stable")
        ax.plot(lam[~ok & ~centroid].real, lam[~ok & ~centroid].imag, "o", color="tab:red", ms=4, mfc="none",
                label="eigenvalue, unstable")
        ax.plot(lam[centroid].real, lam[centroid].imag, "ks", ms=4, label="centroid (lam = 1)")
    ax.set_xlim(-radius, radius)
    ax.set_ylim(-radius, radius)
    ax.set_aspect("equal")
    ax.set_xlabel(r"Re $\lambda$")
    ax.set_ylabel(r"Im $\lambda$")
    ax.set_title(rf"Stable eigenvalues (shaded), $\tau_1$ = {region.tau1:g}, $\tau_2$ = {region.tau2:g}")
    ax.legend(loc="lower left", fontsize="x-small")
    return ax


def safe_delay_chart(
    smap: Any, ax: Axes | None = None, points: Mapping[str, tuple[float, float]] | None = None,
    *, resolution: int = 200, shade: str = "tab:green",
) -> Axes:
    """The delays safe for a whole class of teams, drawn like the CTCR chart.

    ``smap`` is a :class:`delayform.analysis.plane.spectrum_sets.SafeDelayMap`: the
    certified safe set shaded, the exact CTCR curves of the factors at the
    ends of the spectrum set (kernel red, offspring blue) and the envelope
    of the interior eigenvalues where present.

    Parameters
    ----------
    smap
        The map to draw.
    ax
        Axes to draw on; new ones when None.
    points
        Label -> (tau1, tau2) to mark.
    resolution
        Grid cells per axis used to shade the safe set.
    shade
        Colour of the safe set.

    Returns
    -------
    Axes
    """
    ax = _axes(ax)
    t1, t2, safe = smap.grid(resolution)
    if np.any(safe):
        ax.contourf(t1, t2, safe.astype(float), levels=[0.5, 1.5], colors=[shade], alpha=0.45)
    for base in smap.base_maps:
        for kernel, color in ((False, "blue"), (True, "red")):
            lines = [np.column_stack([c.tau1, c.tau2]) for c in base.curves if c.is_kernel == kernel]
            if lines:
                ax.add_collection(LineCollection(lines, colors=color, linewidths=0.7, alpha=0.8))
    for line in getattr(smap, "envelope", ()):
        ax.plot(line[:, 0], line[:, 1], color="black", lw=1.0)
    for name, (a, b) in (points or {}).items():
        ax.plot([a], [b], "ko", ms=4)
        ax.annotate(f"{name}", (a, b), xytext=(4, 4), textcoords="offset points", fontweight="bold")
    ax.set_xlim(0.0, smap.tau1_max)
    ax.set_ylim(0.0, smap.tau2_max)
    ax.set_xlabel(r"$\tau_1$ (s), position delay")
    ax.set_ylabel(r"$\tau_2$ (s), velocity delay")
    title = f"Safe for every team with spectrum in: {smap.spectrum.label}"
    ax.set_title(title if not smap.never_safe else title + " (none)", fontsize="small")
    return ax


# === section: delay margins of python-control loops ===
def plot_delay_margin(result: Any, ax: Axes | None = None) -> Axes:
    """Nyquist plot of a :class:`~delayform.loops.DelayMargin`'s loop, unit circle and crossovers.

    The loci are the eigenvalues mu = -1/z of L(j omega), z the roots of
    g1 + g2 z + g4 z^2 (for a SISO loop, mu = L(j omega) itself), clipped
    radially at |mu| = 4 so that a loop with an integrator stays readable;
    each crossover is marked at mu = -e^{j PM} with its first delay. A loop
    with its own dead time theta is drawn as L(j omega) e^{-j omega theta},
    whose phase margins the crossovers carry.
    """
    import numpy.polynomial.polynomial as npoly

    ax = _axes(ax)
    qp = result.quasi_polynomial
    top = max([c.omega for c in result.crossovers] + [1.0]) * 100.0
    w = np.geomspace(1e-5 * top, top, 2000)
    g1, g2 = npoly.polyval(1j * w, qp.g1), npoly.polyval(1j * w, qp.g2)
    if qp.g4.size == 0:
        loci = [g2 / g1]
    else:
        g4 = npoly.polyval(1j * w, qp.g4)
        root = np.sqrt(g2 * g2 - 4 * g4 * g1)
        loci = [-2 * g4 / (-g2 + root), -2 * g4 / (-g2 - root)]  # -1/z for both roots z
    for k, mu in enumerate(loci):
        mu = mu * np.exp(-1j * w * getattr(result, "delay", 0.0))
        mu = np.where(np.abs(mu) > 4.0, mu / np.abs(mu) * 4.0, mu)
        ax.plot(mu.real, mu.imag, ".", ms=1.5, color=f"C{k}", label="loci of L(j omega), omega > 0" if k == 0 else None)
    t = np.linspace(0.0, 2 * np.pi, 200)
    ax.plot(np.cos(t), np.sin(t), color="0.6", lw=0.8, label="|L| = 1")
    ax.plot([-1.0], [0.0], "k+", ms=10)
    for c in result.crossovers:
        mark = -np.exp(1j * c.phase_margin_rad)
        ax.plot([mark.real], [mark.imag], "o", color="C3")
        ax.annotate(f"tau={c.tau:.3g}", (mark.real, mark.imag), textcoords="offset points", xytext=(5, 5))
    ax.set_aspect("equal")
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.set_title(f"delay margin {result.tau:.4g} s")
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_loop_gains(design: Any, ax: Axes | None = None) -> Axes:
    """The rightmost root's real part over the gain grid of a loop gain design, 0-contour and the design."""
    ax = _axes(ax)
    mesh = ax.pcolormesh(design.P_values, design.D_values, design.grid_abscissa, shading="nearest", cmap="coolwarm")
    ax.figure.colorbar(mesh, ax=ax, label="Re of the rightmost root (1/s)")
    if design.grid_abscissa.min() < 0.0 < design.grid_abscissa.max():
        ax.contour(design.P_values, design.D_values, design.grid_abscissa, levels=[0.0], colors="k", linewidths=1.0)
    ax.plot([design.P], [design.D], "k*", ms=12, label=f"P = {design.P:.3g}, D = {design.D:.3g}")
    ax.set_xlabel("P")
    ax.set_ylabel("D")
    ax.set_title(f"(tau1, tau2) = ({design.tau1:g}, {design.tau2:g}) s")
    ax.legend(loc="best", fontsize="small")
    return ax
