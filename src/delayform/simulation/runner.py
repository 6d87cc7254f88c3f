"""Simulation of the formation protocol with two constant delays (eq. protocol, eq. formation).

Agent i applies (per coordinate, eq. protocol plus the forcing of eq. formation)::

    u_i(t) = P (sum_k C_ik x_k(t - tau1) - x_i(t)) + D (sum_k C_ik xdot_k(t - tau2) - xdot_i(t)) + F_i

with ``F = P (I - C) z_desired`` (:func:`delayform.formation.formation_forcing`).

Agent models (:mod:`delayform.simulation.robots`)
-------------------------------------------------
``double_integrator``
    ``x'' = u`` (Section "Consensus Protocol").
``unicycle`` without limits (ideal robots)
    The feedback-linearized differential-drive robot of Section "Feedback
    Linearization". Its position follows the double integrator exactly while
    v != 0, so the double integrator is integrated (fast and exactly, no
    regularisation of eq. transform2) and heading, signed speed, turn rate
    and wheel speeds are reconstructed from velocity and acceleration
    (:func:`delayform.simulation.robots.ideal_commands`).
``unicycle`` with ``limits``
    The true unicycle state (x, y, theta, v) with saturated inputs
    (:class:`delayform.simulation.robots.LimitedUnicycle`), using the
    neighbours' delayed states from the history. The saturations are
    continuous but not smooth: **stated order 2**.
``physics``
    Differential-drive bodies with mass, wheel servos, tyres and contacts
    stepped by MuJoCo, each robot's controller (the same functions as the
    saturated unicycle) ticking at its control period
    (:mod:`delayform.simulation.physics`).
Over an imperfect ``network``
    The same agent models (the double integrator, from which ideal robots
    are rebuilt, or the saturated unicycle) driven by what each agent hears
    (:func:`delayform.simulation.reception.integrate_network`).

History and integrator: :mod:`delayform.simulation.integrator` (RK4 with
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
from typing import Any

from delayform._validation import check_delay, check_gains, check_magnitude, check_positive, validated
from delayform.errors import SimulationInputError
from delayform.formation import (
    centroid_weights,
    check_formation,
    formation_forcing,
    named_formation,
)
from delayform.resources import require
from delayform.simulation.commands import RobotCommands
from delayform.simulation.integrator import (
    Progress,
    Samples,
    effective_delay,
    history_steps,
    integrate,
    integrate_linear,
    stated_order,
)
from delayform.simulation.network import Network
from delayform.simulation.reception import integrate_network
from delayform.simulation.robots import (
    IROBOT_CREATE,
    MODELS,
    REST_SPEED,
    DoubleIntegrator,
    LimitedUnicycle,
    Robot,
    RobotLimits,
    ideal_commands,
)
from delayform.simulation.assignment import assign_slots, check_assignment
from delayform.simulation.bodies import approach_cost, closest_approach
from delayform.simulation.filtered import integrate_filtered
from delayform.simulation.safety import BarrierFilter, FilteredAgent, SafetyReport
from delayform.simulation.trajectory import (
    Trajectory,
    contact_warning,
    formation_error,
    run_status,
    settling_time,
)
from delayform.topology import Topology, paper_six

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


def _check_array(name: str, value: ArrayLike, shape: tuple[int, ...]) -> _Array:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SimulationInputError(f"{name} must be numbers of shape {shape}") from exc
    if arr.shape != shape:
        if arr.ndim == 0 and len(shape) == 1:
            return _check_array(name, np.full(shape, float(arr)), shape)
        raise SimulationInputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SimulationInputError(f"{name} must be finite")
    # lengths and speeds; angles too (at 1e6 rad a float64 still resolves 1e-10 rad, at 1e300 nothing)
    unit = {"initial_positions": "m", "initial_headings": "rad"}.get(name, "m/s")
    check_magnitude(name, arr, SimulationInputError, unit)
    return arr


def _rng(seed: object) -> np.random.Generator:
    """``numpy.random.default_rng(seed)`` for a seed numpy takes, else SimulationInputError."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise SimulationInputError(f"seed must be a non-negative integer, a numpy Generator or None, got {seed!r}")
    return np.random.default_rng(seed)


