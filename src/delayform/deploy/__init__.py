"""From design to robots: real robot profiles, the on-robot controller and ROS 2 recordings.

Modules: :mod:`~delayform.deploy.profiles` (limits, geometry and arenas of
real robots, each number with its source), :mod:`~delayform.deploy.controller`
(one robot's protocol at each control tick, no ROS dependency),
:mod:`~delayform.deploy.recording` (a run as an MCAP file with ROS 2
messages), :mod:`~delayform.deploy.fit` (whether a formation fits a
robot's body and arena). The check before a real run, which needs the
analyses, is :mod:`delayform.report.check`.
"""

from delayform.deploy.controller import Command, FormationController, NeighbourMessage
from delayform.deploy.profiles import PROFILES, Arena, RobotProfile, profile_names, robot_profile

__all__ = [
    "PROFILES",
    "Arena",
    "RobotProfile",
    "profile_names",
    "robot_profile",
    "FormationController",
    "NeighbourMessage",
    "Command",
]
