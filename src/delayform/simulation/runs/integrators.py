"""The integrator table: one small object per agent model, chosen by :attr:`Robot.model <delayform.model.Robot.model>`.

As scipy's ``solve_ivp`` picks its method from ``METHODS``,
:func:`~delayform.simulation.simulate` picks the entry of :data:`INTEGRATORS`
named by the robot's model and asks it, through one protocol
(:class:`AgentIntegrator`), to refuse what it cannot model, to integrate the
run (:class:`RunPlan`) and to turn the saved samples into the robots'
headings, speeds, inputs and commands (:class:`Motion`).

Entries
-------
``double_integrator``
    ``x'' = u`` (paper, Section "Consensus Protocol"): the blocked linear path
    where it fits (:func:`~delayform.simulation.delayed.integrator.integrate_linear`),
    the filtered linear path for small ideal teams with a safety filter
    (:func:`~delayform.simulation.delayed.filtered.integrate_filtered`), else the
    generic RK4 loop, over the network when there is one.
``unicycle``
    Without limits the ideal robot of Section "Feedback Linearization": its
    position is the double integrator's, integrated as above, and its
    heading, speed and commands are rebuilt
    (:func:`~delayform.simulation.models.robots.ideal_commands`). With limits the
    true unicycle ``(x, y, theta, v)`` with saturated inputs
    (:class:`~delayform.simulation.models.robots.LimitedUnicycle`); stated order 2.
``physics``
    Differential-drive bodies with mass, wheel servos, tyres and contacts
    stepped by MuJoCo (:func:`~delayform.simulation.physics.engine.integrate_physics`,
    the ``physics`` extra), each robot's controller (the saturated unicycle's
    functions) ticking at its chassis' control period; the run's ``dt`` is
    the sampling, rounded to whole ticks. The engine's own memory and time
    are checked before its model is built.

A new agent model is one new class with the four methods of
:class:`AgentIntegrator` and one entry here, under the name it adds to
:data:`delayform.model.MODELS` (docs/architecture.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from delayform.errors import SimulationInputError
from delayform.model import IROBOT_CREATE, Network, Robot, RobotLimits
from delayform.resources import require
from delayform.simulation.bodies.approach import approach_cost
from delayform.simulation.models.commands import RobotCommands
from delayform.simulation.delayed.filtered import integrate_filtered
from delayform.simulation.delayed.integrator import Progress, Samples, integrate, integrate_linear, stated_order
from delayform.simulation.delayed.reception import integrate_network
from delayform.simulation.models.robots import DoubleIntegrator, LimitedUnicycle, ideal_commands
from delayform.simulation.bodies.safety import FilteredAgent
from delayform.topology import Topology

__all__ = ["RunPlan", "Motion", "AgentIntegrator", "DoubleIntegratorModel", "UnicycleModel", "PhysicsModel",
           "INTEGRATORS"]

_Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RunPlan:
    """Everything one run needs, checked and prepared by :func:`~delayform.simulation.simulate`.

    Attributes
    ----------
    topology, P, D
        The team (paper, eq. 1).
    tau1, tau2
        The delays as given (s); ``eff1``, ``eff2`` the ones the integrator
        uses (a delay longer than the run reads only the constant history).
    dt, steps, save_every
        Step (s), number of steps and saving stride.
    duration
        The run's length as given (s); an integrator on its own clock (the
        physics engine's control ticks) ends on it.
    C, F
        The weight matrix (dense for small teams, sparse above) and the
        formation forcing ``P (I - C) z_desired``.
    x0, v0, th0, speed0
        Initial positions, Cartesian velocities, headings and speeds.
    robot, network
        The robot and the network (None for the paper's ideal one).
    actuation
        tau_a (s) every robot executes its command late.
    linear
        Whether the blocked linear path fits in memory (small ideal teams).
    hybrid
        Whether a filtered run of a small ideal team may use the linear path
        where the filter is idle.
    progress
        The callback ``(steps done, steps)``, or None.
    """

    topology: Topology
    P: float
    D: float
    tau1: float
    tau2: float
    eff1: float
    eff2: float
    dt: float
    steps: int
    save_every: int
    duration: float
    C: Any
    F: _Array
    x0: _Array
    v0: _Array
    th0: _Array
    speed0: _Array
    robot: Robot
    network: Network | None
    actuation: float
    linear: bool
    hybrid: bool
    progress: Progress | None


@dataclass(frozen=True, eq=False)
class Motion:
    """What an integrator reports of the robots besides their positions: ``(T, n)`` headings and speeds, inputs, commands.

    ``step`` is the integrator's own step (s) when it is not the run's ``dt``
    (the physics engine's control period), else None.
    """

    headings: _Array
    speeds: _Array
    inputs: _Array
    commands: RobotCommands | None
    stated_order: int
    step: float | None = None


class AgentIntegrator(Protocol):
    """One entry of :data:`INTEGRATORS`: how one agent model is checked, integrated and reported."""

    name: str

    def check(self, robot: Robot, speed0: _Array) -> None:
        """Refuse, with a :class:`~delayform.errors.SimulationInputError`, a start this model cannot take."""
        ...

    def generic(self, robot: Robot) -> bool:
        """Whether the run needs the generic per-step loop (the cost estimate), not the linear paths."""
        ...

    def integrate(self, plan: RunPlan) -> Samples:
        """The saved samples of the run."""
        ...

    def motion(self, plan: RunPlan, run: Samples) -> Motion:
        """Headings, speeds, inputs and commands from the samples."""
        ...


def run_agent(plan: RunPlan, agent: Any) -> Samples:
    """An agent in the generic RK4 loop: behind the safety filter if the robot has one, over the network if any."""
    robot = plan.robot
    if robot.safety is not None:
        agent = FilteredAgent(agent, robot.safety, robot.body_radius)
    if plan.network is not None:
        return integrate_network(agent, plan.topology, plan.F, plan.P, plan.D, plan.tau1, plan.tau2,
                                 network=plan.network, dt=plan.dt, steps=plan.steps, save_every=plan.save_every,
                                 progress=plan.progress, actuation_delay=plan.actuation)  # fmt: skip
    return integrate(agent, plan.C, plan.F, plan.P, plan.D, plan.eff1, plan.eff2, plan.dt, plan.steps,
                     plan.save_every, plan.progress, plan.actuation)  # fmt: skip


def _check_speed(limits: RobotLimits, speed0: _Array) -> None:
    """Refuse robots that start faster than their limits."""
    if np.abs(speed0).max() > limits.speed_cap:
        raise SimulationInputError(
            f"initial_speed {np.abs(speed0).max():g} m/s exceeds the robots' speed limit {limits.speed_cap:g} m/s"
        )


def _limited_motion(run: Samples, limits: RobotLimits, step: float | None = None) -> Motion:
    """Headings, speeds and the executed commands of robots with limits (the states and extras of LimitedUnicycle)."""
    assert run.states is not None
    ex = run.extras
    spd = run.states[..., 3].copy()
    commands = RobotCommands.from_motion(
        run.times, spd, ex["omega"], ex["dv_dt"], limits,
        ideal_turn_rate=ex["ideal_omega"], ideal_acceleration=ex["ideal_dv_dt"], limited=True,
        speed_held=ex["speed_held"] > 0.5,
    )  # fmt: skip
    head = np.angle(np.exp(1j * run.states[..., 2]))
    return Motion(head, spd, np.stack([ex["dv_dt"], ex["omega"]], axis=-1), commands, 2, step)


def _order(plan: RunPlan) -> int:
    """RK4's order 4 for on-grid delays; 2 where a filter or an actuation buffer interpolates (docs/theory.md)."""
    if plan.robot.safety is not None or plan.actuation > 0.0:
        return 2
    return stated_order(plan.tau1, plan.tau2, plan.dt)


class DoubleIntegratorModel:
    """``x'' = u``: the linear paths where they apply, else the generic loop (module doc)."""

    name = "double_integrator"

    def check(self, robot: Robot, speed0: _Array) -> None:
        """Any start will do."""

    def generic(self, robot: Robot) -> bool:
        """The linear paths apply (the filter and the network are accounted for by the runner)."""
        return False

    def integrate(self, plan: RunPlan) -> Samples:
        """Filtered linear path, generic loop (filter or network), or the blocked linear path."""
        robot = plan.robot
        if plan.hybrid and plan.linear:
            # small ideal teams: the blocked linear path wherever the filter is idle (simulation.delayed.filtered)
            run = integrate_filtered(plan.x0, plan.v0, plan.C, plan.F, plan.P, plan.D, plan.eff1, plan.eff2,
                                     plan.dt, plan.steps, plan.save_every,
                                     2.0 * robot.body_radius + robot.safety.margin, robot.safety.rate,
                                     plan.progress)  # fmt: skip
            if run is not None:
                return run
        if plan.network is not None or robot.safety is not None:
            return run_agent(plan, DoubleIntegrator(plan.x0, plan.v0))
        if plan.linear and plan.actuation == 0.0:
            run = integrate_linear(plan.x0, plan.v0, plan.C, plan.F, plan.P, plan.D, plan.eff1, plan.eff2,
                                   plan.dt, plan.steps, plan.save_every, plan.progress)  # fmt: skip
            if run is not None:
                return run
        return run_agent(plan, DoubleIntegrator(plan.x0, plan.v0))

    def motion(self, plan: RunPlan, run: Samples) -> Motion:
        """Heading and speed of the velocity; the input is the acceleration."""
        vel = run.velocities
        return Motion(np.arctan2(vel[..., 1], vel[..., 0]), np.hypot(vel[..., 0], vel[..., 1]), run.accelerations,
                      None, _order(plan))  # fmt: skip


class UnicycleModel:
    """Differential-drive robots: ideal ones rebuilt from the double integrator, limited ones integrated (module doc)."""

    name = "unicycle"

    def check(self, robot: Robot, speed0: _Array) -> None:
        """Refuse ideal robots at exactly zero speed and robots faster than their limits."""
        limits = robot.limits
        if limits is None and np.any(speed0 == 0.0):
            raise SimulationInputError(
                "ideal robots cannot start at exactly zero speed (paper, eq. 19 divides by v); "
                "give initial_speed != 0 (the paper uses 1e-3) or limits"
            )
        if limits is not None:
            _check_speed(limits, speed0)

    def generic(self, robot: Robot) -> bool:
        """Robots with limits need the generic loop."""
        return robot.limits is not None

    def integrate(self, plan: RunPlan) -> Samples:
        """The double integrator for ideal robots; the saturated unicycle for robots with limits."""
        limits = plan.robot.limits
        if limits is None:
            return INTEGRATORS["double_integrator"].integrate(plan)
        return run_agent(plan, LimitedUnicycle(plan.x0, plan.th0, plan.speed0, limits))

    def motion(self, plan: RunPlan, run: Samples) -> Motion:
        """Ideal robots: rebuilt commands (Create geometry for the wheels); limited ones: what was executed."""
        limits, times = plan.robot.limits, run.times
        if limits is None:
            theta, spd, omega, vdot = ideal_commands(run.velocities, run.accelerations, plan.th0,
                                                     rest_speed=plan.robot.rest_speed)  # fmt: skip
            commands = RobotCommands.from_motion(times, spd, omega, vdot, IROBOT_CREATE)
            return Motion(np.angle(np.exp(1j * theta)), spd, np.stack([vdot, omega], axis=-1), commands, _order(plan))
        return _limited_motion(run, limits)


class PhysicsModel:
    """Robots with mass in the MuJoCo engine, on their controllers' ticks (module doc; :mod:`delayform.simulation.physics`)."""

    name = "physics"

    def check(self, robot: Robot, speed0: _Array) -> None:
        """Refuse robots faster than their limits (the Robot gave them the Create's where none were given)."""
        assert robot.limits is not None
        _check_speed(robot.limits, speed0)

    def generic(self, robot: Robot) -> bool:
        """Not the linear paths; the engine's own cost is checked in :meth:`integrate`."""
        return True

    def integrate(self, plan: RunPlan) -> Samples:
        """The engine's run, sampled every ``round(dt / period)`` ticks times the saving stride."""
        from delayform.simulation.physics.engine import integrate_physics, physics_resources, tick_grid

        robot, n = plan.robot, plan.topology.n
        assert robot.limits is not None and robot.chassis is not None
        period, substeps = tick_grid(robot.chassis)
        ticks = max(1, math.ceil(plan.duration / period - 1e-9))
        stride = max(1, round(plan.dt / period)) * plan.save_every
        nbytes, seconds = physics_resources(n, ticks, substeps)
        nbytes += approach_cost(n, ticks // stride + 2)[0]
        require(what=f"this physics run ({ticks:,} control ticks of {n:,} robots)", nbytes=nbytes, seconds=seconds,
                setting="the duration (--duration) or the number of robots")  # fmt: skip
        return integrate_physics(plan.topology, plan.F, plan.P, plan.D, plan.tau1, plan.tau2, chassis=robot.chassis,
                                 limits=robot.limits, x0=plan.x0, th0=plan.th0, speed0=plan.speed0,
                                 duration=plan.duration, save_every=stride, network=plan.network,
                                 progress=plan.progress, safety=robot.safety, radius=robot.body_radius,
                                 actuation_delay=plan.actuation)  # fmt: skip

    def motion(self, plan: RunPlan, run: Samples) -> Motion:
        """What the controllers commanded and executed, as for robots with limits; the step is the control period."""
        assert plan.robot.limits is not None and plan.robot.chassis is not None
        return _limited_motion(run, plan.robot.limits, plan.robot.chassis.control_period)


#: the integrator of each agent model, keyed by :attr:`Robot.model <delayform.model.Robot.model>`
INTEGRATORS: Mapping[str, AgentIntegrator] = MappingProxyType(
    {"double_integrator": DoubleIntegratorModel(), "unicycle": UnicycleModel(), "physics": PhysicsModel()}
)
