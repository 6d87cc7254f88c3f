"""Real robot profiles, kept importable here: they live with the problem's nouns in :mod:`delayform.model.profiles`.

``delayform.deploy.profiles.RobotProfile is delayform.model.RobotProfile``.
"""

from delayform.model.profiles import PROFILES, Arena, RobotProfile, profile_names, robot_profile

__all__ = ["RobotProfile", "Arena", "PROFILES", "robot_profile", "profile_names"]
