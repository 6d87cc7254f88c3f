"""The loose call forms of :func:`simulate` and :func:`monte_carlo`, kept working by mapping each old keyword to its noun.

Before the nouns, a run was described by loose arguments::

    simulate(topology, P, D, tau1, tau2, formation, model="unicycle", limits=IROBOT_CREATE,
             initial_positions=x0, seed=3, save_every=2, duration=60.0, dt=0.05)

Those calls keep working, with the same results: :func:`accepts_loose_calls`
wraps the entry point, recognises the old form (a
:class:`~delayform.topology.Topology` first, or a ``topology`` keyword) and
builds the nouns from it: ``(topology, P, D)`` -> :class:`~delayform.model.Team`,
``(tau1, tau2)`` -> :class:`~delayform.model.Delays`, and each keyword to the
noun named in :data:`SIMULATE_KEYWORDS` or :data:`MONTE_CARLO_KEYWORDS`. The
old keywords are also taken beside the nouns (``simulate(team, delays, shape,
duration=60, dt=0.05, seed=3)``) unless the noun they belong to is given too.
A keyword in neither table is refused by name; nothing is silently dropped.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping
from dataclasses import replace
from types import MappingProxyType
from typing import Any, TypeVar

from delayform.errors import SimulationInputError
from delayform.model import Robot, Team
from delayform.model.loose import LOOSE_TEAM, is_loose, team_and_delays
from delayform.model.start import Start
from delayform.simulation.runs.options import RunOptions

__all__ = ["SIMULATE_KEYWORDS", "MONTE_CARLO_KEYWORDS", "LOOSE_POSITIONAL", "accepts_loose_calls", "nouns_of"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: the old positional parameters, in order
LOOSE_POSITIONAL = (*LOOSE_TEAM, "formation")

_ROBOT = {"model": "model", "limits": "limits", "safety": "safety", "actuation_delay": "actuation_delay",
          "rest_speed": "rest_speed", "radius": "radius", "chassis": "chassis"}  # fmt: skip
_START = {"initial_positions": "positions", "initial_headings": "headings", "initial_speed": "speed", "seed": "seed"}
_OPTIONS = {"save_every": "save_every", "assignment": "assignment", "progress": "progress", "executor": "executor"}

#: each old keyword of ``simulate`` -> where it goes now ("Noun.field")
SIMULATE_KEYWORDS: Mapping[str, str] = MappingProxyType(
    {**{k: f"Robot.{v}" for k, v in _ROBOT.items() if k not in ("radius", "chassis")},
     **{k: f"Start.{v}" for k, v in _START.items()},
     **{k: f"RunOptions.{v}" for k, v in _OPTIONS.items() if k != "executor"}}  # fmt: skip
)

#: each old keyword of ``monte_carlo`` -> where it goes now (its ``seed`` seeds every run's start and network;
#: ``chassis``, of robots with mass, goes to ``Robot.chassis``)
MONTE_CARLO_KEYWORDS: Mapping[str, str] = MappingProxyType(
    {**{k: f"Robot.{v}" for k, v in _ROBOT.items() if k != "rest_speed"},
     **{k: f"Start.{v}" for k, v in _START.items()},
     **{k: f"RunOptions.{v}" for k, v in _OPTIONS.items() if k != "save_every"}}  # fmt: skip
)

#: robot fields that a given Robot may not be combined with (the old rule of simulate)
_EXCLUSIVE = ("model", "limits", "safety", "actuation_delay")


def _split(where: str, table: Mapping[str, str], loose: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Old keywords grouped by noun: ``{"Robot": {...}, "Start": {...}, "RunOptions": {...}}``."""
    groups: dict[str, dict[str, Any]] = {"Robot": {}, "Start": {}, "RunOptions": {}}
    for key, value in loose.items():
        if key not in table:
            raise SimulationInputError(
                f"{where}: unknown keyword {key!r}; the old keywords are {', '.join(sorted(table))}"
            )
        noun, field = table[key].split(".")
        if value is None and key != "seed":  # None was every old keyword's "not given" (seed=None: unseeded)
            continue
        groups[noun][field] = value
    return groups


