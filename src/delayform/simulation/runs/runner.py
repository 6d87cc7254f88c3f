"""Simulation of the formation protocol with two constant delays (paper, eqs. 1 and 13).

Agent i applies (per coordinate, the paper's eq. 1 plus the forcing of the paper's eq. 13)::

    u_i(t) = P (sum_k C_ik x_k(t - tau1) - x_i(t)) + D (sum_k C_ik xdot_k(t - tau2) - xdot_i(t)) + F_i

with ``F = P (I - C) z_desired`` (:func:`delayform.formation.formation_forcing`).

Agent models (:mod:`delayform.simulation.models.robots`)
-------------------------------------------------
``double_integrator``
    ``x'' = u`` (Section "Consensus Protocol").
``unicycle`` without limits (ideal robots)
    The feedback-linearized differential-drive robot of Section "Feedback
    Linearization". Its position follows the double integrator exactly while
    v != 0, so the double integrator is integrated (fast and exactly, no
    regularisation of the paper's eq. 19) and heading, signed speed, turn rate
    and wheel speeds are reconstructed from velocity and acceleration
    (:func:`delayform.simulation.models.robots.ideal_commands`).
``unicycle`` with ``limits``
    The true unicycle state (x, y, theta, v) with saturated inputs
    (:class:`delayform.simulation.models.robots.LimitedUnicycle`), using the
    neighbours' delayed states from the history. The saturations are
    continuous but not smooth: **stated order 2**.
``physics``
    Differential-drive bodies with mass, wheel servos, tyres and contacts
    stepped by MuJoCo, each robot's controller (the same functions as the
    saturated unicycle) ticking at its control period
    (:mod:`delayform.simulation.physics`).
Over an imperfect ``network``
    The same agent models (the double integrator, from which ideal robots
    are rebuilt, the saturated unicycle, or the robots with mass) driven by what each agent hears
    (:func:`delayform.simulation.delayed.reception.integrate_network`).

Each agent model is one entry of the integrator table
:data:`delayform.simulation.runs.integrators.INTEGRATORS`, named by ``Robot.model``.
History and integrator: :mod:`delayform.simulation.delayed.integrator` (RK4 with
Hermite look-ups, stated order 4 for on-grid delays).
The state is constant before ``t = 0``: positions ``x0`` and Cartesian
velocities ``v0 = initial_speed (cos theta0, sin theta0)``. Agents send
positions and Cartesian velocities; headings are private.

Resources and divergence
------------------------
Memory and run time are estimated before anything is allocated and a run
that would exceed the machine is refused with
:class:`~delayform.errors.ResourceLimitError`. A run whose state overflows stops
cleanly; its :attr:`Trajectory.status` says so.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_positive, validated
from delayform.errors import DelayError, SimulationInputError
from delayform.formation import (
    centroid_weights,
    check_formation,
    formation_forcing,
    named_formation,
)
from delayform.resources import require
from delayform.model import MODELS, Delays, Network, Robot, RobotLimits, Team
from delayform.model.start import Start
from delayform.simulation.bodies.assignment import assign_slots
from delayform.simulation.bodies.approach import approach_cost, closest_approach
from delayform.simulation.runs.compat import SIMULATE_KEYWORDS, accepts_loose_calls
from delayform.simulation.delayed.integrator import Samples, history_steps, effective_delay
from delayform.simulation.runs.integrators import INTEGRATORS, Motion, RunPlan
from delayform.simulation.runs.options import RunOptions
from delayform.simulation.bodies.safety import SafetyReport
from delayform.simulation.runs.trajectory import (
    Trajectory,
    contact_warning,
    formation_error,
    run_status,
    settling_time,
)
from delayform.topology import paper_six

__all__ = ["MODELS", "simulate", "paper_simulations", "estimate_resources"]

#: robots slower than this (m/s) at the end of a filtered run that did not settle are deadlocked
DEADLOCK_SPEED = 1e-2

#: teams up to this size multiply by a dense C and use the blocked linear path
_DENSE_AGENTS = 64

#: at most this many float64 samples (times x agents) are saved by default
_SAVE_BUDGET = 2_000_000

#: the linear path keeps every step's record; above this many bytes the generic loop runs
_LINEAR_BYTES = 6 * 2**30

_Array = NDArray[np.float64]


def estimate_resources(
    n: int, steps: int, save_every: int, tau1: float, tau2: float, dt: float, *, limited: bool, nnz: int = 0
) -> tuple[float, float, bool]:
    """Estimated peak bytes and seconds of a run, and whether the blocked linear path is used.

    Parameters
    ----------
    n, steps, save_every
        Agents, steps and saving stride.
    tau1, tau2, dt
        Effective delays (:func:`~delayform.simulation.delayed.integrator.effective_delay`) and step.
    limited
        Whether robots with limits are integrated (the generic loop).
    nnz
        Non-zeros of C (sparse teams).
    """
    saved = steps // save_every + 2
    per_sample = 24 if limited else 20  # floats per agent and saved sample, commands included
    nbytes = 8.0 * saved * n * per_sample
    deepest = int(math.ceil(max(tau1, tau2) / dt)) + 3
    linear_bytes = 8.0 * (deepest + steps + 2) * 6 * n
    linear = not limited and n <= _DENSE_AGENTS and linear_bytes <= _LINEAR_BYTES
    if linear:
        nbytes += linear_bytes
        # one block of about 20 steps costs about 40 microseconds for small teams
        seconds = steps * (2e-6 + 3e-9 * n * n)
    else:
        nbytes += 8.0 * history_steps(tau1, tau2, dt) * 6 * n + 8.0 * 60 * n + 12.0 * nnz
        # per step about 80 microseconds of overhead (300 with limits: more NumPy calls per
        # stage) and 1.6 (2.5) microseconds per agent (docs/benchmarks.md)
        seconds = steps * ((3e-4 + 2.5e-6 * n) if limited else (8e-5 + 1.6e-6 * n))
    # after the run: the exact closest approach between saved samples, quadratic in the team
    approach_bytes, approach_seconds = approach_cost(n, saved)
    return nbytes + approach_bytes, seconds + approach_seconds, linear


# ------------------------------------------------------------------- core
@accepts_loose_calls(SIMULATE_KEYWORDS, default_model="unicycle")
@validated(SimulationInputError)
def simulate(
    team: Team,
    delays: Delays,
    formation: ArrayLike | str,
    *,
    robot: Robot | None = None,
    network: Network | None = None,
    start: Start | None = None,
    duration: float,
    dt: float,
    options: RunOptions | None = None,
) -> Trajectory:
    """Simulate the team under the paper's eq. 13 with delays tau1 (positions) and tau2 (velocities).

    Parameters
    ----------
    team
        Topology and gains (:class:`~delayform.model.Team`, checked when
        made); C is applied as a sparse product above 64 agents.
    delays
        Uniform delays (:class:`~delayform.model.Delays`); a non-zero delay
        must be at least ``dt``. Its actuation delay, if any, is the robots'
        (give it there or in ``robot``, not both). Delays that differ per
        link run over a network: ``network=Network(delays=LinkDelays(tau1,
        tau2))`` beside the nominal pair.
    formation
        ``(n, 2)`` desired positions or a shape name (:data:`delayform.formation.SHAPES`).
    robot
        What belongs to the robot (:class:`~delayform.model.Robot`: model,
        limits or profile, body radius, safety filter, actuation delay,
        rest speed); its model names the entry of the integrator table
        :data:`~delayform.simulation.runs.integrators.INTEGRATORS`. None: ``Robot()``,
        ideal differential-drive robots (paper, eq. 19) whose wheel speeds
        are reported for the geometry of :data:`~delayform.model.IROBOT_CREATE`.
        ``Robot(model="physics")``: robots with mass, wheel servos and
        contacts in a physics engine (:mod:`delayform.simulation.physics`;
        the ``physics`` extra), whose controller ticks at the chassis'
        control period; ``dt`` is then the sampling of the saved run
        (rounded to whole ticks).
    network
        An imperfect network (:class:`~delayform.model.Network`: per-link and
        varying delays, jitter, loss, sampling, noise), integrated by
        :func:`~delayform.simulation.delayed.reception.integrate_network`. None or the
        ideal network: the paper's, exactly the ordinary integrators.
    start
        Where the robots start (:class:`~delayform.model.Start`: positions,
        headings, speed, the seed of what is drawn). None: ``Start()``,
        random positions and headings from seed 0 at the paper's 1e-3 m/s.
        Ideal robots cannot start at exactly zero speed (paper, eq. 19
        divides by v there).
    duration, dt
        Length of the run and the fixed step (s); the run ends at
        ``ceil(duration / dt) dt`` (for ``"physics"``: at a whole number of
        control ticks, sampled every ``round(dt / period)`` ticks).
    options
        Saving stride, slot assignment and a progress callback
        (:class:`~delayform.simulation.runs.options.RunOptions`); None: the defaults.

    Returns
    -------
    Trajectory
        With ``status`` and ``warnings`` saying whether the run settled and
        whether bodies touched (``min_distance``, ``contacts``:
        :func:`~delayform.simulation.bodies.approach.closest_approach`), and the
        robots' ``commands``.

    Raises
    ------
    GainError, DelayError, FormationError, SimulationInputError, NoSpanningTreeError
        For bad gains, delays, formation, step, duration, model, limits or initial state,
        and for formation slots closer than two body radii.
    ResourceLimitError
        When the run would need more memory or time than the machine has.

    Notes
    -----
    The loose form of earlier versions, ``simulate(topology, P, D, tau1, tau2,
    formation, model=..., limits=..., initial_positions=..., seed=...,
    save_every=..., ...)``, is still taken: each keyword goes to its noun
    (:data:`~delayform.simulation.runs.compat.SIMULATE_KEYWORDS`).

    Examples
    --------
    >>> from delayform.model import Delays, Team
    >>> from delayform.topology import paper_six
    >>> traj = simulate(Team(paper_six(), 1.0, 0.5), Delays(0.3, 0.2), "hexagon", duration=60.0, dt=0.05)
    >>> traj.status, bool(traj.formation_error[-1] < 0.02 * traj.formation_error[0])
    ('settled', True)
    """
    robot = Robot() if robot is None else robot
    start = Start() if start is None else start
    options = RunOptions() if options is None else options
    if options.executor is not None:
        raise SimulationInputError("an executor runs the runs of a Monte Carlo; simulate makes one run")
    topology, P, D = team.topology, team.P, team.D
    tau1, tau2 = _uniform(delays)
    dt = check_positive("dt", dt, SimulationInputError)
    duration = check_positive("duration", duration, SimulationInputError)
    robot = _with_actuation(robot, delays)
    integrator = INTEGRATORS[robot.model]
    limits, ta = robot.limits, robot.actuation_delay
    if network is not None and network.is_ideal:
        network = None  # the paper's network: exactly the ordinary integrators
    check_actuation(robot, network, dt)
    for name, tau in (("tau1", tau1), ("tau2", tau2)):
        if 0.0 < tau < dt * (1.0 - 1e-9):
            raise SimulationInputError(
                f"dt = {dt} exceeds {name} = {tau}: a non-zero delay must be at least one step"
            )
    n = topology.n
    desired = check_formation(formation, n)
    robot.check_slots(desired)
    x0, th0, speed0 = start.draw(n)
    integrator.check(robot, speed0)
    v0 = speed0[:, None] * np.column_stack([np.cos(th0), np.sin(th0)])
    slots = np.arange(n)
    if options.assignment == "optimal":
        slots = assign_slots(topology, P, D, tau1, tau2, desired, x0, v0).slots
        desired = desired[slots]
    steps = max(1, math.ceil(duration / dt - 1e-9))
    save_every = options.save_every
    if save_every is None:
        save_every = max(1, math.ceil((steps + 1) * n / _SAVE_BUDGET))
    # a delay longer than the run reads only the constant history (integrator doc)
    eff1, eff2 = effective_delay(tau1, dt, steps), effective_delay(tau2, dt, steps)
    filtered = robot.safety is not None
    generic = integrator.generic(robot)
    # small ideal filtered teams keep the linear path's records (simulation.delayed.filtered)
    hybrid = filtered and network is None and not generic and ta == 0.0 and n <= _DENSE_AGENTS
    nbytes, seconds, linear = estimate_resources(
        n, steps, save_every, eff1, eff2, dt, limited=generic or (filtered and not hybrid),
        nnz=topology.C_sparse.nnz,
    )
    # a step count past 1e12 said in full would be a line of digits
    count = f"{steps:,}" if steps < 10**12 else f"{float(steps):.3g}"
    require(what=f"this simulation ({count} steps of {n:,} agents)", nbytes=nbytes, seconds=seconds,
            setting="the duration (--duration), the number of agents, or the number of steps (a longer step dt, --dt, or a larger save_every)")  # fmt: skip

    plan = RunPlan(
        topology=topology, P=P, D=D, tau1=tau1, tau2=tau2, eff1=eff1, eff2=eff2, dt=dt, steps=steps,
        save_every=save_every, duration=duration, C=topology.C_sparse.toarray() if n <= _DENSE_AGENTS else topology.C_sparse,
        F=formation_forcing(topology, P, desired), x0=x0, v0=v0, th0=th0, speed0=speed0, robot=robot,
        network=network, actuation=ta, linear=linear, hybrid=hybrid, progress=options.progress,
    )  # fmt: skip
    run = integrator.integrate(plan)
    if options.progress is not None:
        options.progress(steps, steps)
    traj = _trajectory(plan, desired, duration, run, integrator.motion(plan, run))
    return dataclasses.replace(traj, slots=slots)


def _uniform(delays: Delays) -> tuple[float, float]:
    """The pair of uniform delays; per-link ones are refused with the way to run them."""
    if delays.kind != "uniform":
        raise DelayError(
            "simulate takes uniform delays (one pair on every link); run delays that differ per link over "
            "network=Network(delays=LinkDelays(tau1, tau2)) with the nominal pair in Delays"
        )
    return delays.pair


def _with_actuation(robot: Robot, delays: Delays) -> Robot:
    """The robot with the actuation delay of ``delays`` (one place for it: refuse two different ones)."""
    if delays.actuation == 0.0 or delays.actuation == robot.actuation_delay:
        return robot
    if robot.actuation_delay != 0.0:
        raise DelayError(
            f"two actuation delays: {delays.actuation:g} s in the delays and {robot.actuation_delay:g} s in the "
            "robot; give it in one place"
        )
    return dataclasses.replace(robot, actuation_delay=delays.actuation)


def check_actuation(robot: Robot, network: Network | None, dt: float) -> None:
    """Refuse the runs an actuation delay is not modelled for, with the reason."""
    ta = robot.actuation_delay
    if ta == 0.0:
        return
    if ta < dt * (1.0 - 1e-9):
        raise SimulationInputError(f"dt = {dt} exceeds actuation_delay = {ta}: a non-zero delay must be at least one step")
    if robot.model == "unicycle" and robot.limits is None:
        raise SimulationInputError(
            "an actuation delay needs robots with limits or model='double_integrator': ideal robots are "
            "integrated as double integrators, which a late (dv/dt, omega) no longer is"
        )
    if robot.safety is not None and robot.limits is not None:
        # the filter must predict where each robot will be when its command is executed: exact for
        # x'' = u (CommandBuffer.predict), not for the saturated unicycle, of which nothing sound is known
        raise SimulationInputError(
            "an actuation delay with the safety filter is modelled for double integrators only: the filter "
            "must predict each robot tau_a ahead, which it cannot do soundly through actuator limits"
        )


def _trajectory(plan: RunPlan, desired: _Array, duration: float, run: Samples, motion: Motion) -> Trajectory:
    """The run's Trajectory: formation error, settling, limits, safety and contacts judged on the samples."""
    robot, limits, topology = plan.robot, plan.robot.limits, plan.topology
    times, pos, vel = run.times, run.positions, run.velocities
    commands, spd = motion.commands, motion.speeds
    error = formation_error(pos, desired)
    settled = settling_time(times, error, 1.0 + float(np.abs(pos[0]).max()))
    status, warnings = run_status(times, error, settled, run.stopped, duration)
    if limits is not None and commands is not None:
        found = commands.exceedances()
        if found and status != "settled":
            warnings += ("the actuator limits were active: " + "; ".join(e.sentence for e in found),)
    report = None
    if robot.safety is not None:
        report = SafetyReport(2.0 * robot.body_radius + robot.safety.margin, run.extras["safety_active"] > 0.5,
                              run.extras["safety_infeasible"] > 0.5, times)  # fmt: skip
        if report.was_active:
            warnings += (report.sentence(),)
        status, warnings = _deadlock(status, warnings, report, spd, duration)
    approach = closest_approach(times, pos, vel, 2.0 * robot.body_radius)
    if approach.contacts:
        warnings += (contact_warning(approach.contacts),)
    return Trajectory(
        times=times, positions=pos, velocities=vel, headings=motion.headings, speeds=spd, inputs=motion.inputs,
        desired=desired, model=robot.model, P=plan.P, D=plan.D, tau1=plan.tau1, tau2=plan.tau2,
        dt=plan.dt if motion.step is None else motion.step,
        stated_order=motion.stated_order,
        actuation_delay=robot.actuation_delay,
        formation_error=error, settling_time=settled,
        final_centroid=centroid_weights(topology) @ pos[-1],
        min_distance=approach.min_distance, closest_at=approach.at, radius=robot.body_radius,
        contacts=approach.contacts, safety=report, commands=commands, limits=limits,
        status=status, warnings=warnings, labels=topology.labels, stopped_at=run.stopped,
    )  # fmt: skip


