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

# === section: formation and simulation figures (issue 5) ===
