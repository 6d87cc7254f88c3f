"""The nouns: a Team and its Delays are checked once, when they are made."""

from __future__ import annotations

import numpy as np
import pytest

from delayform import Delays, Team, Topology, paper_six
from delayform.errors import DelayError, GainError, NoSpanningTreeError, TopologyError


def test_team_checks_its_topology_and_gains_once() -> None:
    team = Team(paper_six(), 1, 0.5)
    assert (team.n, team.P, team.D) == (6, 1.0, 0.5)
    assert team.with_gains(2, 1).P == 2.0
    two_pairs = Topology.from_adjacency([[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]])
    with pytest.raises(NoSpanningTreeError):
        Team(two_pairs, 1, 0.5)
    with pytest.raises(GainError):
        Team(paper_six(), -1, 0.5)
    with pytest.raises(TopologyError):
        Team(np.eye(3), 1, 0.5)  # type: ignore[arg-type]


def test_delays_say_their_kind_and_refuse_mixed_or_misshapen_forms() -> None:
    assert Delays(0.3, 0.2).pair == (0.3, 0.2)
    A = paper_six().adjacency
    equal = Delays(np.full((6, 6), 0.3), np.full((6, 6), 0.2))
    assert equal.kind == "per_link" and equal.uniform_on(A) == (0.3, 0.2)
    varied = np.full((6, 6), 0.3)
    varied[np.nonzero(A)[0][0], np.nonzero(A)[1][0]] = 0.4
    assert Delays(varied, np.full((6, 6), 0.2)).uniform_on(A) is None
    off_link = np.full((6, 6), 0.3)
    off_link[A == 0] = 9.0  # entries off the links change nothing
    assert Delays(off_link, np.full((6, 6), 0.2)).uniform_on(A) == (0.3, 0.2)
    with pytest.raises(DelayError, match="per link"):
        equal.pair
    with pytest.raises(DelayError, match="both"):
        Delays(0.3, np.full((6, 6), 0.2))
    with pytest.raises(DelayError, match="square"):
        Delays(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(DelayError):
        Delays(-0.1, 0.2)
    with pytest.raises(DelayError, match="7 agents"):
        equal.check_team(7)
    assert Delays.of((1, 2)).pair == (1.0, 2.0) and Delays(0.3, 0.2, actuation=0.1).actuation == 0.1
