"""CTCR: the exact stability map in the (tau1, tau2) plane (Section "Stability Analysis Using CTCR").

``phase``          crossing sets in phase space, (omega, theta1, theta2) with q(j omega) = 0
``curves``         their kernel and offspring images in the delay plane (paper, eq. 6)
``family_curves``  the curves of every factor of the paper's eq. 3 at once, vectorized
``count``          NU(tau1, tau2) from the curves and their root tendencies
``stability_map``  the public maps: ``crossing_map``, ``stability_map``, ``StabilityMap``
"""

from delayform.analysis.ctcr.stability_map import (
    PAPER_POINTS,
    CrossingCurve,
    StabilityMap,
    crossing_map,
    curve_residual,
    stability_map,
)

__all__ = ["CrossingCurve", "StabilityMap", "crossing_map", "stability_map", "curve_residual", "PAPER_POINTS"]
