"""Whether this machine can run a team as processes at its control period: asked before any process starts.

A fleet run is ``n + 1`` operating-system processes (the robots and the
world) beside the parent that records them. Each takes its messages from its
channels every millisecond, and every control period each robot ticks its
controller and publishes its state and command while the world steps it and
publishes its odometry. Their CPU demand, in cores::

    (n + 2) POLL_CORES + (n TICK_SECONDS + E MESSAGE_SECONDS) / period

with E the links (state messages received per period). With a ROS domain
(:mod:`delayform.fleet.rmw`) every robot's state, command and odometry is
published a second time on its rmw_zenoh key: ``n ROS_TICK_SECONDS`` more per period. The constants are
CPU seconds measured on the reference machine (2 cores, Python 3.11, Zenoh on
the loopback; docs/benchmarks.md, the team as processes): fitted to the paper's
six Create 3 robots at 10 and 40 ms and the complete graph of six at 10 ms,
whole runs of 5 and 20 s differenced so that start-up and the writing of the
results cancel. On another machine they are scaled by the time the
controller's own tick takes there against the reference (:func:`speed_factor`).

A run whose demand exceeds :data:`HEADROOM` of the cores would miss control
ticks however it is scheduled (the processes share the cores with nothing
left for the operating system's slack), so :func:`check_machine` refuses it
in one line saying how many cores it would need; memory is the general budget
(:func:`delayform.resources.require`) at :data:`PROCESS_BYTES` a process.
"""

from __future__ import annotations

import os
import time

from delayform.errors import FleetError
from delayform.resources import require

__all__ = ["POLL_CORES", "TICK_SECONDS", "MESSAGE_SECONDS", "ROS_TICK_SECONDS", "PROCESS_BYTES", "HEADROOM",
           "fleet_demand", "speed_factor", "check_machine"]  # fmt: skip

#: cores one process spends taking its messages from its channels every millisecond
POLL_CORES = 0.03
#: CPU seconds per robot and control tick: the controller, its command, the world's step and odometry for it
TICK_SECONDS = 2.0e-4
#: CPU seconds per state message: published, delivered, decoded, held in the playout buffer
MESSAGE_SECONDS = 7.4e-5
#: CPU seconds per robot and control tick for the rmw_zenoh copies of its state, command and odometry: three
#: puts at 19 us each when a ROS 2 node subscribes to them (2.3 us when none does), measured at one put a millisecond
ROS_TICK_SECONDS = 6.0e-5
#: resident memory planned per process: a running robot or world holds 43 MB (Python, NumPy, Zenoh; 98 MB while
#: they imported SciPy), the recording parent more (the run's messages, the simulator): 100 MB each keeps room
PROCESS_BYTES = 100 * 2**20
#: the share of the cores a run may plan to use
HEADROOM = 0.8
#: CPU seconds of :func:`_reference_ticks` on the reference machine (median of 5, quiet)
REFERENCE_TICKS_SECONDS = 0.0071


def fleet_demand(n: int, links: int, period: float, *, factor: float = 1.0, ros: bool = False) -> float:
    """Cores a run of ``n`` robots with ``links`` links at ``period`` seconds keeps busy (module doc).

    Parameters
    ----------
    n, links
        Robots and the links they receive on (nonzero off-diagonal entries of C).
    period
        The control period (s).
    factor
        This machine's CPU time for the same work against the reference machine's (:func:`speed_factor`).
    ros
        Whether the processes also publish as rmw_zenoh does (a ROS domain, module doc).

    >>> round(fleet_demand(6, 13, 0.01), 2)
    0.46
    """
    poll, work = _demand_parts(n, links, factor=factor, ros=ros)
    return poll + work / period


def _demand_parts(n: int, links: int, *, factor: float, ros: bool) -> tuple[float, float]:
    """(cores the polling keeps busy, CPU seconds of work per control period): demand = poll + work / period."""
    tick = TICK_SECONDS + (ROS_TICK_SECONDS if ros else 0.0)
    return factor * (n + 2) * POLL_CORES, factor * (n * tick + links * MESSAGE_SECONDS)


def _reference_ticks() -> float:
    """CPU seconds of 1,000 ticks of one Create 3 controller hearing two neighbours (the work a robot's tick does)."""
    from delayform.deploy.controller import FormationController, NeighbourMessage
    from delayform.model.profiles import robot_profile

    ctrl = FormationController(robot=1, P=1.0, D=1.5, tau1=0.3, tau2=0.2, weights={2: 0.5, 3: 0.5},
                               limits=robot_profile("create3").limits)  # fmt: skip
    start = time.process_time()
    for k in range(1000):
        t = 0.01 * k
        for j in (2, 3):
            ctrl.receive(NeighbourMessage(j, t, 1.0 + 0.001 * k, 0.5 * j, 0.1, 0.0))
        ctrl.tick(t, 0.01 * k, 0.0, 0.1, 0.1)
    return time.process_time() - start


def speed_factor() -> float:
    """This machine's CPU time for a controller's ticks against the reference machine's, within [0.25, 4]."""
    measured = min(_reference_ticks() for _ in range(3))
    return min(4.0, max(0.25, measured / REFERENCE_TICKS_SECONDS))


def check_machine(n: int, links: int, period: float, *, cores: int | None = None,
                  factor: float | None = None, ros: bool = False) -> float:  # fmt: skip
    """The run's demand in cores; :class:`~delayform.errors.FleetError` when this machine cannot keep the period.

    Parameters
    ----------
    n, links, period, ros
        As for :func:`fleet_demand`.
    cores
        The cores available (default: those this process may run on).
    factor
        As for :func:`fleet_demand` (default: :func:`speed_factor`, measured now).

    Raises
    ------
    FleetError
        When the demand exceeds :data:`HEADROOM` of the cores.
    ResourceLimitError
        When the processes would need more memory than the budget allows.
    """
    require(what=f"a fleet of {n} robot processes, the world and the recorder", nbytes=(n + 2) * PROCESS_BYTES,
            setting="the number of robots")  # fmt: skip
    cores = cores or len(os.sched_getaffinity(0))
    factor = speed_factor() if factor is None else factor
    poll, work = _demand_parts(n, links, factor=factor, ros=ros)
    demand = poll + work / period
    if demand > HEADROOM * cores:
        spare = HEADROOM * cores - poll  # what the polling leaves for the ticks and messages
        hint = (f"a control period of at least {work / spare * 1e3:.3g} ms, or fewer robots" if spare > 0
                else "fewer robots (their processes' polling alone fills the cores)")
        raise FleetError(f"{n} robot processes at a {period * 1e3:g} ms control period would keep {demand:.2g} cores busy "
                         f"and need about {demand / HEADROOM:.2g} to hold it; this machine has {cores}: choose {hint}")  # fmt: skip
    return demand
