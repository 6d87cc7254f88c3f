"""Before the real run: does the design fit the robot? One page of verdicts, each with its number.

:func:`robot_check` takes a scenario (topology, gains, delays, formation,
initial state, simulation settings) and a robot profile
(:mod:`delayform.deploy.profiles`) and answers five questions:

``limits``
    The scenario simulated with the profile's limits (the saturated
    unicycle) settles, and how fast next to ideal robots; how often and
    until when a limit was active (the controller's demand of the paper's
    eq. 19 beyond a limit, or the speed limit holding a robot back).
    Fits when the saturated run settles.
``radius``
    The desired places are more than a body diameter apart, and the
    closest approach of two robots during the saturated run too (a closer
    approach is a contact: the safety filter or a new design must handle
    it). Fits when both hold.
``arena``
    Where the profile has an arena: the shape with its bodies fits, the
    initial positions and the whole saturated run stay inside (a body
    radius from the walls). Not applicable otherwise.
``control rate``
    A robot that ticks every h seconds and hears its neighbours once a tick
    applies each delay somewhere in ``[tau, tau + h)`` (the playout buffer
    of :mod:`delayform.deploy.controller` takes the newest message sent at
    or before ``t - tau``). Fits when the exact CTCR map proves the whole
    box ``[tau1, tau1 + h] x [tau2, tau2 + h]`` stable
    (:func:`delayform.design.gains.box_is_stable`; it says stable only
    when no crossing curve meets the box).
``jitter``
    The largest extra delay j such that every constant pair in
    ``[tau1, tau1 + j] x [tau2, tau2 + j]`` is proven stable, by bisection
    on the same certificate. This covers delays that are constant but
    unknown within the box. Delays that vary in time are covered by the
    small-gain jitter margin (:func:`delayform.analysis.network.jitter_margin`,
    Kao & Lincoln's bound: per link, arbitrarily fast): the margin about
    (tau1, tau2), and whether the tick's own variation (a delay in
    ``tau + [0, h)``, i.e. ``tau + h/2`` varying by ``h/2``) is certified.
    Informational: no verdict.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from delayform._validation import validated
from delayform.deploy.fit import formation_fit
from delayform.deploy.profiles import RobotProfile, robot_profile
from delayform.errors import RobotProfileError
from delayform.resources import sized_by
from delayform.scenario import Scenario
from delayform.simulation.runs.trajectory import Trajectory  # loaded by the scenario already

__all__ = ["Verdict", "RobotCheck", "robot_check"]

#: bisection steps of the jitter margin (resolution: window / 2^steps)
_JITTER_STEPS = 18


@dataclass(frozen=True)
class Verdict:
    """One question of the check, its answer and the numbers behind it.

    Attributes
    ----------
    key
        ``"limits"``, ``"radius"``, ``"arena"``, ``"control rate"`` or ``"jitter"``.
    fits
        True, False, or None where the question does not apply or is only informational.
    text
        One sentence with the numbers.
    numbers
        The numbers, by name (SI units).
    """

    key: str
    fits: bool | None
    text: str
    numbers: dict[str, float] = field(default_factory=dict)

    @property
    def word(self) -> str:
        """``"fits"``, ``"does not fit"`` or ``"n/a"``."""
        return {True: "fits", False: "does not fit", None: "n/a"}[self.fits]


@validated(RobotProfileError)
@dataclass(frozen=True, eq=False)
class RobotCheck:
    """The verdicts of :func:`robot_check`, the page that prints them and the run they come from.

    Attributes
    ----------
    scenario
        What was checked.
    profile
        The robot.
    verdicts
        One :class:`Verdict` per question, in the order of the module doc.
    trajectory
        The saturated run (:class:`delayform.simulation.Trajectory`).
    """

    scenario: Scenario
    profile: RobotProfile
    verdicts: tuple[Verdict, ...]
    trajectory: Trajectory

    @property
    def fits(self) -> bool:
        """Whether no verdict says "does not fit"."""
        return all(v.fits is not False for v in self.verdicts)

    def page(self) -> str:
        """The one-page text: the design, the robot, one line per verdict, the conclusion."""
        sc, p = self.scenario, self.profile
        lines = [
            f"Check of {sc.name} on {p.title}",
            f"  design: {sc.topology.n} robots, P = {sc.P:g}, D = {sc.D:g}, (tau1, tau2) = ({sc.tau1:g}, {sc.tau2:g}) s, "
            f"{sc.formation.describe()}"
            + ("" if sc.network is None else f", network: {sc.network.describe(sc.topology.adjacency)}"),
            f"  robot:  {p.limits.describe()}, radius {p.limits.radius:g} m"
            + (f", arena {p.arena.describe()}" if p.arena is not None else ""),
        ]  # fmt: skip
        width = max(len(v.key) for v in self.verdicts)
        for v in self.verdicts:
            lines.append(f"  {v.key:<{width}}  {v.word:<12}  {v.text}")
        lines.append("The design fits the robot." if self.fits else
                     "The design does not fit the robot: see the lines marked 'does not fit'.")  # fmt: skip
        lines.append("Sources of the robot's numbers: docs/deploy.md (delayform.deploy.PROFILES).")
        return "\n".join(lines)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the profile, whether it fits, and every verdict with its numbers."""
        return {
            "scenario": self.scenario.name, "robot": self.profile.name, "fits": self.fits,
            "network": "ideal" if self.scenario.network is None else self.scenario.network.describe(self.scenario.topology.adjacency),
            "verdicts": {v.key: {"fits": v.fits, "text": v.text, **v.numbers} for v in self.verdicts},
        }  # fmt: skip

    def plot(self, ax: Any = None) -> Any:
        """The saturated run's paths, final bodies to scale and the arena; returns the axes.

        Parameters
        ----------
        ax
            Axes to draw on, or None for a new figure.
        """
        import matplotlib.pyplot as plt
        from matplotlib.patches import Circle, Rectangle

        if ax is None:
            _, ax = plt.subplots(figsize=(7.0, 5.0))
        traj = self.trajectory
        for i in range(traj.positions.shape[1]):
            ax.plot(traj.positions[:, i, 0], traj.positions[:, i, 1], lw=0.8, label=f"robot {i + 1}")
            ax.add_patch(Circle(tuple(traj.positions[-1, i]), self.profile.limits.radius, fill=False))
        arena = self.profile.arena
        if arena is not None:
            ax.add_patch(Rectangle((arena.x_min, arena.y_min), arena.width, arena.height, fill=False, ls="--",
                                   color="k", label="arena"))  # fmt: skip
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"{self.scenario.name} on {self.profile.title}: {'fits' if self.fits else 'does not fit'}")
        return ax


