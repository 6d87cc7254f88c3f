"""The team in the loop: one OS process per robot and a world process, talking over Zenoh on the loopback.

:func:`run_fleet` (``delayform fleet``) runs each robot's
:class:`~delayform.deploy.controller.FormationController` in its own process
at the control period on the wall clock, a world process that moves the
robots (:mod:`~delayform.fleet.world`), CDR-encoded ROS 2 messages on
ROS 2 key expressions (:mod:`~delayform.fleet.wire`), the scenario's network
(per-link delays, jitter, loss, sampling, noise) on reception with the
simulator's draws (:mod:`~delayform.fleet.plan`), robots killed and restarted
(:mod:`~delayform.fleet.faults`), a live view for Foxglove (:mod:`~delayform.fleet.live`), the topics also
published as rmw_zenoh does for ROS 2 nodes (:mod:`~delayform.fleet.rmw`), and measures what happened against the analysis
(:mod:`~delayform.fleet.outcome`). Needs the ``fleet`` extra.

The names are imported on first use: the robot and world processes start
from :mod:`delayform.fleet.agents` and must not pay for the rest.
"""

from __future__ import annotations

from delayform._lazy import lazy_names

__all__ = ["run_fleet", "FleetRun", "decay_rate", "Fault"]

_WHERE = {"run_fleet": "delayform.fleet.run", "FleetRun": "delayform.fleet.outcome", "decay_rate": "delayform.fleet.outcome",
          "Fault": "delayform.fleet.faults"}

__getattr__, __dir__ = lazy_names(__name__, _WHERE)
