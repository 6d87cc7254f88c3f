"""The explorer's robot controls: actuation delay, safety filter and slot assignment, set from the page.

The page sends three more query parameters, checked like every other
(:mod:`delayform.app.params`):

``actuation_delay``
    tau_a (s) in [0, ``max_delay``], default the scenario's ``[robot] actuation_delay``.
    The analysis endpoints (chart, point, roots) compute at it -- the exact CTCR map and
    the certified roots in three delays; the run applies each command tau_a late. The
    jitter margin and the eigenvalue plane have no actuation delay in their theory: at
    tau_a > 0 they answer 400 with the reason, never a number for another system.
``safety``
    0 / 1: the barrier filter of :mod:`delayform.simulation.bodies.safety` on the run (default:
    the scenario's ``[robot] safety``).
``assignment``
    0 / 1: optimal slot assignment (:mod:`delayform.simulation.bodies.assignment`) or the
    scenario's given slots (default: the scenario's ``[simulation] assignment``).

Runs, figures and scenario downloads take all three; the analysis endpoints take only
``actuation_delay`` (the other two change nothing there, and a parameter that changes
nothing is refused, not ignored). Each setting is served by an
:class:`~delayform.app.explorer.Explorer` of the scenario with that setting (a few kept,
least recently used first out), so maps, runs and downloads are cached per setting
and a download's file name (the controls that differ from the scenario's own) and its
``scenario.toml`` carry the setting.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from delayform.app.explorer import Explorer
from delayform.app.params import Param
from delayform.errors import InputError

__all__ = ["RobotControls"]

#: explorers kept, one per setting of the controls (each holds its own maps and runs)
_SETTINGS_KEPT = 4
#: the endpoints whose theory has no actuation delay (they refuse tau_a > 0 with the reason)
_NO_ACTUATION = {
    "guarantee": "the certified jitter margin (small-gain test) has no actuation delay in its theory",
    "region": "the eigenvalue plane's boundary curve has no actuation delay in its theory",
}


def _name(base: str, setting: tuple[float, bool, bool], defaults: tuple[float, bool, bool]) -> str:
    """The scenario's name with each control that differs from the scenario's own (download names carry it).

    The scenario's own setting keeps the plain name, so no two settings share a file name.
    """
    parts = [base]
    if setting[0] != defaults[0]:
        parts.append(f"ta{setting[0]:.12g}")
    if setting[1] != defaults[1]:
        parts.append("barrier" if setting[1] else "nobarrier")
    if setting[2] != defaults[2]:
        parts.append("optimal" if setting[2] else "given")
    return "_".join(parts)


class RobotControls:
    """Routes the explorer's requests to an :class:`Explorer` per setting of the robot controls.

    Parameters
    ----------
    explorer
        The explorer of the scenario as loaded: its settings are the controls' defaults,
        and it serves every request at those settings itself.
    """

    def __init__(self, explorer: Explorer) -> None:
        self.base = explorer
        s = explorer.scenario
        self.defaults = {
            "actuation_delay": float(s.actuation_delay),
            "safety": s.safety is not None,
            "assignment": s.simulation.assignment == "optimal",
        }
        self._lock = threading.Lock()
        self._explorers: OrderedDict[tuple[float, bool, bool], Explorer] = OrderedDict()

    def params(self, *, run: bool) -> tuple[Param, ...]:
        """The controls' parameters: the actuation delay, and for runs and downloads the two switches."""
        d = self.defaults
        out = (Param("actuation_delay", "float", 0.0, self.base.limits.max_delay, default=d["actuation_delay"],
                     limit="max_delay"),)  # fmt: skip
        if run:
            out += (Param("safety", "bool", default=d["safety"]), Param("assignment", "bool", default=d["assignment"]))
        return out

    def describe(self) -> dict[str, Any]:
        """What the page needs to draw the controls: defaults and the actuation delay's bound."""
        return {"defaults": dict(self.defaults), "max_actuation_delay": self.base.limits.max_delay}

    def explorer_for(self, actuation_delay: float, safety: bool, assignment: bool) -> Explorer:
        """The explorer of the scenario at these settings (the base one at the scenario's own)."""
        key = (float(actuation_delay), bool(safety), bool(assignment))
        d = self.defaults
        own = (d["actuation_delay"], d["safety"], d["assignment"])
        if key == own:
            return self.base
        with self._lock:
            if key in self._explorers:
                self._explorers.move_to_end(key)
                return self._explorers[key]
        s = self.base.scenario
        scenario = replace(
            s, name=_name(s.name, key, own), actuation_delay=key[0],
            safety=("barrier" if s.safety is None else s.safety) if safety else None,
            simulation=replace(s.simulation, assignment="optimal" if assignment else "given"),
        )  # fmt: skip
        made = Explorer(scenario, out_dir=self.base.out_dir, limits=self.base.limits)
        with self._lock:
            made = self._explorers.setdefault(key, made)
            while len(self._explorers) > _SETTINGS_KEPT:
                self._explorers.popitem(last=False)
        return made

    def route(self, spec: str, method: str, *, run: bool = False,
              on: Callable[[Explorer], Any] | None = None) -> tuple[Callable[[], tuple[Param, ...]], Callable[..., Any]]:  # fmt: skip
        """(parameters, work) of an endpoint: the explorer's ``spec()`` plus the controls, and ``method`` at them.

        Parameters
        ----------
        spec
            Name of the parameter method (``"point_params"``, ...) of the explorer, or of ``on(explorer)``.
        method
            Name of the method answering the request, on the explorer or on ``on(explorer)``.
        run
            The endpoint simulates or downloads: it takes the safety and assignment switches too.
        on
            A view of an explorer that answers instead of the explorer itself (the jitter-margin
            layer, guaranteed vs observed); it is made for the explorer of each setting, so
            whatever it caches on its explorer is cached per setting.
        """
        d = self.defaults
        view = on if on is not None else (lambda e: e)

        def params() -> tuple[Param, ...]:
            return getattr(view(self.base), spec)() + self.params(run=run)  # type: ignore[no-any-return]

        def work(actuation_delay: float, safety: bool = d["safety"], assignment: bool = d["assignment"],
                 **args: Any) -> Any:  # fmt: skip
            if actuation_delay > 0.0 and method in _NO_ACTUATION:
                raise InputError(f"actuation_delay: {_NO_ACTUATION[method]}; set it to 0 for this answer")
            return getattr(view(self.explorer_for(actuation_delay, safety, assignment)), method)(**args)

        return params, work
