"""Simulation of the team, by concept: agent models, delayed integrators, bodies, single runs, experiments.

Subpackages, from the bottom up: :mod:`~delayform.simulation.models` (agent
models and the commands robots execute), :mod:`~delayform.simulation.delayed`
(RK4 with a bounded Hermite history, the actuation buffer, what each agent
hears over an imperfect network), :mod:`~delayform.simulation.bodies`
(closest approach, the safety filter, slot assignment),
:mod:`~delayform.simulation.physics` (robots with mass in MuJoCo),
:mod:`~delayform.simulation.runs` (``simulate``, the integrator table, run
options, the loose call forms, ``Trajectory``) and
:mod:`~delayform.simulation.experiments` (Monte Carlo runs and sweeps). The
network's description is a noun, :mod:`delayform.model.network`. Their public
names are re-exported here.
"""

from delayform.simulation.models.commands import LimitExceedance, RobotCommands
from delayform.simulation.delayed.integrator import stated_order
from delayform.simulation.experiments.montecarlo import MonteCarloResult, monte_carlo
from delayform.model.network import (
    BernoulliLoss,
    GilbertElliott,
    Jitter,
    LinkDelays,
    MeasurementNoise,
    Network,
    Sampling,
    SmoothVariation,
)
from delayform.simulation.bodies.approach import Approach, Contact, closest_approach
from delayform.simulation.models.robots import IROBOT_CREATE, REST_SPEED, Robot, RobotLimits
from delayform.simulation.runs.integrators import INTEGRATORS
from delayform.simulation.runs.options import RunOptions
from delayform.simulation.runs.runner import MODELS, paper_simulations, simulate
from delayform.simulation.runs.trajectory import SETTLING_FRACTION, STATUSES, Trajectory

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
