"""What a fleet run did, beside what the analysis promised for the same team at the same delays.

From the processes' logs (:mod:`delayform.fleet.agents`):

Per link (receiver i, informer k)
    The link's design delays (``tau1_ik``, ``tau2_ik``: the scenario's
    per-link delays, else (tau1, tau2)) beside the measured ones (the median
    applied delay), the network latency of each state message (receipt, when the receiving
    process took it from its channel, within a millisecond of its
    arrival, minus the sender's stamp), the delay the controller actually applied at each tick (the tick's
    time minus the stamp of the newest message it had received that was due,
    ``stamp + d <= t`` with d the link's delay plus the packet's jitter:
    what the playout buffer hands the controller), the receiving robot's ticks missed and late,
    how long that message waited in the buffer (playout), and the messages
    sent, received, lost on the way and dropped by the scenario's network.
    With a playout buffer the applied delay lies in ``[tau_ik, tau_ik + h)`` (h the
    control period) when the network is faster than the design and there is no jitter.
Per robot
    Its processes (more than one after a fault's restart) and when each
    replacement first ticked, the intervals in which a fault left it silent
    (:func:`silent_intervals`), ticks run, missed (a deadline that passed while the process waited for
    the CPU) and late (woken more than :data:`LATE_FRACTION` of a period after
    its deadline), the lateness's median, 99th percentile and largest value,
    and the controller's :attr:`~delayform.deploy.controller.Command.lag`.
The team
    The formation error of the true states the world integrated (RMS
    distance from the shape after removing the common offset), its settling
    time (:data:`~delayform.simulation.runs.trajectory.SETTLING_FRACTION`), the
    closest approach of two robots, and the measured decay rate: the slope of
    a least-squares line through ``log e(t)`` over the linear phase
    (:func:`linear_decay`): after the last control tick at which a robot's
    limits changed its command (the speed cap, the turn or acceleration
    limits: there the error falls at what the actuators allow, not at the
    dominant root's rate), once the error is below ``FIT_WINDOW[0]`` of its
    initial value, and while it stays above :data:`FLOOR_MARGIN` times its
    floor (the level it holds at the end of the run: the wobble left by the
    ticks' timing and the turn law's softening at rest, docs/theory.md; below
    a millimetre on the Create 3 example) and above ``FIT_WINDOW[1]`` of the
    initial error. The summary names the window (``decay_window``) and how
    long it would have to be for its slope to be the dominant root's
    (``decay_window_needed_s``, :func:`window_needed`). Beside them:
    the exact CTCR chart's verdict at (tau1, tau2), the dominant root's decay
    rate ``-Re s`` of the formation modes (:func:`delayform.dominant_root`),
    and the simulator's settling time, closest approach and its own error's
    decay fitted the same way. With per-link delays the chart and the
    dominant root are those of the nominal pair (they do not cover other
    delays; ``per_link_delays`` says so): the simulator, run over the same
    network, is then the promise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.fleet.agents import TICK_COLUMNS
from delayform.fleet.plan import LinkPlan
from delayform.model import Team
from delayform.simulation.bodies.approach import closest_approach
from delayform.model.network import Network
from delayform.simulation.models.robots import RobotLimits
from delayform.simulation.runs.trajectory import Trajectory, formation_error, settling_time

__all__ = ["FleetRun", "measure", "decay_rate", "linear_decay", "DecayFit", "window_needed", "saturated", "silent_intervals",
           "FIT_WINDOW", "FLOOR_MARGIN", "FLOOR_TAIL", "SATURATION_TOLERANCE", "LATE_FRACTION"]

_Array = NDArray[np.float64]

#: the decay is fitted where the error is between these fractions of its initial value
FIT_WINDOW = (0.3, 0.003)

#: the fit stops where the error falls to this many times its floor (the floor's own wobble stays out of the slope)
FLOOR_MARGIN = 3.0

#: the floor is the median error over this last fraction of the run
FLOOR_TAIL = 0.1

#: a command is saturated when a limit changed it by more than this fraction of what the controller asked
SATURATION_TOLERANCE = 0.01

#: messages sent in the last this many seconds are not counted as sent or lost
_SETTLE = 0.1

#: a tick is late when it woke more than this fraction of a period after its deadline
LATE_FRACTION = 0.2


def decay_rate(times: _Array, error: _Array, *, window: tuple[float, float] = FIT_WINDOW) -> float:
    """The decay rate (1/s) of ``error``: minus the slope of a least-squares line through log error.

    The fit starts when the error first falls to ``window[0]`` of its initial
    value (after the approach, which actuator limits may slow) and stops when
    it first falls to ``window[1]`` of it (before noise and rounding), or at
    the end.

    Parameters
    ----------
    times, error
        ``(T,)`` times and positive errors.
    window
        The two fractions of the initial error.

    Returns
    -------
    float
        NaN when fewer than ten samples lie in the window.

    >>> t = np.linspace(0, 10, 101)
    >>> round(decay_rate(t, 3 * np.exp(-0.5 * t)), 6)
    0.5
    """
    e0 = float(error[0])
    hi, lo = window[0] * e0, window[1] * e0
    start = np.flatnonzero(error <= hi)
    if start.size == 0:
        return math.nan
    a = int(start[0])
    stop = np.flatnonzero(error[a:] <= lo)
    b = a + int(stop[0]) if stop.size else error.size
    t, e = times[a:b], error[a:b]
    keep = e > 0
    if keep.sum() < 10:
        return math.nan
    slope = np.polyfit(t[keep], np.log(e[keep]), 1)[0]
    return float(-slope)


def saturated(executed: _Array, wanted: _Array) -> NDArray[np.bool_]:
    """Where a limit changed a command: ``|executed - wanted| > SATURATION_TOLERANCE |wanted|`` (elementwise).

    The absolute part (1e-9) keeps rounding of a command near zero from counting.

    >>> saturated(np.array([0.5, 0.3, 0.0]), np.array([0.5, 0.9, 1e-12])).tolist()
    [False, True, False]
    """
    executed, wanted = np.asarray(executed, dtype=np.float64), np.asarray(wanted, dtype=np.float64)
    return np.abs(executed - wanted) > SATURATION_TOLERANCE * np.abs(wanted) + 1e-9


@dataclass(frozen=True)
class DecayFit:
    """The decay rate fitted over the linear phase of a run, and the window it used.

    Attributes
    ----------
    rate
        ``-slope`` of the least-squares line through ``log e(t)`` (1/s); NaN
        when fewer than ten samples lie in the window.
    start_s, stop_s
        The window (s); NaN when there is none.
    start_error_m, stop_error_m
        The error at its ends (m).
    saturated_until_s
        The last time a limit changed a command (s; NaN: never).
    floor_m
        The error's level over the run's last :data:`FLOOR_TAIL` (m).
    samples
        How many error samples the fit used.
    """

    rate: float
    start_s: float
    stop_s: float
    start_error_m: float
    stop_error_m: float
    saturated_until_s: float
    floor_m: float
    samples: int

    def describe(self) -> dict[str, float | int]:
        """JSON-ready fields (the rate is the summary's own entry)."""
        return {"start_s": self.start_s, "stop_s": self.stop_s, "start_error_m": self.start_error_m,
                "stop_error_m": self.stop_error_m, "saturated_until_s": self.saturated_until_s,
                "floor_m": self.floor_m, "samples": self.samples}  # fmt: skip


def linear_decay(times: _Array, error: _Array, *, saturated_until: float = math.nan) -> DecayFit:
    """The decay rate of ``error`` over its linear phase (module doc), with the window it used.

    The window opens at the later of: the first sample after
    ``saturated_until`` and the first sample at or below ``FIT_WINDOW[0]`` of the
    initial error. It closes at the first later sample at or below the larger of
    ``FIT_WINDOW[1]`` of the initial error and :data:`FLOOR_MARGIN` times the
    floor (the median error over the last :data:`FLOOR_TAIL` of the run), or at
    the end.

    Parameters
    ----------
    times, error
        ``(T,)`` times (s) and errors (m).
    saturated_until
        The last time a robot's limits changed its command (NaN: never).

    Returns
    -------
    DecayFit
        The rate is NaN when fewer than ten samples lie in the window (a run
        that never leaves its limits, an error that does not fall).

    A ramp at the speed cap, then an exponential onto a floor of 0.1 mm (the window opens at 0.3 of the
    initial error, 0.72 s after the ramp):

    >>> t = np.linspace(0, 30, 3001)
    >>> e = np.where(t < 4, 2.0 - 0.3 * t, 0.8 * np.exp(-0.4 * (t - 4))) + 1e-4
    >>> fit = linear_decay(t, e, saturated_until=4.0)
    >>> round(fit.rate, 2), round(fit.start_s, 2), round(fit.floor_m, 4)
    (0.4, 4.72, 0.0001)
    """
    times, error = np.asarray(times, dtype=np.float64), np.asarray(error, dtype=np.float64)
    nan = DecayFit(math.nan, math.nan, math.nan, math.nan, math.nan, float(saturated_until), math.nan, 0)
    if error.size == 0:
        return nan
    tail = times >= times[0] + (1.0 - FLOOR_TAIL) * (times[-1] - times[0])
    floor = float(np.median(error[tail]))
    nan = DecayFit(**{**nan.__dict__, "floor_m": floor})
    e0 = float(error[0])
    opened = error <= FIT_WINDOW[0] * e0
    if math.isfinite(saturated_until):
        opened &= times > saturated_until
    start = np.flatnonzero(opened)
    if start.size == 0:
        return nan
    a = int(start[0])
    low = max(FIT_WINDOW[1] * e0, FLOOR_MARGIN * floor)
    stop = np.flatnonzero(error[a:] <= low)
    b = a + int(stop[0]) if stop.size else error.size
    t, e = times[a:b], error[a:b]
    keep = e > 0
    if keep.sum() < 10:
        return nan
    slope = np.polyfit(t[keep], np.log(e[keep]), 1)[0]
    return DecayFit(float(-slope), float(t[0]), float(t[-1]), float(e[0]), float(e[-1]), float(saturated_until),
                    floor, int(keep.sum()))  # fmt: skip


def window_needed(root: complex) -> float:
    """How long (s) a fit window must be for its slope to be the decay of the dominant root ``root``.

    One time constant ``1 / |Re s|`` and half an oscillation ``pi / |Im s|``,
    whichever is longer: over a shorter window the slope of ``log e(t)`` is
    that of the oscillation's phase and of the faster modes as much as the
    envelope's. Infinite for a root that does not decay.

    >>> round(window_needed(complex(-0.42, 0.55)), 2)
    5.71
    """
    if root.real >= 0.0:
        return math.inf
    return max(1.0 / -root.real, math.pi / abs(root.imag) if root.imag else 0.0)


def _last_saturated(times: _Array, flags: _Array) -> float:
    """The last time (s) any robot's command was saturated (``flags``: ``(T, ...)`` booleans); NaN: never."""
    hit = np.flatnonzero(np.asarray(flags).reshape(times.size, -1).any(axis=1))
    return float(times[hit[-1]]) if hit.size else math.nan


def _fleet_saturation(ticks: _Array, cap: float | None) -> NDArray[np.bool_]:
    """Per tick row (:data:`~delayform.fleet.agents.TICK_COLUMNS`): did a limit change the command?

    The turn rate and the acceleration against the controller's wish, and the
    speed set-point sent against the one the acceleration asked (``v + a h``
    within the speed cap ``cap``).
    """
    turn, want_turn, accel, want_accel = (ticks[:, c] for c in range(6, 10))
    flags = saturated(turn, want_turn) | saturated(accel, want_accel)
    if cap is not None:
        flags |= np.abs(ticks[:, 4]) >= cap * (1.0 - 1e-9)
    return flags


def _simulator_saturated_until(simulation: Trajectory) -> float:
    """The last time a limit changed one of the simulator's commands (NaN: never, or ideal robots)."""
    c = simulation.commands
    if c is None or not c.limited:
        return math.nan
    flags = saturated(c.turn_rate, c.ideal_turn_rate) | saturated(c.acceleration, c.ideal_acceleration)
    return _last_saturated(np.asarray(c.times), flags)


def _stats(values: _Array) -> dict[str, float]:
    if values.size == 0:
        return {"median": math.nan, "p99": math.nan, "max": math.nan}
    return {"median": float(np.median(values)), "p99": float(np.quantile(values, 0.99)), "max": float(values.max())}


def _applied(ticks_t: _Array, stamps: _Array, receipts: _Array, delays: _Array) -> tuple[_Array, _Array]:
    """Per tick: the delay applied (t minus the stamp used) and how long that message waited (t minus its receipt).

    The message used at t is the controller's: the newest one received and
    due (``stamp + d <= t``, ``d`` the message's own delay, infinite for a
    stream the network lost); before the first, the oldest received.
    """
    delay = np.full(ticks_t.size, math.nan)
    wait = np.full(ticks_t.size, math.nan)
    if stamps.size == 0:
        return delay, wait
    usable = np.maximum(receipts, stamps + delays)
    by_use = np.argsort(usable, kind="stable")
    newest = np.maximum.accumulate(stamps[by_use])
    newest_receipt = receipts[by_use][_running_argmax(stamps[by_use])]
    by_receipt = np.argsort(receipts, kind="stable")
    oldest = np.minimum.accumulate(stamps[by_receipt])
    oldest_receipt = receipts[by_receipt][_running_argmin(stamps[by_receipt])]
    pos = np.searchsorted(usable[by_use], ticks_t + 1e-9, side="right") - 1
    got = np.searchsorted(receipts[by_receipt], ticks_t, side="right") - 1
    due = pos >= 0
    early = ~due & (got >= 0)
    delay[due] = ticks_t[due] - newest[pos[due]]
    wait[due] = ticks_t[due] - newest_receipt[pos[due]]
    delay[early] = ticks_t[early] - oldest[got[early]]
    wait[early] = ticks_t[early] - oldest_receipt[got[early]]
    return delay, wait


def _running_argmax(values: _Array) -> NDArray[np.intp]:
    """Index of the largest value so far, at each position (the first of equal ones)."""
    best = np.maximum.accumulate(values)
    idx = np.where(values == best, np.arange(values.size), 0)
    return np.maximum.accumulate(idx) if values.size else idx


def _running_argmin(values: _Array) -> NDArray[np.intp]:
    """Index of the smallest value so far, at each position."""
    return _running_argmax(-values)


def silent_intervals(robot: int, faults: list[dict[str, Any]], heard: _Array, duration: float) -> list[dict[str, Any]]:
    """When robot ``robot`` was silent because a fault killed it, measured on the messages its neighbours could hear.

    For each kill: from the last state message of the killed process (taken
    by the recording before the restart, or before the end) to the first
    message of the process that replaced it (None: silent to the end).

    Parameters
    ----------
    robot
        The robot (from 1).
    faults
        The faults carried out (``robot``, ``action``, ``at_s``), in time order.
    heard
        When its state messages were taken (s, run clock).
    duration
        The run's length (s).

    Returns
    -------
    list of dict
        ``killed_at_s``, ``restarted_at_s`` (None), ``last_heard_s``, ``heard_again_s`` (None), ``silent_s``.
    """
    mine = [f for f in faults if f["robot"] == robot]
    heard = np.sort(np.asarray(heard, dtype=np.float64))
    out = []
    for n_, f in enumerate(mine):
        if f["action"] != "kill":
            continue
        restart = next((g["at_s"] for g in mine[n_ + 1:] if g["action"] == "restart"), None)
        before = heard[heard < (restart if restart is not None else math.inf)]
        last = float(before.max()) if before.size else math.nan
        after = heard[heard >= restart] if restart is not None else np.zeros(0)
        again = float(after.min()) if after.size else None
        out.append({"killed_at_s": float(f["at_s"]), "restarted_at_s": restart, "last_heard_s": last,
                    "heard_again_s": again, "silent_s": (again if again is not None else duration) - last})  # fmt: skip
    return out


@dataclass(frozen=True, eq=False)
class FleetRun:
    """A fleet run measured: the summary (module doc) and the formation error over time, fleet and simulator.

    Attributes
    ----------
    summary
        JSON-ready: ``links``, ``robots``, ``team`` (measured beside promised), ``run`` (what ran).
    times, error
        The fleet's formation error (m) at the world's odometry times (s).
    sim_times, sim_error
        The simulator's, for the same team at the same delays.
    """

    summary: dict[str, Any]
    times: _Array
    error: _Array
    sim_times: _Array
    sim_error: _Array
    files: tuple[str, ...] = field(default=())

    def plot(self, ax: Any = None) -> Any:
        """The formation error of the fleet and of the simulator, log scale, with the dominant root's slope."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7.0, 4.0))
        ax.semilogy(self.sim_times, self.sim_error, color="0.6", lw=2.0, label="simulator")
        ax.semilogy(self.times, self.error, color="C0", lw=1.0, label="fleet (processes)")
        team = self.summary["team"]
        rate = team["dominant_decay_rate"]
        if self.error.size and math.isfinite(rate):
            t = self.times
            ax.semilogy(t, self.error[0] * np.exp(-rate * t), "k--", lw=0.8, label=f"exp({-rate:+.3g} t): dominant root")
        ax.set_ylim(max(float(np.min(self.error, initial=1.0)) * 0.5, 1e-6), None)
        ax.set_xlabel("t (s)")
        ax.set_ylabel("formation error (m)")
        ax.legend(loc="upper right", fontsize=8)
        return ax


def measure(*, team: Team, tau1: float, tau2: float, plan: LinkPlan, desired: _Array, limits: RobotLimits | None, period: float,
            duration: float, network: Network | None, simulation: Trajectory, logs: dict[str, dict[str, Any]],
            recording: dict[str, int], pids: dict[str, int], mcap: Any, world: str, endpoint: str,
            faults: list[dict[str, Any]] | None = None, heard: dict[int, _Array] | None = None,
            ros_domain: int | None = None) -> FleetRun:  # fmt: skip
    """Measure a run from its logs (module doc); the comparison with the analysis included.

    Parameters
    ----------
    team, tau1, tau2, desired, limits, period, duration, network
        What was run.
    plan
        The network's draws: each link's design delays.
    simulation
        The simulator's run of the same team at the same delays, from the same initial state.
    logs
        ``"world"`` and ``"robot_<i>"`` -> the arrays each process saved.
    recording, pids, mcap, world, endpoint
        For the summary: messages recorded per key, the processes' PIDs, the MCAP path, the world model, the endpoint.
    faults
        The kills and restarts carried out: robot, action, planned and actual time (s).
    heard
        Robot (from 1) -> when its state messages were taken by the recording
        process (s): the silent intervals are measured on them (:func:`silent_intervals`).
    ros_domain
        The ROS domain the processes also published on as rmw_zenoh does, or None.
    """
    from delayform.analysis.ctcr import stability_map
    from delayform.analysis.roots.dominant import dominant_root

    n, h = team.n, period
    topology = team.topology
    w = logs["world"]
    times, states = np.asarray(w["times"]), np.asarray(w["states"])
    positions = states[:, :, :2]
    velocities = states[:, :, 3:4] * np.stack([np.cos(states[:, :, 2]), np.sin(states[:, :, 2])], axis=-1)
    error = formation_error(positions, desired) if times.size else np.zeros(0)
    scale = float(np.abs(positions).max(initial=1.0))
    radius = 0.0 if limits is None else limits.radius
    approach = closest_approach(times, positions, velocities, 2 * radius) if times.size > 1 else None

    # --- robots: ticks
    robots = []
    tick_times: dict[int, _Array] = {}
    saturated_until = -math.inf
    for i in range(1, n + 1):
        log = logs[f"robot_{i}"]
        ticks = np.asarray(log["ticks"]).reshape(-1, len(TICK_COLUMNS))
        hit = _fleet_saturation(ticks, None if limits is None else limits.speed_cap)
        if hit.any():
            saturated_until = max(saturated_until, float(ticks[hit, 0].max()))
        late = ticks[:, 1]
        tick_times[i] = ticks[:, 0] + late
        expected = math.ceil(duration / h - 1e-9)
        starts = np.asarray(log.get("starts", np.zeros(1)))
        robots.append({
            "robot": i, "ticks_expected": expected, "ticks_run": int(ticks.shape[0]),
            "last_tick_s": float(ticks[-1, 0]) if ticks.size else math.nan,
            "processes": int(starts.size),
            "rejoined_s": [float(v) for v in starts[1:]],
            # a restarted process that never ticked: the neighbours it never heard from
            "rejoin_waits_for": [int(k) for k in np.asarray(log.get("waiting", np.zeros(0))).reshape(-1)],
            "silent": silent_intervals(i, faults or [], (heard or {}).get(i, np.zeros(0)), duration),
            "ticks_missed": int(log["missed"]), "ticks_late": int(np.sum(late > LATE_FRACTION * h)),
            "lateness_s": _stats(late), "compute_s": _stats(ticks[:, 3]), "lag_s": _stats(ticks[:, 2]),
            "error": str(log["error"]) or None,
        })  # fmt: skip

    # --- links
    links = []
    design = {(int(i) + 1, int(k) + 1): (float(a), float(b))
              for i, k, a, b in zip(plan.receivers, plan.informers, plan.tau1, plan.tau2)}  # fmt: skip
    C = topology.C_sparse.tocsr()
    loss_rate = 0.0 if network is None or network.loss is None else float(
        network.loss.link_loss_rate(topology.adjacency) if hasattr(network.loss, "link_loss_rate") else network.loss.loss_rate)  # fmt: skip
    cutoff = duration - _SETTLE  # a message sent in the run's last instant may meet a receiver that has stopped
    for i in range(1, n + 1):
        rec = np.asarray(logs[f"robot_{i}"]["received"]).reshape(-1, 6)
        for j in C.indices[C.indptr[i - 1]:C.indptr[i]]:
            k = int(j) + 1
            if k == i:
                continue
            mine = rec[(rec[:, 0] == k) & (rec[:, 1] >= 0.0) & (rec[:, 1] <= cutoff)]
            delivered = mine[mine[:, 3] == 0.0]
            every = rec[rec[:, 0] == k]  # the ones before t = 0 too: the initial history
            d1, wait1 = _applied(tick_times[i], every[:, 1], every[:, 2], every[:, 4])
            d2, _ = _applied(tick_times[i], every[:, 1], every[:, 2], every[:, 5])
            sent = int(np.sum(np.asarray(logs[f"robot_{k}"]["sent"]) <= cutoff))
            want1, want2 = design[(i, k)]
            applied1, applied2 = _stats(d1[np.isfinite(d1)]), _stats(d2[np.isfinite(d2)])
            links.append({
                "receiver": i, "informer": k, "design_tau1_s": want1, "design_tau2_s": want2,
                "measured_tau1_s": applied1["median"], "measured_tau2_s": applied2["median"],
                "within_one_period": bool(abs(applied1["median"] - want1) <= h and abs(applied2["median"] - want2) <= h),
                "receiver_ticks_missed": robots[i - 1]["ticks_missed"], "receiver_ticks_late": robots[i - 1]["ticks_late"],
                "sent": sent, "received": int(mine.shape[0]),
                "lost_in_transport": max(sent - int(mine.shape[0]), 0), "dropped_by_network": int(np.sum(mine[:, 3] != 0.0)),
                "latency_s": _stats(mine[:, 2] - mine[:, 1]),
                "applied_tau1_s": applied1, "applied_tau2_s": applied2,
                "dropped_velocities_by_network": int(np.sum(np.isinf(mine[:, 5]))),
                "playout_s": _stats(wait1[np.isfinite(wait1)]),
                "delivered": int(delivered.shape[0]),
            })  # fmt: skip

    # --- the promise
    dr = dominant_root(topology, team.P, team.D, tau1, tau2)
    root = dr.formation_root if getattr(dr, "formation_root", None) is not None else dr.root
    smap = stability_map(topology, team.P, team.D, max(8.0, 1.25 * tau1), max(8.0, 1.25 * tau2))
    chart_stable = bool(np.asarray(smap.is_stable(np.array([tau1]), np.array([tau2])))[0])
    sim_error = simulation.formation_error
    fit = linear_decay(times, error, saturated_until=saturated_until if saturated_until > -math.inf else math.nan)
    measured = fit.rate
    sim_fit = linear_decay(simulation.times, sim_error, saturated_until=_simulator_saturated_until(simulation))
    sim_rate = sim_fit.rate
    fleet_settling = settling_time(times, error, scale) if times.size else math.inf
    sent = sum(link["sent"] for link in links)
    dropped = sum(link["dropped_by_network"] for link in links)
    per_link = bool(network is not None and network.delays is not None and not network.delays.is_uniform)
    team_summary = {
        "per_link_delays": per_link,
        "simulator_decay_ratio": measured / sim_rate if math.isfinite(measured) and sim_rate > 0 else math.nan,
        "chart_verdict": "stable" if chart_stable else "unstable",
        "dominant_root": [float(np.real(root)), float(np.imag(root))],
        "dominant_decay_rate": float(-np.real(root)),
        "measured_decay_rate": measured,
        "simulator_decay_rate": sim_rate,
        "decay_window": fit.describe(),
        "simulator_decay_window": sim_fit.describe(),
        "decay_ratio": measured / float(-np.real(root)) if np.real(root) < 0 and math.isfinite(measured) else math.nan,
        "decay_window_needed_s": window_needed(complex(root)),
        "initial_error_m": float(error[0]) if error.size else math.nan,
        "final_error_m": float(error[-1]) if error.size else math.nan,
        "error_reduction": float(error[0] / error[-1]) if error.size and error[-1] > 0 else math.inf,
        "settling_time_s": fleet_settling,
        "simulator_settling_time_s": float(simulation.settling_time),
        "closest_approach_m": approach.min_distance if approach is not None else math.nan,
        "closest_at_s": approach.at if approach is not None else math.nan,
        "simulator_closest_approach_m": float(simulation.min_distance),
        "contacts": 0 if approach is None else len(approach.contacts),
        "ticks_missed": sum(r["ticks_missed"] for r in robots),
        "ticks_late": sum(r["ticks_late"] for r in robots),
        "messages_dropped_by_network": dropped,
        "network_drop_rate": dropped / max(sum(link["received"] for link in links), 1),
        "network_loss_rate": loss_rate,
        "messages_lost_in_transport": sum(link["lost_in_transport"] for link in links),
        "state_messages_sent": sent,
        "silent_robots": [r["robot"] for r in robots if r["silent"]],
        "stopped_by_command_timeout": [[int(a), float(b)] for a, b in np.asarray(w.get("stopped", np.zeros((0, 2)))).reshape(-1, 2)],
    }  # fmt: skip
    run = {
        "robots": n, "P": team.P, "D": team.D, "tau1": tau1, "tau2": tau2, "period": h, "duration": duration,
        "world": world, "world_step": 0.001, "endpoint": endpoint, "ros_domain": ros_domain,
        "network": "ideal" if network is None else network.describe(topology.adjacency),
        "limits": None if limits is None else limits.describe(), "pids": pids, "recording": str(mcap),
        "messages_recorded": recording,
        "world_lateness_s": _stats(np.asarray(w["lateness"])), "commands_applied": int(w["applied"]),
        "faults": list(faults or []),
    }  # fmt: skip
    summary = {"run": run, "team": team_summary, "robots": robots, "links": links}
    return FleetRun(summary=summary, times=times, error=error, sim_times=simulation.times, sim_error=sim_error)
