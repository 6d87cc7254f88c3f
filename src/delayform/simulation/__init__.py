"""Simulation of the team: agent and robot models, the delayed integrator, runs.

The public names of :mod:`delayform.simulation.runner` are re-exported here.
"""

from delayform.simulation.runner import (
    MIN_SPEED,
    MODELS,
    SETTLING_FRACTION,
    Trajectory,
    paper_simulations,
    simulate,
    stated_order,
)

__all__ = ["MODELS", "MIN_SPEED", "SETTLING_FRACTION", "Trajectory", "simulate", "stated_order", "paper_simulations"]
