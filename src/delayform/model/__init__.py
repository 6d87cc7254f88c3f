"""The problem's nouns: the team, its delays, the robot and the network.

Everything delayform computes is about a :class:`Team` (who hears whom, with
which gains) under :class:`Delays` (how late they hear it); a simulation adds
the :class:`Robot` (agent model, limits or the real robot's
:class:`RobotProfile`, body, safety filter, and for robots with mass the
:class:`Chassis`), the :class:`Network` (per-link
and varying delays, jitter, loss, sampling, noise) and the :class:`Start`
(where the robots are at t = 0). Each noun checks its own
fields once, when it is built, so the layers above take it whole and never
check or rename its parts again.
"""

from delayform.model.chassis import CREATE_CHASSIS, Chassis
from delayform.model.delays import Delays
from delayform.model.limits import IROBOT_CREATE, RobotLimits
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
from delayform.model.profiles import PROFILES, Arena, RobotProfile, profile_names, robot_profile
from delayform.model.robot import MODELS, REST_SPEED, SAFETY_FILTERS, BarrierFilter, Robot, check_safety
from delayform.model.start import PAPER_SPEED, Start
from delayform.model.team import Team

__all__ = [
    "Team",
    "Delays",
    "Robot",
    "Start",
    "PAPER_SPEED",
    "RobotLimits",
    "IROBOT_CREATE",
    "RobotProfile",
    "Arena",
    "Chassis",
    "CREATE_CHASSIS",
    "PROFILES",
    "robot_profile",
    "profile_names",
    "BarrierFilter",
    "check_safety",
    "SAFETY_FILTERS",
    "MODELS",
    "REST_SPEED",
    "Network",
    "LinkDelays",
    "SmoothVariation",
    "Jitter",
    "BernoulliLoss",
    "GilbertElliott",
    "Sampling",
    "MeasurementNoise",
]
