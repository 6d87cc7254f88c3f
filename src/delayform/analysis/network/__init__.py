"""Guarantees for real networks: per-link delays, boxes of delays, jitter, packet loss.

``links``           per-link delays, their checks, the N x N matrix quasi-polynomial
``discretization``  Chebyshev collocation of the 2N-state DDE (seeds)
``count``           certified count of roots of det M right of a line
``per_link``        the certified dominant root with per-link delays
``box``             a box of constant per-link delays certified stable
``jitter``          the jitter margin for time-varying per-link delays (small gain)
``loss``            mean-square stability under packet loss, exactly (lifted jump-linear model)
``bursty``          the same under Gilbert-Elliott (bursty) loss: a Markov jump-linear model
"""

from delayform.analysis.network.box import RobustStability, robust_stability
from delayform.analysis.network.jitter import JitterMargin, JitterMarginMap, jitter_margin, jitter_margin_map
from delayform.analysis.network.loss import MeanSquareStability, mean_square_stability
from delayform.analysis.network.bursty import bursty_mean_square_stability
from delayform.analysis.network.links import LinkTeam, link_team
from delayform.analysis.network.per_link import LinkDominantRoot, link_dominant_root

__all__ = ["LinkTeam", "link_team", "LinkDominantRoot", "link_dominant_root", "RobustStability", "robust_stability",
           "JitterMargin", "JitterMarginMap", "jitter_margin", "jitter_margin_map",
           "MeanSquareStability", "mean_square_stability", "bursty_mean_square_stability"]
