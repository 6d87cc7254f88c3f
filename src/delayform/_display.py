"""Rich display in Jupyter: results that can be drawn show their figure.

IPython calls ``_repr_png_`` on the last value of a cell; the mixin below
draws the result's own figure method on a fresh, pyplot-free ``Figure``
(so nothing is left open and no global state is touched) and returns the
PNG bytes. ``control_plot`` wraps a drawing as python-control's ``ControlPlot``.
A leaf: imports no delayform module; matplotlib and python-control only when asked.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from typing import Any, ClassVar

__all__ = ["FigureRepr", "LoopPlot", "control_plot"]


class FigureRepr:
    """Mixin: ``_repr_png_`` from the method named by ``_figure_method`` (``plot`` unless set)."""

    _figure_method: ClassVar[str] = "plot"
    _figure_size: ClassVar[tuple[float, float]] = (6.0, 4.5)

    def _repr_png_(self) -> bytes:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=self._figure_size)
        FigureCanvasAgg(fig)
        getattr(self, self._figure_method)(ax=fig.add_subplot())
        data = io.BytesIO()  # in memory: no file, so no complete-or-absent writer (_files) needed
        fig.savefig(data, format="png", dpi=90, bbox_inches="tight")
        return data.getvalue()


class LoopPlot:
    """What python-control's ``ControlPlot`` holds, for when python-control is not installed.

    Attributes
    ----------
    lines
        A 1 x 1 object array holding the list of ``Line2D`` drawn (one
        entry per axes, python-control's layout).
    axes
        A 1 x 1 object array of the ``Axes``.
    figure
        The ``Figure`` the axes are on.
    legend
        The axes' ``Legend``, or None.
    """

    def __init__(self, lines: Any, axes: Any, figure: Any, legend: Any = None) -> None:
        self.lines, self.axes, self.figure, self.legend = lines, axes, figure, legend

    def set_plot_title(self, title: str) -> None:
        """Title over the axes (python-control's ``ControlPlot.set_plot_title``)."""
        self.figure.suptitle(title)


def control_plot(draw: Callable[[Any], Any], ax: Any = None) -> Any:
    """Call ``draw(ax)`` (which returns its Axes) and wrap what it drew as a ``ControlPlot``.

    python-control's plotting functions return a ``control.ControlPlot``
    (``.lines``, ``.axes``, ``.figure``, ``.legend``); the loop results return
    the same class when python-control is installed, so code written for
    ``control.nyquist_plot`` works on them, and a :class:`LoopPlot` with the
    same attributes when it is not (a ``(num, den)`` loop needs no
    python-control). Only the lines ``draw`` added count, also on given axes.
    """
    import numpy as np

    before = set(ax.get_lines()) if ax is not None else set()
    ax = draw(ax)
    lines = np.empty((1, 1), dtype=object)
    lines[0, 0] = [line for line in ax.get_lines() if line not in before]
    axes = np.empty((1, 1), dtype=object)
    axes[0, 0] = ax
    try:
        from control import ControlPlot
    except ImportError:
        return LoopPlot(lines, axes, ax.figure, ax.get_legend())
    return ControlPlot(lines, axes, ax.figure, legend=ax.get_legend())
