"""The team in the loop: one OS process per robot and a world process, talking over Zenoh on the loopback.

:func:`run_fleet` (``delayform fleet``) runs each robot's
:class:`~delayform.deploy.controller.FormationController` in its own process
at the control period on the wall clock, a world process that moves the
robots (:mod:`~delayform.fleet.world`), CDR-encoded ROS 2 messages on
ROS 2 key expressions (:mod:`~delayform.fleet.wire`), the scenario's network
loss on reception, and measures what happened against the analysis
(:mod:`~delayform.fleet.outcome`). Needs the ``fleet`` extra.
"""

from delayform.fleet.outcome import FleetRun, decay_rate
from delayform.fleet.run import run_fleet

__all__ = ["run_fleet", "FleetRun", "decay_rate"]
