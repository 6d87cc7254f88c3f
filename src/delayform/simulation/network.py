"""The network's description, kept importable here: it lives with the problem's nouns in :mod:`delayform.model.network`.

``delayform.simulation.network.Network is delayform.model.Network``; what
each agent hears over it is computed in :mod:`delayform.simulation.reception`.
"""

from delayform.model.network import (
    BernoulliLoss,
    GilbertElliott,
    Jitter,
    LinkDelays,
    MeasurementNoise,
    Network,
    Sampling,
    SmoothVariation,
    check_link_matrix,
)

__all__ = [
    "LinkDelays",
    "Jitter",
    "SmoothVariation",
    "BernoulliLoss",
    "GilbertElliott",
    "Sampling",
    "MeasurementNoise",
    "Network",
    "check_link_matrix",
]