def _deadlock(
    status: str, warnings: tuple[str, ...], report: SafetyReport, speeds: _Array, duration: float
) -> tuple[str, tuple[str, ...]]:
    """A run that did not settle because the filter holds robots still short of their slots: ``"deadlock"``.

    Deadlock: not settled, the filter still acting over the last tenth of the
    saved samples, and every robot slower than :data:`DEADLOCK_SPEED` at the end.
    """
    if status != "not settled":
        return status, warnings
    tail = max(1, report.times.size // 10)
    if report.active[-tail:].any() and float(np.abs(speeds[-1]).max()) < DEADLOCK_SPEED:
        return "deadlock", (
            f"deadlock: the robots stopped short of the formation within {duration:.4g} s, held apart by "
            f"the safety filter (robots {', '.join(str(i + 1) for i in np.flatnonzero(report.active[-1]))} "
            f"were still filtered at the end)",
        ) + tuple(w for w in warnings if not w.startswith("the formation error did not stay"))
    return status, warnings


# ------------------------------------------------------------ paper demo
@validated(SimulationInputError)
def paper_simulations(
    *, seed: int = 0, duration: float = 150.0, dt: float = 0.01, spacing: float = 2.0,
    limits: RobotLimits | None = None,
) -> tuple[Trajectory, Trajectory]:  # fmt: skip
    """The paper's six robots (paper, Fig. 2, P = 1, D = 0.5) into a hexagon at points a and b.

    Unicycle robots from random positions and headings (``seed``) with initial
    speed 1e-3 (Section "Simulation Examples"); point a is
    ``(tau1, tau2) = (0.3, 0.2)``, point b is ``(2, 1)``.

    Parameters
    ----------
    seed
        Seed of the random initial positions and headings; both runs start
        from the same state. Default 0.
    duration
        Length of each run (s); default 150.
    dt
        Fixed RK4 step (s); default 0.01, at most 0.2 (the delay tau2 at
        point a).
    spacing
        Side length of the desired hexagon; default 2.0.
    limits
        Actuator limits (e.g. :data:`IROBOT_CREATE`); default: ideal robots.

    Returns
    -------
    (Trajectory, Trajectory)
        The runs at point a and at point b.
    """
    team = Team(paper_six(), 1.0, 0.5)
    shape = named_formation("hexagon", team.n, spacing=spacing)
    robot, start = Robot(limits=limits), Start(seed=seed)
    runs = tuple(
        simulate(team, Delays(t1, t2), shape, robot=robot, start=start, duration=duration, dt=dt)
        for t1, t2 in ((0.3, 0.2), (2.0, 1.0))
    )
    return runs[0], runs[1]