@validated(RobotProfileError)
def robot_check(scenario: Scenario, robot: str | RobotProfile) -> RobotCheck:
    """Whether the scenario's design fits a real robot (module doc: the five questions).

    Parameters
    ----------
    scenario
        The design and its run settings (simulation duration and step, initial
        state, ``[robot] safety``); both runs go over its ``[network]``.
    robot
        A profile or its name (:data:`delayform.deploy.PROFILES`).

    Returns
    -------
    RobotCheck

    Raises
    ------
    RobotProfileError
        For an unknown profile.
    SimulationInputError, ScenarioError
        For a scenario that cannot be simulated on that robot (e.g. a
        formation that does not fit the team), or whose per-link delays
        differ between links (:meth:`~delayform.scenario.Scenario.at_one_delay_pair`).
    """
    from delayform.simulation import simulate

    profile = robot_profile(robot)
    # the runs go over the scenario's [network]; the certificates need one delay pair on every link
    scenario = scenario.at_one_delay_pair("check (its CTCR box and jitter margin)",
                                          "delayform links / jitter / box, or simulate")
    desired = scenario.desired_positions()
    sim = scenario.simulation
    common = dict(initial_positions=scenario.initial_positions(), initial_headings=scenario.initial_headings(),
                  initial_speed=scenario.initial.speed, seed=scenario.initial.seed, duration=sim.duration, dt=sim.dt,
                  network=scenario.network)  # fmt: skip
    args = (scenario.topology, scenario.P, scenario.D, scenario.tau1, scenario.tau2, desired)
    # the delay verdicts first: a chart too large for the machine is refused before the runs, and named
    # by the delays that set its window (the check has no window of its own)
    with sized_by("the delays (delays.tau1, delays.tau2, --tau1, --tau2)"):
        delay_verdicts = _delay_verdicts(scenario, profile)
    # the robot as the scenario configures it: its safety filter too (a filtered run keeps bodies apart),
    # over the scenario's [network] (jitter, loss, ...), the run `delayform simulate` makes
    limited = simulate(*args, limits=profile.limits, safety=scenario.safety, **common)
    ideal = simulate(*args, safety=scenario.safety, **common)
    verdicts = (
        _limits_verdict(profile, limited, ideal),
        _radius_verdict(profile, desired, limited),
        _arena_verdict(profile, desired, limited),
        *delay_verdicts,
    )
    return RobotCheck(scenario=replace(scenario, robot=profile.limits, robot_profile=profile.name),
                      profile=profile, verdicts=verdicts, trajectory=limited)  # fmt: skip


def _limits_verdict(profile: RobotProfile, limited: Any, ideal: Any) -> Verdict:
    cmd = limited.commands
    # where the controller's demand (paper, eq. 19 at the saturated robot's state) exceeded a limit
    active = np.zeros(cmd.speed.shape, dtype=bool)
    for values, limit, _ in cmd.needed().values():
        active |= values > limit * (1 + 1e-9)
    if cmd.speed_held is not None:
        active |= cmd.speed_held
    fraction = float(active.mean())
    when = limited.times[active.any(axis=1)]
    last = float(when.max()) if when.size else 0.0
    numbers = {"settling_time": float(limited.settling_time), "ideal_settling_time": float(ideal.settling_time),
               "limited_fraction": fraction, "last_limited_time": last}  # fmt: skip
    settled = limited.status == "settled"
    active_text = (f"a limit was active in {100 * fraction:.3g} % of robot-samples, the last time at t = {last:.3g} s"
                   if when.size else "no limit was ever active")  # fmt: skip
    if settled:
        text = f"settles in {limited.settling_time:.3g} s with the limits (ideal robots: {ideal.settling_time:.3g} s); {active_text}"
    else:
        text = f"does not settle within {limited.times[-1]:.3g} s with the limits ({limited.status}); {active_text}"
    return Verdict("limits", settled, text, numbers)


def _radius_verdict(profile: RobotProfile, desired: np.ndarray, limited: Any) -> Verdict:
    fit = formation_fit(desired, profile)
    approach = float(limited.min_distance)
    ok = fit.bodies_fit and approach > fit.body_diameter
    text = (f"desired places {fit.closest_places:.3g} m apart and closest approach in the run {approach:.3g} m, "
            f"against a body diameter of {fit.body_diameter:.3g} m")  # fmt: skip
    if approach <= fit.body_diameter:
        text += " (bodies touch during the transient)"
    return Verdict("radius", ok, text, {"closest_places": fit.closest_places, "closest_approach": approach,
                                        "body_diameter": fit.body_diameter})  # fmt: skip


def _arena_verdict(profile: RobotProfile, desired: np.ndarray, limited: Any) -> Verdict:
    arena = profile.arena
    if arena is None:
        return Verdict("arena", None, "the robot has no arena")
    fit = formation_fit(desired, profile)
    r = profile.limits.radius
    pos = limited.positions
    lo, hi = pos.min(axis=(0, 1)), pos.max(axis=(0, 1))
    start_lo, start_hi = pos[0].min(axis=0), pos[0].max(axis=0)

    def inside(a: np.ndarray, b: np.ndarray) -> bool:
        return bool(a[0] - r >= arena.x_min and a[1] - r >= arena.y_min and b[0] + r <= arena.x_max and b[1] + r <= arena.y_max)

    shape_ok, start_ok, run_ok = bool(fit.arena_fits), inside(start_lo, start_hi), inside(lo, hi)
    text = (f"shape {fit.extent[0] + 2 * r:.3g} m x {fit.extent[1] + 2 * r:.3g} m with bodies "
            f"({'fits' if shape_ok else 'too large'}); start inside: {'yes' if start_ok else 'no'}; "
            f"the run spans x in [{lo[0]:.3g}, {hi[0]:.3g}], y in [{lo[1]:.3g}, {hi[1]:.3g}] "
            f"(inside: {'yes' if run_ok else 'no'}) of {arena.describe()}")  # fmt: skip
    return Verdict("arena", shape_ok and start_ok and run_ok, text,
                   {"x_min": float(lo[0]), "x_max": float(hi[0]), "y_min": float(lo[1]), "y_max": float(hi[1])})  # fmt: skip


def _delay_verdicts(scenario: Scenario, profile: RobotProfile) -> tuple[Verdict, Verdict]:
    from delayform.analysis.ctcr import stability_map
    from delayform.analysis.network import jitter_margin
    from delayform.design.gains import box_is_stable

    tau1, tau2 = scenario.tau1, scenario.tau2
    h = profile.control_period
    assumed = h is None
    if h is None:  # no documented period: the simulation's step stands for it
        h = scenario.simulation.dt
    reach = max(1.0, tau1, tau2, 4 * h)
    smap = stability_map(scenario.topology, scenario.P, scenario.D, tau1 + reach, tau2 + reach)

    def stable_box(j: float) -> bool:
        return box_is_stable(smap, (tau1, tau1 + j), (tau2, tau2 + j))

    period_text = f"{h:g} s" + (" (assumed: the simulation step; the maker states none)" if assumed else "")
    rate_ok = stable_box(h)
    rate = Verdict("control rate", rate_ok,
                   f"ticking every {period_text} the robot applies tau1 in [{tau1:g}, {tau1 + h:.3g}) s and tau2 in "
                   f"[{tau2:g}, {tau2 + h:.3g}) s: that box is "
                   f"{'proven stable' if rate_ok else 'not proven stable'} (exact CTCR map); "
                   f"the simulation steps {scenario.simulation.dt:g} s",
                   {"control_period": h, "tau1_periods": tau1 / h, "tau2_periods": tau2 / h})  # fmt: skip
    if not stable_box(0.0):
        jitter = Verdict("jitter", None, f"none: the design is not proven stable at ({tau1:g}, {tau2:g}) s itself",
                         {"jitter_margin": 0.0})  # fmt: skip
        return rate, jitter
    lo, hi = 0.0, reach
    if stable_box(hi):
        lo = hi
    else:
        for _ in range(_JITTER_STEPS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if stable_box(mid) else (lo, mid)
    more = " or more" if lo == reach else ""
    # delays that vary in time: the small-gain jitter margin (Kao & Lincoln), per link and as fast as they
    # like; a robot ticking every h applies tau + [0, h), i.e. tau + h/2 with a variation of h/2
    varying = jitter_margin(scenario.topology, scenario.P, scenario.D, tau1, tau2).delta
    tick = jitter_margin(scenario.topology, scenario.P, scenario.D, tau1 + h / 2, tau2 + h / 2).delta
    covered = tick >= h / 2
    jitter = Verdict("jitter", None,
                     f"constant delays up to {lo:.3g} s{more} above (tau1, tau2) are proven stable "
                     f"({lo / h:.3g} control periods, exact CTCR map); delays varying in time, per link and "
                     f"arbitrarily fast, within +-{varying:.3g} s of (tau1, tau2) are certified (small gain, "
                     f"jitter_margin); the tick's own variation (h/2 = {h / 2:.3g} s about tau + h/2, margin "
                     f"{tick:.3g} s there) is {'certified' if covered else 'not certified'}",
                     {"jitter_margin": lo, "jitter_margin_periods": lo / h if math.isfinite(lo) else math.inf,
                      "time_varying_jitter_margin": varying, "tick_jitter_margin": tick,
                      "tick_variation_certified": covered})  # fmt: skip
    return rate, jitter
