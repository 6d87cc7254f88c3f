"""The team: its communication topology and the gains of the protocol (paper, eq. 1).

A :class:`Team` is what the characteristic equation (paper, eq. 3) is
factored by: the eigenvalues of C come from its topology, P and D enter every
factor. It is checked once, when it is made: the topology must have a
spanning tree (paper, Lemma 3: without one no gains and no delays bring the
robots to formation) and both gains must be positive and of a size the
analysis handles.
"""

from __future__ import annotations

from dataclasses import dataclass

from delayform._validation import check_gains, validated
from delayform.errors import TopologyError
from delayform.topology import Topology

__all__ = ["Team"]


@validated(TopologyError)
@dataclass(frozen=True)
class Team:
    """A team of agents under the protocol of the paper's eq. 1.

    Parameters
    ----------
    topology
        Who receives from whom (row i of the adjacency is what agent i
        hears); it must have a spanning tree.
    P, D
        The position and velocity gains, positive.

    Raises
    ------
    NoSpanningTreeError
        When the topology has no spanning tree.
    GainError
        When a gain is not a positive real number of moderate size.

    Examples
    --------
    >>> from delayform import paper_six
    >>> team = Team(paper_six(), P=1, D=0.5)
    >>> team.n, team.P, team.D
    (6, 1.0, 0.5)
    """

    topology: Topology
    P: float
    D: float

    def __post_init__(self) -> None:
        if not isinstance(self.topology, Topology):
            raise TopologyError(f"topology must be a Topology, got {type(self.topology).__name__}")
        P, D = check_gains(self.P, self.D)
        object.__setattr__(self, "P", P)
        object.__setattr__(self, "D", D)
        self.topology.require_spanning_tree()

    @property
    def n(self) -> int:
        """The number of agents."""
        return self.topology.n

    def with_gains(self, P: float, D: float) -> Team:
        """The same topology with other gains (checked as at construction).

        Parameters
        ----------
        P, D
            The new gains.
        """
        return Team(self.topology, P, D)

    def describe(self) -> str:
        """One line: ``"paper-six (6 agents), P = 1, D = 0.5"``."""
        return f"{self.topology.name} ({self.n} agents), P = {self.P:g}, D = {self.D:g}"
