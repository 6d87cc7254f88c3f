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

from __future__ import annotations

from typing import TYPE_CHECKING

from delayform._lazy import lazy_names

if TYPE_CHECKING:  # pragma: no cover - the names, for type checkers and IDEs
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

#: Where each name lives: imported on first use, so that a process that needs one noun (a robot's
#: controller needs its limits) does not import the team's sparse algebra and SciPy with it
_WHERE = {
    "CREATE_CHASSIS": "delayform.model.chassis",
    "Chassis": "delayform.model.chassis",
    "Delays": "delayform.model.delays",
    "IROBOT_CREATE": "delayform.model.limits",
    "RobotLimits": "delayform.model.limits",
    "BernoulliLoss": "delayform.model.network",
    "GilbertElliott": "delayform.model.network",
    "Jitter": "delayform.model.network",
    "LinkDelays": "delayform.model.network",
    "MeasurementNoise": "delayform.model.network",
    "Network": "delayform.model.network",
    "Sampling": "delayform.model.network",
    "SmoothVariation": "delayform.model.network",
    "PROFILES": "delayform.model.profiles",
    "Arena": "delayform.model.profiles",
    "RobotProfile": "delayform.model.profiles",
    "profile_names": "delayform.model.profiles",
    "robot_profile": "delayform.model.profiles",
    "MODELS": "delayform.model.robot",
    "REST_SPEED": "delayform.model.robot",
    "SAFETY_FILTERS": "delayform.model.robot",
    "BarrierFilter": "delayform.model.robot",
    "Robot": "delayform.model.robot",
    "check_safety": "delayform.model.robot",
    "PAPER_SPEED": "delayform.model.start",
    "Start": "delayform.model.start",
    "Team": "delayform.model.team",
}


__getattr__, __dir__ = lazy_names(__name__, _WHERE)

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
