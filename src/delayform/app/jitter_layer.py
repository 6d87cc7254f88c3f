"""The explorer's jitter-margin layer: the certified margin as contour lines on the chart.

``GET /api/jitter_map?P=&D=&tau1_max=&tau2_max=&grid=`` answers with
:func:`~delayform.analysis.network.jitter_margin_map` on ``grid x grid`` cell
centres of the chart window (the shading's convention), computed when the page's
toggle asks for it and cached like the stability map, so switching the layer off
and on again, or clicking points, costs nothing. Work is refused up front, with
one line naming the limit: a grid beyond :data:`MAX_GRID`, a map whose estimate
(:func:`~delayform.analysis.network.jitter.jitter_map_estimate`) exceeds
:data:`MAX_SECONDS`, a team beyond the explorer's ``GUARANTEE_AGENTS``, and a
scenario with an actuation delay (the margin is certified for tau_a = 0 only).

Nothing here is web code: :class:`JitterLayer` takes checked values and returns
a :class:`JitterLayerData` with ``as_json``; :mod:`delayform.app.server` routes it.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any
from weakref import WeakKeyDictionary

import numpy as np

from delayform.analysis.network import JitterMarginMap, jitter_margin_map
from delayform.analysis.network.jitter import jitter_map_estimate
from delayform.app.explorer import GUARANTEE_AGENTS, Explorer
from delayform.app.params import Param
from delayform.errors import InputError
from delayform.resources import format_seconds

__all__ = ["JitterLayer", "JitterLayerData", "MAX_GRID", "MAX_SECONDS"]

#: most grid points per axis of the layer
MAX_GRID = 24
#: default grid points per axis (the paper's team: about 5 s on a quiet core)
DEFAULT_GRID = 12
#: longest estimated computation one request may start (s)
MAX_SECONDS = 60.0
#: maps kept per explorer
_CACHE = 8
#: each explorer's cache, dropped with the explorer
_CACHES: WeakKeyDictionary[Explorer, OrderedDict[Any, Any]] = WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class JitterLayerData:
    """The layer as the page draws it.

    Attributes
    ----------
    jmap
        The certified margins at the cell centres.
    """

    jmap: JitterMarginMap

    def as_json(self) -> dict[str, Any]:
        """Axes, ``delta[j][i]`` at (tau1[i], tau2[j]) (Plotly's z) with None where nothing is certified, levels."""
        d = self.jmap.delta
        z = [[float(v) if v > 0 else None for v in row] for row in d.T]
        levels = self.jmap.levels()
        best = np.unravel_index(int(np.argmax(d)), d.shape)
        return {
            "tau1": [float(v) for v in self.jmap.tau1_values],
            "tau2": [float(v) for v in self.jmap.tau2_values],
            "delta": z,
            "levels": [float(v) for v in levels],
            "largest": float(d[best]),
            "largest_at": [float(self.jmap.tau1_values[best[0]]), float(self.jmap.tau2_values[best[1]])],
            "method": "small gain, Kao-Lincoln bound: any time-varying delay within +-delta, per link",
        }


class JitterLayer:
    """The margin maps of one explorer's scenario, cached.

    Parameters
    ----------
    explorer
        The explorer whose scenario, limits and window bounds the layer shares.
    """

    def __init__(self, explorer: Explorer) -> None:
        self.explorer = explorer
        # the cache lives as long as its explorer, whichever layer object asks (one per setting is cheap)
        self._maps: OrderedDict[tuple[float, ...], JitterLayerData] = _CACHES.setdefault(explorer, OrderedDict())

    def params(self) -> tuple[Param, ...]:
        """P, D and the window as for the chart, and ``grid`` (4 to :data:`MAX_GRID`)."""
        return self.explorer.chart_params()[:4] + (Param("grid", "int", 4, MAX_GRID, default=DEFAULT_GRID),)

    def check(self, grid: int) -> None:
        """Refuse what the layer cannot certify or would take too long, before any work."""
        sc = self.explorer.scenario
        if sc.actuation_delay:
            raise InputError(f"jitter margin: certified for tau_a = 0 only, the scenario has tau_a = {sc.actuation_delay:g} s")
        if sc.topology.n > GUARANTEE_AGENTS:
            raise InputError(f"jitter margin: computed for teams of up to {GUARANTEE_AGENTS} agents (GUARANTEE_AGENTS)")
        seconds, _ = jitter_map_estimate(sc.topology, grid * grid)
        if seconds > MAX_SECONDS:
            raise InputError(f"jitter margin: a {grid} x {grid} map would take about {format_seconds(seconds)}, "
                             f"more than the {MAX_SECONDS:g} s one request may (MAX_SECONDS); reduce grid")  # fmt: skip

    def compute(self, P: float, D: float, tau1_max: float, tau2_max: float, grid: int) -> JitterLayerData:
        """The certified margin on ``grid x grid`` cell centres of the window (cached).

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1_max, tau2_max
            The chart window.
        grid
            Points per axis.
        """
        self.check(grid)
        self.explorer._check_bandwidth(P, D, max(tau1_max, tau2_max), "tau1_max, tau2_max")
        key = (P, D, tau1_max, tau2_max, float(grid))
        t1 = (np.arange(grid) + 0.5) * tau1_max / grid
        t2 = (np.arange(grid) + 0.5) * tau2_max / grid
        topology = self.explorer.scenario.topology
        # the explorer's own LRU cache (its lock), on a dictionary of the layer's
        return self.explorer._cached(self._maps, key, _CACHE,
                                     lambda: JitterLayerData(jitter_margin_map(topology, P, D, t1, t2)))  # fmt: skip
