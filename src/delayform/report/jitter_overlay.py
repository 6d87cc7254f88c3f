"""The certified jitter margin drawn on the stability chart.

:func:`jitter_overlay` computes :func:`~delayform.analysis.network.jitter_margin_map`
on a grid of cell centres of the chart window (the axes themselves are left out:
at tau1 = 0 the loop's low-frequency form degenerates and the certificate gives 0
there, which would draw a misleading edge) and :func:`draw_overlay` adds its
contour lines to the chart's axes, over the stable region only. The margin is for
the paper's protocol without actuation delay; :func:`check_overlay` refuses the
overlay up front for a scenario with one, for a grid that would exceed the time
budget, and for a team beyond :data:`MAX_AGENTS`, before anything is computed or
written.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["DEFAULT_GRID", "AUTO_SECONDS", "MAX_AGENTS", "check_overlay", "jitter_overlay", "draw_overlay", "overlay_wanted", "auto_grid"]

#: grid points per axis of the overlay by default (the paper's team over [0, 8]^2: about 10 s, 100 stable points)
DEFAULT_GRID = 24
#: longest estimate (s) of an overlay the report draws without being asked (``--jitter-grid`` draws any)
AUTO_SECONDS = 60.0
#: the largest team the overlay is drawn for (the certificate's cost grows like L^1.5 per point)
MAX_AGENTS = 60


def _grid(tau_max: float, size: int) -> np.ndarray:
    return (np.arange(size) + 0.5) * tau_max / size


def check_overlay(scenario: Any, tau1_max: float, tau2_max: float, size: int) -> None:
    """Refuse the overlay before any work: actuation delay, team size, grid size and time budget.

    Parameters
    ----------
    scenario
        The scenario (its topology and actuation delay).
    tau1_max, tau2_max
        The chart window.
    size
        Grid points per axis.

    Raises
    ------
    InputError
        For an actuation delay, a grid smaller than 2 or a team larger than :data:`MAX_AGENTS`.
    ResourceLimitError
        When the map would exceed the time budget or the memory.
    """
    from delayform.analysis.network.jitter import jitter_map_estimate
    from delayform.errors import InputError
    from delayform.resources import require

    if scenario.actuation_delay:
        raise InputError("the jitter margin is certified without actuation delay (tau_a = 0); "
                         f"this scenario has tau_a = {scenario.actuation_delay:g} s")  # fmt: skip
    if isinstance(size, bool) or not isinstance(size, int) or size < 2:
        raise InputError(f"the jitter-margin grid needs at least 2 points per axis, got {size!r}")
    if scenario.topology.n > MAX_AGENTS:
        raise InputError(f"the jitter-margin map is drawn for teams of up to {MAX_AGENTS} agents, "
                         f"this one has {scenario.topology.n}")  # fmt: skip
    seconds, nbytes = jitter_map_estimate(scenario.topology, size * size)
    require(what=f"a {size} x {size} jitter-margin map over [0, {tau1_max:g}] x [0, {tau2_max:g}]",
            setting="the jitter-margin grid (--jitter-grid)", nbytes=nbytes, seconds=seconds)  # fmt: skip


def jitter_overlay(scenario: Any, tau1_max: float, tau2_max: float, size: int) -> Any:
    """The :class:`~delayform.analysis.network.JitterMarginMap` on ``size x size`` cell centres of the window.

    Parameters
    ----------
    scenario, tau1_max, tau2_max, size
        As for :func:`check_overlay`, which is applied first.
    """
    from delayform.analysis.network import jitter_margin_map

    check_overlay(scenario, tau1_max, tau2_max, size)
    return jitter_margin_map(scenario.topology, scenario.P, scenario.D, _grid(tau1_max, size), _grid(tau2_max, size))


def draw_overlay(jmap: Any, ax: Any) -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """Draw ``jmap`` on the chart's axes; return its summary and table rows.

    Parameters
    ----------
    jmap
        The map of :func:`jitter_overlay`.
    ax
        The stability chart's axes.
    """
    jmap.plot(ax=ax)
    best = np.unravel_index(int(np.argmax(jmap.delta)), jmap.delta.shape)
    top = float(jmap.delta[best])
    at = (float(jmap.tau1_values[best[0]]), float(jmap.tau2_values[best[1]]))
    summary = {"grid": [int(jmap.tau1_values.size), int(jmap.tau2_values.size)], "largest_delta": top,
               "largest_at": list(at), "certified_points": int(np.count_nonzero(jmap.delta > 0)),
               "levels": [float(v) for v in jmap.levels()]}  # fmt: skip
    rows = [("jitter margin (certified, any variation)",
             f"largest delta = {top:.3g} s at ({at[0]:.3g}, {at[1]:.3g}) on a "
             f"{jmap.tau1_values.size} x {jmap.tau2_values.size} grid; contour lines on the chart")]  # fmt: skip
    return summary, rows


def overlay_wanted(scenario: Any) -> bool:
    """True when the scenario's network varies its delays in time (jitter or a smooth variation).

    Parameters
    ----------
    scenario
        The scenario (its ``[network]``).
    """
    net = getattr(scenario, "network", None)
    if net is None:
        return False
    return any(getattr(net, part, None) is not None and not getattr(net, part).is_off for part in ("jitter", "variation"))


def auto_grid(scenario: Any) -> int:
    """:data:`DEFAULT_GRID` when the overlay is wanted (:func:`overlay_wanted`) and allowed, else 0.

    A report draws the overlay on its own initiative only where it fits: no
    actuation delay, a team within :data:`MAX_AGENTS` and the budget, and an
    estimate within :data:`AUTO_SECONDS`.

    Parameters
    ----------
    scenario
        The scenario of the report.
    """
    from delayform.errors import InputError, ResourceLimitError

    if not overlay_wanted(scenario):
        return 0
    from delayform.analysis.network.jitter import jitter_map_estimate

    try:
        check_overlay(scenario, scenario.chart.tau1_max, scenario.chart.tau2_max, DEFAULT_GRID)
    except (InputError, ResourceLimitError):
        return 0
    # unasked, the overlay may not dominate the report's time
    return DEFAULT_GRID if jitter_map_estimate(scenario.topology, DEFAULT_GRID**2)[0] <= AUTO_SECONDS else 0
