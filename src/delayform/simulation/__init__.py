"""Simulation of the team: agent and robot models, the delayed integrator, networks, Monte Carlo.

The public names of :mod:`delayform.simulation.runner`,
:mod:`delayform.simulation.network` and :mod:`delayform.simulation.montecarlo`
are re-exported here.
"""

from delayform.simulation.montecarlo import MonteCarloResult, monte_carlo
from delayform.simulation.network import (
    BernoulliLoss,
    GilbertElliott,
    Jitter,
    LinkDelays,
    MeasurementNoise,
    Network,
    Sampling,
    SmoothVariation,
)
from delayform.simulation.runner import (
    MIN_SPEED,
    MODELS,
    SETTLING_FRACTION,
    Trajectory,
    paper_simulations,
    simulate,
    stated_order,
)

__all__ = [
    "MODELS",
    "MIN_SPEED",
    "SETTLING_FRACTION",
    "Trajectory",
    "simulate",
    "stated_order",
    "paper_simulations",
    "Network",
    "LinkDelays",
    "SmoothVariation",
    "Jitter",
    "BernoulliLoss",
    "GilbertElliott",
    "Sampling",
    "MeasurementNoise",
    "monte_carlo",
    "MonteCarloResult",
]
