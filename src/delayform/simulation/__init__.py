"""Simulation of the team: agent and robot models, the delayed integrator, runs and commands, networks.

Modules, by concept: :mod:`~delayform.simulation.integrator` (RK4 with a
bounded Hermite history), :mod:`~delayform.simulation.robots` (agent models,
robot limits, ideal commands), :mod:`~delayform.simulation.commands` (the
commands each robot executes), :mod:`~delayform.simulation.trajectory` (the
result and its metrics), :mod:`~delayform.simulation.models` (the integrator
table, one entry per agent model), :mod:`~delayform.simulation.options` (how a
run is carried out), :mod:`~delayform.simulation.runner` (``simulate``;
:mod:`~delayform.simulation.compat` keeps its loose call form),
:mod:`~delayform.simulation.network` (imperfect networks),
:mod:`~delayform.simulation.reception` (what each agent hears, the per-link
integrator), :mod:`~delayform.simulation.montecarlo` (seeded Monte Carlo runs).
Their public names are re-exported here.
"""

from delayform.simulation.commands import LimitExceedance, RobotCommands
from delayform.simulation.integrator import stated_order
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
from delayform.simulation.bodies import Approach, Contact, closest_approach
from delayform.simulation.robots import IROBOT_CREATE, REST_SPEED, Robot, RobotLimits
from delayform.simulation.models import INTEGRATORS
from delayform.simulation.options import RunOptions
from delayform.simulation.runner import MODELS, paper_simulations, simulate
from delayform.simulation.trajectory import SETTLING_FRACTION, STATUSES, Trajectory

__all__ = [
    "MODELS",
    "REST_SPEED",
    "SETTLING_FRACTION",
    "STATUSES",
    "IROBOT_CREATE",
    "RobotLimits",
    "Robot",
    "Contact",
    "Approach",
    "closest_approach",
    "RobotCommands",
    "LimitExceedance",
    "Trajectory",
    "simulate",
    "RunOptions",
    "INTEGRATORS",
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
