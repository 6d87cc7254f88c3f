"""Rich display in Jupyter: results that can be drawn show their figure.

IPython calls ``_repr_png_`` on the last value of a cell; the mixin below
draws the result's own figure method on a fresh, pyplot-free ``Figure``
(so nothing is left open and no global state is touched) and returns the
PNG bytes. A leaf: imports no delayform module; matplotlib only when asked.
"""

from __future__ import annotations

import io
from typing import ClassVar

__all__ = ["FigureRepr"]


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