def _initial_state(
    n: int,
    initial_positions: ArrayLike | None,
    initial_headings: ArrayLike | None,
    initial_speed: ArrayLike,
    seed: int | np.random.Generator | None,
) -> tuple[_Array, _Array, _Array]:
    """Positions, headings, speeds; missing ones drawn with ``seed``.

    Random positions are uniform in ``[-L, L]^2`` with ``L = 5 max(1, sqrt(n / 6))``
    (the density of the paper's six robots in a 10 x 10 square), headings
    uniform in ``[-pi, pi)``.
    """
    rng = _rng(seed)
    half = 5.0 * max(1.0, math.sqrt(n / 6.0))
    if initial_positions is None:
        x0 = rng.uniform(-half, half, size=(n, 2))
    else:
        x0 = _check_array("initial_positions", initial_positions, (n, 2))
    if initial_headings is None:
        th0 = rng.uniform(-np.pi, np.pi, size=n)
    else:
        th0 = _check_array("initial_headings", initial_headings, (n,))
    v0 = _check_array("initial_speed", initial_speed, (n,))
    return x0, th0, v0


def estimate_resources(
    n: int, steps: int, save_every: int, tau1: float, tau2: float, dt: float, *, limited: bool, nnz: int = 0
) -> tuple[float, float, bool]:
    """Estimated peak bytes and seconds of a run, and whether the blocked linear path is used.

    Parameters
    ----------
    n, steps, save_every
        Agents, steps and saving stride.
    tau1, tau2, dt
        Effective delays (:func:`~delayform.simulation.integrator.effective_delay`) and step.
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
@validated(SimulationInputError)
def simulate(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    formation: ArrayLike | str,
    *,
    robot: Robot | None = None,
    model: str | None = None,
    limits: RobotLimits | None = None,
    initial_positions: ArrayLike | None = None,
    initial_headings: ArrayLike | None = None,
    initial_speed: ArrayLike = 1e-3,
    seed: int | np.random.Generator | None = 0,
    duration: float,
    dt: float,
    rest_speed: float = REST_SPEED,
    save_every: int | None = None,
    progress: Progress | None = None,
    network: Network | None = None,
    assignment: str = "given",
    safety: str | BarrierFilter | None = None,
    actuation_delay: float | None = None,
) -> Trajectory:
    """Simulate n agents under eq. formation with delays tau1 (positions) and tau2 (velocities).

    Parameters
    ----------
    topology
        Communication topology; C is applied as a sparse product above 64 agents.
    P, D
        Positive gains of eq. protocol.
    tau1, tau2
        Non-negative delays (s); a non-zero delay must be at least ``dt``.
    formation
        ``(n, 2)`` desired positions or a shape name (:data:`delayform.formation.SHAPES`).
    robot
        What belongs to the robot (:class:`~delayform.simulation.robots.Robot`:
        model, limits, body radius). None: ``Robot(model, limits)`` from the
        two shortcuts below (give either ``robot`` or the shortcuts).
    model
        Shortcut for ``Robot.model``: ``"unicycle"`` (differential-drive robot,
        eq. transform2; the default), ``"double_integrator"``, or ``"physics"``:
        robots with mass, wheel servos and contacts in a physics engine
        (:mod:`delayform.simulation.physics`; the ``physics`` extra), whose
        controller ticks at the chassis' control period; ``dt`` is then the
        sampling of the saved run (rounded to whole ticks).
    limits
        Shortcut for ``Robot.limits``: actuator limits of the robots
        (:class:`RobotLimits`, e.g. :data:`IROBOT_CREATE`): the saturated
        unicycle is integrated. None (default): ideal robots, whose wheel
        speeds are reported for the geometry of :data:`IROBOT_CREATE`.
    initial_positions
        ``(n, 2)``; default: uniform random (see ``_initial_state``) from ``seed``.
    initial_headings
        ``(n,)`` radians; default: uniform random from ``seed``.
    initial_speed
        Scalar or ``(n,)`` signed speeds (m/s); default 1e-3 as in the paper.
        The initial Cartesian velocity is ``speed (cos theta, sin theta)``.
        Ideal robots cannot start at exactly zero speed (eq. transform2
        divides by v there): give a speed or ``limits``.
    seed
        Seed of the random initial state.
    duration, dt
        Length of the run and the fixed step (s); the run ends at
        ``ceil(duration / dt) dt`` (for ``"physics"``: at a whole number of
        control ticks, sampled every ``round(dt / period)`` ticks).
    rest_speed
        Ideal robots whose speed (m/s) and commanded acceleration (m/s^2)
        are both below this hold their heading (:data:`REST_SPEED`).
    save_every
        Keep every ``save_every``-th step; default: every step while
        ``samples x n <= 2e6``, else the smallest stride that fits.
    progress
        Optional callback ``progress(steps_done, steps)``, called now and then.
    network
        An imperfect network (:class:`~delayform.simulation.network.Network`:
        per-link and varying delays, jitter, loss, sampling, noise), integrated
        by :func:`~delayform.simulation.reception.integrate_network`: the
        double integrator (ideal robots are rebuilt from it), or with
        ``limits`` the saturated unicycle driven by what each robot hears.
        None or the ideal network: the paths above, unchanged.
    actuation_delay
        Shortcut for :attr:`Robot.actuation_delay` (s, >= 0; at least dt when
        non-zero): each robot executes its command that much later (a command
        buffer, linear between steps: :mod:`delayform.simulation.actuation`;
        stated order 2). Double integrators and robots with ``limits``, over any
        ``network``; with ``safety`` double integrators only (the filter predicts
        each robot tau_a ahead, docs/theory.md); ideal robots (no limits) refuse it.
    assignment
        ``"given"`` (default): robot i takes slot i of ``formation``.
        ``"optimal"``: the slots that minimise the total squared distance from
        each robot's start to its predicted final position
        (:func:`~delayform.simulation.assignment.assign_slots`; exact for
        balanced teams, certified or bounded otherwise). It relabels the
        slots only: the stability analysis is unchanged (docs/theory.md).
    safety
        Shortcut for ``Robot.safety``: ``"barrier"`` (or a
        :class:`~delayform.simulation.safety.BarrierFilter`) filters every
        command through control barrier functions that keep the bodies
        apart (:mod:`delayform.simulation.safety`); the run's ``safety``
        says when it acted, and a team it stopped short of the formation has
        status ``"deadlock"``. None (default): no filter.

    Returns
    -------
    Trajectory
        With ``status`` and ``warnings`` saying whether the run settled and
        whether bodies touched (``min_distance``, ``contacts``:
        :func:`~delayform.simulation.bodies.closest_approach`), and the
        robots' ``commands``.

    Raises
    ------
    GainError, DelayError, FormationError, SimulationInputError, NoSpanningTreeError
        For bad gains, delays, formation, step, duration, model, limits or initial state,
        and for formation slots closer than two body radii.
    ResourceLimitError
        When the run would need more memory or time than the machine has.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=60.0, dt=0.05)
    >>> traj.status, bool(traj.formation_error[-1] < 0.02 * traj.formation_error[0])
    ('settled', True)
    """
    if not isinstance(topology, Topology):
        raise SimulationInputError(f"topology must be a Topology, got {type(topology).__name__}")
    P, D = check_gains(P, D)
    tau1, tau2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    dt = check_positive("dt", dt, SimulationInputError)
    duration = check_positive("duration", duration, SimulationInputError)
    rest_speed = check_positive("rest_speed", rest_speed, SimulationInputError)
    robot = _robot(robot, model, limits, safety, actuation_delay)
    model, limits, ta = robot.model, robot.limits, robot.actuation_delay
    if network is not None and not isinstance(network, Network):
        raise SimulationInputError(f"network must be a Network, got {type(network).__name__}")
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
    check_assignment(assignment)
    x0, th0, speed0 = _initial_state(n, initial_positions, initial_headings, initial_speed, seed)
    if model == "unicycle" and limits is None and np.any(speed0 == 0.0):
        raise SimulationInputError(
            "ideal robots cannot start at exactly zero speed (eq. transform2 divides by v); "
            "give initial_speed != 0 (the paper uses 1e-3) or limits"
        )
    if limits is not None and np.abs(speed0).max() > limits.speed_cap:
        raise SimulationInputError(
            f"initial_speed {np.abs(speed0).max():g} m/s exceeds the robots' speed limit {limits.speed_cap:g} m/s"
        )
    v0 = speed0[:, None] * np.column_stack([np.cos(th0), np.sin(th0)])
    slots = np.arange(n)
    if assignment == "optimal":
        slots = assign_slots(topology, P, D, tau1, tau2, desired, x0, v0).slots
        desired = desired[slots]
    if model == "physics":
        traj = _physics(topology, desired, robot, P, D, tau1, tau2, dt, duration, (x0, th0, speed0),
                        save_every, network, progress, rest_speed)  # fmt: skip
        return dataclasses.replace(traj, slots=slots)
    steps = max(1, math.ceil(duration / dt - 1e-9))
    if save_every is None:
        save_every = max(1, math.ceil((steps + 1) * n / _SAVE_BUDGET))
    elif isinstance(save_every, bool) or not isinstance(save_every, int) or save_every < 1:
        raise SimulationInputError(f"save_every must be a positive integer, got {save_every!r}")
    # a delay longer than the run reads only the constant history (integrator doc)
    eff1, eff2 = effective_delay(tau1, dt, steps), effective_delay(tau2, dt, steps)
    filtered = robot.safety is not None
    # small ideal filtered teams keep the linear path's records (simulation.filtered)
    hybrid = filtered and network is None and limits is None and ta == 0.0 and n <= _DENSE_AGENTS
    nbytes, seconds, linear = estimate_resources(
        n, steps, save_every, eff1, eff2, dt, limited=limits is not None or (filtered and not hybrid),
        nnz=topology.C_sparse.nnz,
    )
    # a step count past 1e12 said in full would be a line of digits
    count = f"{steps:,}" if steps < 10**12 else f"{float(steps):.3g}"
    require(what=f"this simulation ({count} steps of {n:,} agents)", nbytes=nbytes, seconds=seconds,
            setting="the duration (--duration), the number of agents, or the number of steps (a longer step dt, --dt, or a larger save_every)")  # fmt: skip

    C = topology.C_sparse.toarray() if n <= _DENSE_AGENTS else topology.C_sparse
    F = formation_forcing(topology, P, desired)
    run: Samples | None = None
    if hybrid and linear:
        # small ideal teams: the blocked linear path wherever the filter is idle (simulation.filtered)
        run = integrate_filtered(x0, v0, C, F, P, D, eff1, eff2, dt, steps, save_every,
                                 2.0 * robot.body_radius + robot.safety.margin, robot.safety.rate, progress)  # fmt: skip
    if run is not None:
        pass
    elif network is not None or limits is not None or filtered:
        agent: Any = DoubleIntegrator(x0, v0) if limits is None else LimitedUnicycle(x0, th0, speed0, limits)
        if filtered:
            agent = FilteredAgent(agent, robot.safety, robot.body_radius)
        if network is not None:
            run = integrate_network(agent, topology, F, P, D, tau1, tau2, network=network, dt=dt, steps=steps,
                                    save_every=save_every, progress=progress, actuation_delay=ta)  # fmt: skip
        else:
            run = integrate(agent, C, F, P, D, eff1, eff2, dt, steps, save_every, progress, ta)
    else:
        if linear and ta == 0.0:
            run = integrate_linear(x0, v0, C, F, P, D, eff1, eff2, dt, steps, save_every, progress)
        if run is None:
            run = integrate(DoubleIntegrator(x0, v0), C, F, P, D, eff1, eff2, dt, steps, save_every, progress, ta)
    if progress is not None:
        progress(steps, steps)
    traj = _trajectory(topology, desired, robot, P, D, tau1, tau2, dt, duration, th0, run, rest_speed)
    return dataclasses.replace(traj, slots=slots)


def _physics(
    topology: Topology, desired: _Array, robot: Robot, P: float, D: float, tau1: float, tau2: float,
    dt: float, duration: float, start: tuple[_Array, _Array, _Array], save_every: int | None,
    network: Network | None, progress: Progress | None, rest_speed: float,
) -> Trajectory:  # fmt: skip
    """A run of robots with mass (:mod:`delayform.simulation.physics`): samples every ``dt``, on the control ticks."""
    from delayform.simulation.physics.engine import integrate_physics, physics_resources, tick_grid

    assert robot.limits is not None and robot.chassis is not None
    period, substeps = tick_grid(robot.chassis)
    ticks = max(1, math.ceil(duration / period - 1e-9))
    n = topology.n
    stride = max(1, round(dt / period))
    if save_every is None:
        save_every = max(1, math.ceil((ticks // stride + 1) * n / _SAVE_BUDGET))
    elif isinstance(save_every, bool) or not isinstance(save_every, int) or save_every < 1:
        raise SimulationInputError(f"save_every must be a positive integer, got {save_every!r}")
    nbytes, seconds = physics_resources(n, ticks, substeps)
    nbytes += approach_cost(n, ticks // (stride * save_every) + 2)[0]
    require(what=f"this physics run ({ticks:,} control ticks of {n:,} robots)", nbytes=nbytes, seconds=seconds,
            setting="the duration (--duration) or the number of robots")  # fmt: skip
    x0, th0, speed0 = start
    F = formation_forcing(topology, P, desired)
    run = integrate_physics(topology, F, P, D, tau1, tau2, chassis=robot.chassis, limits=robot.limits,
                            x0=x0, th0=th0, speed0=speed0, duration=duration, save_every=stride * save_every,
                            network=network, progress=progress)  # fmt: skip
    if progress is not None:
        progress(ticks, ticks)
    return _trajectory(topology, desired, robot, P, D, tau1, tau2, period, duration, th0, run, rest_speed)


def _robot(
    robot: Robot | None, model: str | None, limits: RobotLimits | None, safety: object,
    actuation_delay: float | None = None,
) -> Robot:
    """The robot of a run: ``robot``, or one built from the shortcuts (model, limits, safety, actuation_delay)."""
    if robot is None:
        return Robot(model="unicycle" if model is None else model, limits=limits, safety=safety,
                     actuation_delay=0.0 if actuation_delay is None else actuation_delay)  # fmt: skip
    if not isinstance(robot, Robot):
        raise SimulationInputError(f"robot must be a Robot, got {type(robot).__name__}")
    if model is not None or limits is not None or safety is not None or actuation_delay is not None:
        raise SimulationInputError(
            "give the model, limits, safety and actuation_delay either in robot or as keywords, not both"
        )
    return robot


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


def _trajectory(
    topology: Topology,
    desired: _Array,
    robot: Robot,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    dt: float,
    duration: float,
    th0: _Array,
    run: Samples,
    rest_speed: float,
) -> Trajectory:
    model, limits = robot.model, robot.limits
    times, pos, vel, acc = run.times, run.positions, run.velocities, run.accelerations
    commands = None
    if model == "double_integrator":
        head, spd, inp = np.arctan2(vel[..., 1], vel[..., 0]), np.hypot(vel[..., 0], vel[..., 1]), acc
    elif limits is None:
        theta, spd, omega, vdot = ideal_commands(vel, acc, th0, rest_speed=rest_speed)
        head = np.angle(np.exp(1j * theta))
        inp = np.stack([vdot, omega], axis=-1)
        commands = RobotCommands.from_motion(times, spd, omega, vdot, IROBOT_CREATE)
    else:
        assert run.states is not None and limits is not None
        head, spd = np.angle(np.exp(1j * run.states[..., 2])), run.states[..., 3].copy()
        ex = run.extras
        inp = np.stack([ex["dv_dt"], ex["omega"]], axis=-1)
        commands = RobotCommands.from_motion(
            times, spd, ex["omega"], ex["dv_dt"], limits,
            ideal_turn_rate=ex["ideal_omega"], ideal_acceleration=ex["ideal_dv_dt"], limited=True,
            speed_held=ex["speed_held"] > 0.5,
        )  # fmt: skip
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
        times=times, positions=pos, velocities=vel, headings=head, speeds=spd, inputs=inp,
        desired=desired, model=model, P=P, D=D, tau1=tau1, tau2=tau2, dt=dt,
        stated_order=2 if limits is not None or report is not None or robot.actuation_delay > 0.0
        else stated_order(tau1, tau2, dt),
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
    """The paper's six robots (Fig. topol, P = 1, D = 0.5) into a hexagon at points a and b.

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
    topo = paper_six()
    shape = named_formation("hexagon", topo.n, spacing=spacing)
    runs = tuple(
        simulate(topo, 1.0, 0.5, t1, t2, shape, seed=seed, duration=duration, dt=dt, limits=limits)
        for t1, t2 in ((0.3, 0.2), (2.0, 1.0))
    )
    return runs[0], runs[1]

