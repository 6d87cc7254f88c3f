"""Characteristic roots and their certificates.

``problem``             the quasi-polynomial solved for roots, its DDE realization, Newton polishing
``generator``           Chebyshev collocation of the infinitesimal generator (the seeds)
``argument_principle``  certified counts right of a line or inside a rectangle
``rightmost``           the certified rightmost root of one problem
``single``              public roots of one quasi-polynomial: ``roots_in``, ``rightmost_root``, ...
``family/``             every factor of the paper's eq. 3 at many delay pairs at once, vectorized
``dominant``            the formation's dominant root, dominant-root maps
``team_roots``          every root of every factor in a rectangle, for a whole team
``warm``                uncertified, warm-started rightmost real parts that steer local searches
"""

from delayform.analysis.roots.dominant import (
    DominantRoot,
    DominantRootMap,
    dominant_root,
    dominant_root_map,
)
from delayform.analysis.roots.single import (
    count_roots_right_of,
    relative_residual,
    rightmost_root,
    roots_in,
)
from delayform.analysis.roots.team_roots import factor_roots_in

__all__ = [
    "roots_in",
    "rightmost_root",
    "count_roots_right_of",
    "relative_residual",
    "factor_roots_in",
    "dominant_root",
    "dominant_root_map",
    "DominantRoot",
    "DominantRootMap",
]
