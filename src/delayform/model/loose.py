"""The loose form ``(topology, P, D, tau1, tau2)`` of earlier versions, turned into a Team and Delays.

Functions that take the nouns (``f(team, delays, ...)``) keep taking the
loose form users wrote before them, ``f(topology, P, D, tau1, tau2, ...)``,
through :func:`accepts_loose_team`: a :class:`~delayform.topology.Topology`
first (or a ``topology`` keyword) marks the loose form, and
:func:`team_and_delays` builds the nouns from it with the old meaning kept:
per-link arrays ignore their entries off the links (they may be NaN), and a
number beside an array is that delay on every link.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import numpy as np

from delayform._validation import check_delay
from delayform.errors import InputError
from delayform.model.delays import Delays
from delayform.model.team import Team
from delayform.topology import Topology

__all__ = ["LOOSE_TEAM", "is_loose", "team_and_delays", "accepts_loose_team"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: the loose form's leading parameters, in order
LOOSE_TEAM = ("topology", "P", "D", "tau1", "tau2")


def is_loose(args: tuple[Any, ...], kwargs: Mapping[str, Any]) -> bool:
    """Whether a call is in the loose form: a Topology first, or ``topology`` by name.

    Parameters
    ----------
    args, kwargs
        The call's positional and keyword arguments.
    """
    return "topology" in kwargs or bool(args and isinstance(args[0], Topology))


def _on_links(team: Team, value: Any, other: Any) -> Any:
    """A delay as :class:`Delays` takes it: per-link arrays with 0 off the links, a number beside an array spread."""
    if np.ndim(value) == 0 and np.ndim(other) == 0:
        return value
    n = team.n
    links = team.topology.adjacency_sparse.toarray() != 0
    if np.ndim(value) == 0:
        return np.where(links, value, 0.0) if isinstance(value, (int, float, np.number)) and not isinstance(value, bool) else value
    arr = np.asarray(value)
    if arr.shape != (n, n) or arr.dtype.kind not in "iuf":
        return value  # Delays names what is wrong with it
    return np.where(links, arr, 0.0)


def team_and_delays(topology: Any, P: Any, D: Any, tau1: Any, tau2: Any, actuation: Any = 0.0) -> tuple[Team, Delays]:
    """The :class:`Team` and :class:`Delays` of a loose call (module doc).

    Parameters
    ----------
    topology, P, D
        The team's topology and gains.
    tau1, tau2
        Numbers, or ``n x n`` per-link arrays whose entries off the links are ignored.
    actuation
        The actuation delay tau_a (s).

    Raises
    ------
    TopologyError, GainError, DelayError
        As :class:`Team` and :class:`Delays` do.
    """
    team = Team(topology, P, D)
    return team, Delays(_on_links(team, tau1, tau2), _on_links(team, tau2, tau1), actuation)


def accepts_loose_team(*, actuation: str | None = None) -> Callable[[_F], _F]:
    """Let ``f(team, delays, ...)`` also take ``f(topology, P, D, tau1, tau2, ...)`` (module doc).

    Parameters
    ----------
    actuation
        The loose form's keyword for the actuation delay (``"actuation_delay"``),
        which goes to :attr:`Delays.actuation`; None if it had none.
    """

    def decorate(func: _F) -> _F:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            if not is_loose(args, kwargs):
                return func(*args, **kwargs)
            bound = dict(zip(LOOSE_TEAM, args))
            for name in LOOSE_TEAM:
                if name in kwargs:
                    if name in bound:
                        raise InputError(f"{func.__name__}: {name} given twice")
                    bound[name] = kwargs.pop(name)
            missing = [n for n in LOOSE_TEAM if n not in bound]
            if missing:
                raise InputError(f"{func.__name__}: {', '.join(missing)} required and not given")
            # checked under the keyword the caller wrote
            ta = check_delay(actuation, kwargs.pop(actuation)) if actuation and actuation in kwargs else 0.0
            team, delays = team_and_delays(*(bound[n] for n in LOOSE_TEAM), actuation=ta)
            return func(team, delays, *args[len(LOOSE_TEAM):], **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate
