"""The problem's nouns: the team, its delays (and, above them, the robot and the network).

Everything delayform computes is about a :class:`Team` (who hears whom, with
which gains) under :class:`Delays` (how late they hear it). Each noun checks
its own fields once, when it is built, so the layers above take it whole and
never check or rename its parts again.
"""

from delayform.model.delays import Delays
from delayform.model.team import Team

__all__ = ["Team", "Delays"]
