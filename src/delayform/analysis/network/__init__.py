"""Guarantees for real networks: per-link delays, boxes of delays, jitter (issue 20).

``links``           per-link delays, their checks, the N x N matrix quasi-polynomial
``discretization``  Chebyshev collocation of the 2N-state DDE (seeds)
``count``           certified count of roots of det M right of a line
``per_link``        the certified dominant root with per-link delays
"""

from delayform.analysis.network.links import LinkTeam, link_team
from delayform.analysis.network.per_link import LinkDominantRoot, link_dominant_root

__all__ = ["LinkTeam", "link_team", "LinkDominantRoot", "link_dominant_root"]