def nouns_of(
    where: str, table: Mapping[str, str], new: Mapping[str, Any], loose: dict[str, Any], default_model: str
) -> dict[str, Any]:
    """The keyword arguments of the noun form: ``new`` with the old keywords folded into robot, start and options.

    Parameters
    ----------
    where
        The entry point, for messages.
    table
        Its old keywords (:data:`SIMULATE_KEYWORDS` or :data:`MONTE_CARLO_KEYWORDS`).
    new
        The keywords of the noun form that were given (``robot``, ``start``, ...).
    loose
        The old keywords that were given.
    default_model
        The agent model of the old form when none is named.

    Raises
    ------
    SimulationInputError
        For an unknown keyword, or an old keyword beside the noun it belongs to.
    """
    groups = _split(where, table, loose)
    out = dict(new)
    robot_fields, start_fields, option_fields = groups["Robot"], groups["Start"], groups["RunOptions"]
    robot = out.get("robot")
    if robot is None:
        if robot_fields or default_model != "unicycle":
            out["robot"] = Robot(**{"model": default_model, **robot_fields})
    elif robot_fields:
        if not isinstance(robot, Robot):
            raise SimulationInputError(f"robot must be a Robot, got {type(robot).__name__}")
        if any(k in robot_fields for k in _EXCLUSIVE):
            raise SimulationInputError(
                "give the model, limits, safety and actuation_delay either in robot or as keywords, not both"
            )
        out["robot"] = replace(robot, **robot_fields)
    for name, noun, fields in (("start", Start, start_fields), ("options", RunOptions, option_fields)):
        if not fields:
            continue
        if out.get(name) is not None:
            keys = ", ".join(k for k in loose if table[k].startswith(noun.__name__ + "."))
            raise SimulationInputError(f"give {keys} in {name} or as keywords, not both")
        out[name] = noun(**fields)
    return out


def _is_loose(args: tuple[Any, ...], loose: Mapping[str, Any]) -> bool:
    """The old form: a Topology first (or by name), or more than the three nouns positionally."""
    return is_loose(args, loose) or (len(args) > 3 and not isinstance(args[0], Team))


def accepts_loose_calls(table: Mapping[str, str], *, default_model: str) -> Callable[[_F], _F]:
    """Let a noun-form entry point also take the old loose call form (module doc).

    Parameters
    ----------
    table
        Its old keywords and their nouns.
    default_model
        The agent model of the old form when none was named (``monte_carlo``'s
        was ``"double_integrator"``, ``simulate``'s ``"unicycle"``).
    """

    def decorate(func: _F) -> _F:
        params = inspect.signature(func).parameters
        where = func.__name__

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            loose = {k: kwargs.pop(k) for k in list(kwargs) if k not in params}
            if _is_loose(args, loose):
                bound = dict(zip(LOOSE_POSITIONAL, args))
                if len(args) > len(LOOSE_POSITIONAL):
                    raise SimulationInputError(f"{where} takes {len(LOOSE_POSITIONAL)} positional arguments in its "
                                               f"loose form ({', '.join(LOOSE_POSITIONAL)}), got {len(args)}")  # fmt: skip
                for name in LOOSE_POSITIONAL:
                    if name in kwargs or name in loose:
                        bound[name] = kwargs.pop(name) if name in kwargs else loose.pop(name)
                missing = [n for n in LOOSE_POSITIONAL if n not in bound]
                if missing:
                    raise SimulationInputError(f"{where}: {', '.join(missing)} required and not given")
                team, delays = team_and_delays(*(bound[n] for n in LOOSE_TEAM))
                kwargs = nouns_of(where, table, kwargs, loose, default_model)
                return func(team, delays, bound["formation"], **kwargs)
            if loose:
                kwargs = nouns_of(where, table, kwargs, loose, "unicycle")
            return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate
