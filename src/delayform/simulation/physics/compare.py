"""What the dynamics cost: the physics model beside the kinematic one, and the analysis with the robot's lag.

:func:`compare_with_kinematic` runs the same team twice from the same start,
at the same delays, with the same limits: robots with mass
(``model="physics"``) and the saturated kinematic unicycle
(``model="unicycle"``); it reports how far apart the robots are over the
run and the two settling times. :func:`actuation_verdict` asks the exact
analysis the question again with the robot's own lag (a
:class:`~delayform.simulation.physics.identify.ServoIdentification`'s
equivalent actuation delay): which delay pairs of the chart change their
verdict, and what the dominant root becomes at a design point.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_gains, validated
from delayform.errors import SimulationInputError
from delayform.model import Delays, Network, Robot, Start, Team
from delayform.simulation.runs.compat import SIMULATE_KEYWORDS, accepts_loose_calls
from delayform.simulation.runs.trajectory import Trajectory
from delayform.topology import Topology

__all__ = ["KinematicComparison", "compare_with_kinematic", "kinematic_twin", "ActuationVerdict", "actuation_verdict"]

_Array = NDArray[np.float64]


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class KinematicComparison:
    """Robots with mass against the kinematic model, same start, delays and limits.

    Attributes
    ----------
    physics, kinematic
        The two runs.
    times
        ``(T,)`` the physics run's sample times (s).
    deviation
        ``(T,)`` the largest distance (m) between a robot of one run and the
        same robot of the other (the kinematic run interpolated linearly).
    """

    physics: Trajectory
    kinematic: Trajectory
    times: _Array
    deviation: _Array

    @classmethod
    def of(cls, physics: Trajectory, kinematic: Trajectory) -> KinematicComparison:
        """The comparison of two runs from the same start (the kinematic run interpolated at the physics samples).

        Parameters
        ----------
        physics, kinematic
            A ``model="physics"`` run and the kinematic run of :func:`kinematic_twin`.
        """
        times, kt = physics.times, kinematic.times
        idx = np.clip(np.searchsorted(kt, times, side="right") - 1, 0, max(kt.size - 2, 0))
        nxt = np.minimum(idx + 1, kt.size - 1)
        span = np.where(kt[nxt] > kt[idx], kt[nxt] - kt[idx], 1.0)
        w = np.clip((times - kt[idx]) / span, 0.0, 1.0)[:, None, None]
        at = (1.0 - w) * kinematic.positions[idx] + w * kinematic.positions[nxt]
        inside = times <= kt[-1] + 1e-12
        deviation = np.hypot(*(physics.positions[inside] - at[inside]).transpose(2, 0, 1)).max(axis=1)
        return cls(physics=physics, kinematic=kinematic, times=times[inside], deviation=deviation)

    @property
    def max_deviation(self) -> float:
        """The largest deviation over the run (m)."""
        return float(self.deviation.max())

    @property
    def final_deviation(self) -> float:
        """The deviation at the end (m)."""
        return float(self.deviation[-1])

    @property
    def settling_times(self) -> tuple[float, float]:
        """(physics, kinematic) 2 % settling times (s; inf where a run did not settle)."""
        return float(self.physics.settling_time), float(self.kinematic.settling_time)

    def describe(self) -> str:
        """One sentence for reports."""
        tp, tk = self.settling_times
        return (f"robots with mass stay within {100 * self.max_deviation:.3g} cm of the kinematic robots "
                f"({100 * self.final_deviation:.3g} cm at the end); they settle in {tp:.4g} s against {tk:.4g} s")  # fmt: skip

    def plot(self, ax: Any = None) -> Any:
        """Deviation (top) and both formation errors (bottom) over time; returns the two axes.

        Parameters
        ----------
        ax
            Two matplotlib axes, or None for a new figure.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        top, bottom = ax
        top.plot(self.times, 100 * self.deviation)
        top.set_ylabel("largest deviation (cm)")
        bottom.semilogy(self.physics.times, self.physics.formation_error, label="physics (mass, servos, contacts)")
        bottom.semilogy(self.kinematic.times, self.kinematic.formation_error, "--", label="kinematic (same limits)")
        bottom.set_xlabel("t (s)")
        bottom.set_ylabel("formation error (m)")
        bottom.legend()
        return ax


#: the old keywords the loose form of :func:`compare_with_kinematic` takes: the robot's and the start's
_LOOSE_KEYWORDS = MappingProxyType({k: v for k, v in SIMULATE_KEYWORDS.items() if not v.startswith("RunOptions.")})


@accepts_loose_calls(_LOOSE_KEYWORDS, default_model="physics")
@validated(SimulationInputError)
def compare_with_kinematic(
    team: Team,
    delays: Delays,
    formation: ArrayLike | str,
    *,
    robot: Robot | None = None,
    network: Network | None = None,
    start: Start | None = None,
    duration: float,
    dt: float,
) -> KinematicComparison:
    """Run the team as robots with mass and as kinematic robots with the same limits, and compare.

    Parameters
    ----------
    team, delays, formation
        As for :func:`~delayform.simulation.simulate` (paper, eqs. 1 and 13).
    robot
        A ``Robot(model="physics", ...)``: limits and chassis; None: the
        Create's. The kinematic run uses the same limits and body radius.
    network
        The network both runs hear through; None: the paper's.
    start
        The common start (:class:`~delayform.model.Start`; random positions
        and headings are drawn once from its seed).
    duration, dt
        Length of both runs; the kinematic run's step and the physics run's sampling (s).

    Returns
    -------
    KinematicComparison

    Raises
    ------
    SimulationInputError
        For a robot that is not a physics robot, and the errors of ``simulate``.

    Notes
    -----
    The loose form ``compare_with_kinematic(topology, P, D, tau1, tau2,
    formation, robot=..., initial_positions=..., seed=..., duration=...,
    dt=...)`` is taken as :func:`~delayform.simulation.simulate` takes it.
    """
    from delayform.simulation.runs.runner import simulate

    robot = Robot(model="physics") if robot is None else robot
    if not isinstance(robot, Robot) or robot.model != "physics":
        raise SimulationInputError("robot must be a Robot(model='physics', ...): its limits drive both runs")
    phys = simulate(team, delays, formation, robot=robot, network=network, start=start, duration=duration, dt=dt)
    kin = simulate(team, delays, formation, robot=kinematic_twin(robot), network=network, start=start,
                   duration=duration, dt=dt)  # fmt: skip
    return KinematicComparison.of(phys, kin)


def kinematic_twin(robot: Robot) -> Robot:
    """The kinematic robot with a physics robot's limits and body: ``model="unicycle"``, same limits and radius.

    Parameters
    ----------
    robot
        A ``Robot(model="physics", ...)``.
    """
    return replace(robot, model="unicycle", chassis=None, radius=robot.body_radius)


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class ActuationVerdict:
    """Where the robot's lag changes the exact chart's verdict.

    Attributes
    ----------
    actuation_delay
        tau_a (s) the second chart uses.
    tau1, tau2
        ``(m,)`` and ``(k,)`` the grid of delay pairs (s).
    stable_kinematic, stable_actuated
        ``(k, m)`` verdicts of the exact charts without and with tau_a
        (rows: tau2).
    """

    actuation_delay: float
    tau1: _Array
    tau2: _Array
    stable_kinematic: NDArray[np.bool_]
    stable_actuated: NDArray[np.bool_]

    @property
    def lost(self) -> NDArray[np.bool_]:
        """``(k, m)``: stable for kinematic robots, unstable with the lag."""
        return self.stable_kinematic & ~self.stable_actuated

    @property
    def gained(self) -> NDArray[np.bool_]:
        """``(k, m)``: unstable for kinematic robots, stable with the lag."""
        return ~self.stable_kinematic & self.stable_actuated

    def describe(self) -> str:
        """Which delays change their verdict, in one sentence."""
        lost, gained = self.lost, self.gained
        total = lost.size
        if not lost.any() and not gained.any():
            return (f"an actuation delay of {1e3 * self.actuation_delay:.1f} ms changes no verdict on the "
                    f"{self.tau1.size} x {self.tau2.size} grid")  # fmt: skip
        parts = []
        if lost.any():
            t1 = self.tau1[np.nonzero(lost)[1]]
            t2 = self.tau2[np.nonzero(lost)[0]]
            parts.append(f"{100 * lost.sum() / total:.2g} % of the grid loses stability (tau1 in "
                         f"[{t1.min():.3g}, {t1.max():.3g}] s, tau2 in [{t2.min():.3g}, {t2.max():.3g}] s)")  # fmt: skip
        if gained.any():
            parts.append(f"{100 * gained.sum() / total:.2g} % gains it")
        return f"with an actuation delay of {1e3 * self.actuation_delay:.1f} ms " + "; ".join(parts)

    def plot(self, ax: Any = None) -> Any:
        """The two charts' verdicts and the pairs that change; returns the axes.

        Parameters
        ----------
        ax
            Matplotlib axes, or None for a new figure.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(5, 4.5))
        code = np.where(self.stable_kinematic & self.stable_actuated, 2, 0) + self.lost * 1 + self.gained * 3
        ax.pcolormesh(self.tau1, self.tau2, code, shading="nearest", cmap="RdYlGn", vmin=0, vmax=3)
        ax.set_xlabel("tau1 (s)")
        ax.set_ylabel("tau2 (s)")
        ax.set_title(f"verdicts with tau_a = {1e3 * self.actuation_delay:.1f} ms (yellow: lost)")
        return ax


@validated(SimulationInputError)
def actuation_verdict(
    topology: Topology, P: float, D: float, tau1_max: float, tau2_max: float, actuation_delay: float,
    *, resolution: int = 121,
) -> ActuationVerdict:  # fmt: skip
    """The exact charts without and with an actuation delay, compared on a grid of delay pairs.

    Parameters
    ----------
    topology, P, D
        Team and gains of the paper's eq. 1.
    tau1_max, tau2_max
        The chart's window (s), positive.
    actuation_delay
        tau_a > 0 (s), e.g. :attr:`ServoIdentification.effective_delay`.
    resolution
        Grid points per axis (>= 2).

    Returns
    -------
    ActuationVerdict
    """
    from delayform.analysis.ctcr.stability_map import stability_map

    P, D = check_gains(P, D)
    ta = check_delay("actuation_delay", actuation_delay)
    if ta <= 0.0:
        raise SimulationInputError("actuation_delay must be positive: at 0 both charts are the same")
    if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 2:
        raise SimulationInputError(f"resolution must be an integer >= 2, got {resolution!r}")
    t1 = np.linspace(0.0, check_delay("tau1_max", tau1_max), resolution)
    t2 = np.linspace(0.0, check_delay("tau2_max", tau2_max), resolution)
    X, Y = np.meshgrid(t1, t2)
    plain = stability_map(topology, P, D, tau1_max, tau2_max)
    late = stability_map(topology, P, D, tau1_max, tau2_max, actuation_delay=ta)
    return ActuationVerdict(actuation_delay=ta, tau1=t1, tau2=t2,
                            stable_kinematic=np.asarray(plain.is_stable(X, Y)),
                            stable_actuated=np.asarray(late.is_stable(X, Y)))  # fmt: skip
