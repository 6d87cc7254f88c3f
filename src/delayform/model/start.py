"""Where the robots start: positions, headings and speed, given or drawn from a seed.

The state is constant before ``t = 0`` (the constant history of the paper's
the paper's eq. 2): positions ``x0`` and Cartesian velocities
``v0 = speed (cos theta0, sin theta0)``. What is not given is drawn from
:attr:`Start.seed`: positions uniform in ``[-L, L]^2`` with
``L = 5 max(1, sqrt(n / 6))`` (the density of the paper's six robots in a
10 x 10 square), headings uniform in ``[-pi, pi)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_magnitude, validated
from delayform.errors import SimulationInputError

__all__ = ["Start", "PAPER_SPEED"]

_Array = NDArray[np.float64]

#: the initial speed of the paper's simulations (m/s): ideal robots cannot start at rest
PAPER_SPEED = 1e-3

_UNITS = {"positions": "m", "headings": "rad", "speed": "m/s"}


def _numbers(name: str, value: ArrayLike) -> _Array:
    """Finite float64 numbers of sensible size, or SimulationInputError naming them as the old keyword did."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SimulationInputError(f"initial_{name} must be numbers") from exc
    if not np.all(np.isfinite(arr)):
        raise SimulationInputError(f"initial_{name} must be finite")
    # lengths and speeds; angles too (at 1e6 rad a float64 still resolves 1e-10 rad, at 1e300 nothing)
    check_magnitude(f"initial_{name}", arr, SimulationInputError, _UNITS[name])
    arr.setflags(write=False)
    return arr


def _rng(seed: object) -> np.random.Generator:
    """``numpy.random.default_rng(seed)`` for a seed numpy takes, else SimulationInputError."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise SimulationInputError(f"seed must be a non-negative integer, a numpy Generator or None, got {seed!r}")
    return np.random.default_rng(seed)


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class Start:
    """The robots' state at ``t = 0`` (and before: the history is constant).

    Parameters
    ----------
    positions
        ``(n, 2)`` positions (m); None: uniform random from ``seed`` (module doc).
    headings
        ``(n,)`` headings (rad); None: uniform random from ``seed``.
    speed
        Scalar or ``(n,)`` signed speeds (m/s); default 1e-3 as in the paper.
        The initial Cartesian velocity is ``speed (cos theta, sin theta)``.
    seed
        Seed of what is drawn: a non-negative integer, a
        ``numpy.random.Generator`` or None. A Monte Carlo replaces it per run,
        as it replaces the network's seed.

    Raises
    ------
    SimulationInputError
        For numbers that are not finite or of absurd size, or a bad seed;
        the shapes are checked against the team in :meth:`draw`.

    Examples
    --------
    >>> x0, th0, v0 = Start(positions=[[0, 0], [1, 0]], headings=[0, 0]).draw(2)
    >>> v0.tolist()
    [0.001, 0.001]
    """

    positions: ArrayLike | None = None
    headings: ArrayLike | None = None
    speed: ArrayLike = PAPER_SPEED
    seed: int | np.random.Generator | None = 0

    def __post_init__(self) -> None:
        for name in ("positions", "headings"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _numbers(name, getattr(self, name)))
        object.__setattr__(self, "speed", _numbers("speed", self.speed))
        if not isinstance(self.seed, np.random.Generator):
            _rng(self.seed)  # refuse a bad seed now, not when drawing

    def with_seed(self, seed: int | np.random.Generator | None) -> Start:
        """The same start with another seed (Monte Carlo runs).

        Parameters
        ----------
        seed
            As :attr:`seed`.
        """
        return Start(self.positions, self.headings, self.speed, seed)

    def draw(self, n: int) -> tuple[_Array, _Array, _Array]:
        """Positions ``(n, 2)``, headings ``(n,)`` and speeds ``(n,)``; what is missing is drawn from :attr:`seed`.

        Parameters
        ----------
        n
            The number of agents.

        Raises
        ------
        SimulationInputError
            When a given array does not fit a team of n.
        """
        rng = _rng(self.seed)
        half = 5.0 * max(1.0, math.sqrt(n / 6.0))
        x0 = rng.uniform(-half, half, size=(n, 2)) if self.positions is None else _shaped("positions", self.positions, (n, 2))
        th0 = rng.uniform(-np.pi, np.pi, size=n) if self.headings is None else _shaped("headings", self.headings, (n,))
        return x0, th0, _shaped("speed", self.speed, (n,))  # type: ignore[arg-type]


def _shaped(name: str, arr: _Array, shape: tuple[int, ...]) -> _Array:
    """``arr`` in ``shape`` (a scalar fills a vector), or SimulationInputError naming both shapes."""
    if arr.shape != shape:
        if arr.ndim == 0 and len(shape) == 1:
            return np.full(shape, float(arr))
        raise SimulationInputError(f"initial_{name} must have shape {shape}, got {arr.shape}")
    return np.array(arr)
