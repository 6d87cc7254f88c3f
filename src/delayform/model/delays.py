"""The delays: how late each agent hears its neighbours' positions and velocities, and acts.

The paper's delays are one pair on every link: ``tau1`` on positions,
``tau2`` on velocities (paper, eq. 1). Real networks differ from link to
link, so a :class:`Delays` holds either two numbers (:attr:`Delays.kind` is
``"uniform"``) or two ``n x n`` matrices, entry ``[i, k]`` for what agent i
hears from agent k (``"per_link"``), and the actuation delay ``tau_a`` with
which every robot executes its own command. Which of the two a computation
faces is said by :attr:`Delays.kind`, never guessed from an array's shape.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_delay_array, validated
from delayform.errors import DelayError

__all__ = ["Delays"]

_Matrix = NDArray[np.float64]


def _delay(name: str, value: Any) -> float | _Matrix:
    """A non-negative delay, scalar or square matrix, or DelayError naming it."""
    if np.ndim(value) == 0:
        return check_delay(name, value)
    arr = check_delay_array(name, value)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise DelayError(f"{name} must be a number or a square n x n matrix (one entry per pair of agents), "
                         f"got shape {arr.shape}")  # fmt: skip
    arr.setflags(write=False)
    return arr


@validated(DelayError)
@dataclass(frozen=True, eq=False)
class Delays:
    """The delays of the protocol (paper, eq. 1) and of the robots' actuators.

    Parameters
    ----------
    tau1, tau2
        Position and velocity delays (s): two non-negative numbers (the same
        on every link, as in the paper), or two ``n x n`` matrices with entry
        ``[i, k]`` for what agent i receives from agent k (entries off the
        links are ignored). Both scalars or both matrices.
    actuation
        tau_a >= 0 (s): every robot executes its command this late. 0: the
        paper's model.

    Raises
    ------
    DelayError
        For a negative, non-finite or misshapen delay, or one scalar beside
        one matrix.

    Examples
    --------
    >>> Delays(0.3, 0.2).kind
    'uniform'
    >>> import numpy as np
    >>> d = Delays(np.full((3, 3), 0.3), np.full((3, 3), 0.2))
    >>> d.kind, d.n
    ('per_link', 3)
    """

    tau1: float | _Matrix
    tau2: float | _Matrix
    actuation: float = 0.0

    def __post_init__(self) -> None:
        tau1, tau2 = _delay("tau1", self.tau1), _delay("tau2", self.tau2)
        if np.ndim(tau1) != np.ndim(tau2):
            raise DelayError("tau1 and tau2 must both be numbers (the same on every link) or both "
                             "n x n matrices (per link)")  # fmt: skip
        if np.ndim(tau1) and np.shape(tau1) != np.shape(tau2):
            raise DelayError(f"tau1 and tau2 must have one shape, got {np.shape(tau1)} and {np.shape(tau2)}")
        object.__setattr__(self, "tau1", tau1)
        object.__setattr__(self, "tau2", tau2)
        object.__setattr__(self, "actuation", check_delay("actuation delay", self.actuation))

    @classmethod
    def of(cls, delays: Delays | tuple[ArrayLike, ArrayLike]) -> Delays:
        """A :class:`Delays` as given, or made from a pair ``(tau1, tau2)``.

        Parameters
        ----------
        delays
            A :class:`Delays`, or a pair of numbers or matrices.
        """
        if isinstance(delays, Delays):
            return delays
        try:
            tau1, tau2 = delays  # type: ignore[misc]
        except (TypeError, ValueError) as exc:
            raise DelayError(f"delays must be a Delays or a pair (tau1, tau2), got {type(delays).__name__}") from exc
        return cls(tau1, tau2)  # type: ignore[arg-type]

    @property
    def kind(self) -> Literal["uniform", "per_link"]:
        """``"uniform"`` (one pair on every link) or ``"per_link"`` (two matrices)."""
        return "uniform" if np.ndim(self.tau1) == 0 else "per_link"

    @property
    def n(self) -> int | None:
        """The team size the matrices are for, or None for uniform delays."""
        return None if self.kind == "uniform" else int(np.shape(self.tau1)[0])

    @property
    def pair(self) -> tuple[float, float]:
        """``(tau1, tau2)`` of uniform delays.

        Raises
        ------
        DelayError
            For per-link delays: use :meth:`uniform_on` to read one pair off
            matrices that are equal on every link.
        """
        if self.kind != "uniform":
            raise DelayError("these delays differ per link: they have no single pair (tau1, tau2)")
        return float(self.tau1), float(self.tau2)  # type: ignore[arg-type]

    def check_team(self, n: int) -> None:
        """Refuse matrices that are not ``n x n``.

        Parameters
        ----------
        n
            The number of agents.
        """
        if self.kind == "per_link" and self.n != n:
            raise DelayError(f"the per-link delays are {self.n} x {self.n} but the team has {n} agents")

    def uniform_on(self, adjacency: ArrayLike) -> tuple[float, float] | None:
        """The single pair ``(tau1, tau2)`` these delays are on the links of ``adjacency``, or None.

        Uniform delays give their pair; matrices give it when every link
        carries the same two delays (entries off the links are ignored).

        Parameters
        ----------
        adjacency
            ``n x n`` adjacency of the team (non-zero where i hears k).
        """
        if self.kind == "uniform":
            return self.pair
        A = np.asarray(adjacency)
        self.check_team(A.shape[0])
        links = A != 0
        if not links.any():
            return None
        t1, t2 = np.asarray(self.tau1)[links], np.asarray(self.tau2)[links]
        if np.all(t1 == t1[0]) and np.all(t2 == t2[0]):
            return float(t1[0]), float(t2[0])
        return None

    def with_actuation(self, actuation: float) -> Delays:
        """The same communication delays with another actuation delay.

        Parameters
        ----------
        actuation
            tau_a >= 0 (s).
        """
        return Delays(self.tau1, self.tau2, actuation)

    def describe(self) -> str:
        """One line: ``"tau1 = 0.3 s, tau2 = 0.2 s"`` (per-link: their ranges)."""
        if self.kind == "uniform":
            text = f"tau1 = {float(self.tau1):g} s, tau2 = {float(self.tau2):g} s"  # type: ignore[arg-type]
        else:
            t1, t2 = np.asarray(self.tau1), np.asarray(self.tau2)
            text = (f"per-link tau1 in [{t1.min():g}, {t1.max():g}] s, "
                    f"tau2 in [{t2.min():g}, {t2.max():g}] s")  # fmt: skip
        return text + (f", actuation {self.actuation:g} s" if self.actuation else "")
