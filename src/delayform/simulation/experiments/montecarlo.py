"""Monte Carlo runs of the formation over an imperfect network.

:func:`monte_carlo` simulates the same team N times, each run with its own
random initial state (unless explicit initial positions are given) and its
own draw of the network's randomness (jitter, losses, noise, drawn delays),
and returns the distribution of what a user checks: settling time, final
formation error and peak commands, plus the formation error over time.

Reproducibility
---------------
Run r's seeds are child r of ``numpy.random.SeedSequence(seed).spawn(runs)``:
each run is a pure function of (setup, run index, seed), so the numbers do
not depend on the order in which runs finish, nor on where they run (this
process, a local Dask cluster, a remote one: :mod:`delayform.simulation.experiments.sweeps`).

Executors
---------
The runs are handed to an *executor* (:class:`~delayform.simulation.runs.options.Executor`:
``map(fn, tasks, progress=None) -> list`` returning the results in the order
of ``tasks``; :class:`SerialExecutor` here, Dask ones in :mod:`delayform.simulation.experiments.sweeps`),
given in :class:`~delayform.simulation.runs.options.RunOptions`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.resources import require
from delayform.formation import check_formation
from delayform.model import MODELS, REST_SPEED, Delays, Network, Robot, Team
from delayform.model.start import Start
from delayform.simulation.runs.compat import MONTE_CARLO_KEYWORDS, accepts_loose_calls
from delayform.simulation.runs.options import Executor, Progress, RunOptions, SerialExecutor
from delayform.simulation.delayed.reception import network_memory
from delayform.simulation.runs.runner import simulate
from delayform.topology import Topology

__all__ = [
    "Setup",
    "RunOutcome",
    "MonteCarloResult",
    "Executor",
    "SerialExecutor",
    "run_seeds",
    "make_setup",
    "checked",
    "simulate_run",
    "monte_carlo",
    "collect",
    "estimate_cost",
    "run_quantile",
]

_Array = NDArray[np.float64]

@validated(SimulationInputError)
def run_quantile(values: ArrayLike, q: ArrayLike) -> _Array:
    """Quantiles of run metrics where a run that never settled counts as +inf.

    The definition is the usual one, linear interpolation between order
    statistics (Hyndman and Fan's type 7, numpy's default ``"linear"``, the
    ``"inclusive"`` method of Python's :mod:`statistics`): with the sorted
    values ``v_0 <= ... <= v_{n-1}`` and ``h = (n - 1) q``,
    ``Q(q) = v_floor(h) + (h - floor(h)) (v_ceil(h) - v_floor(h))``. So
    ``q = 0.5`` is the ordinary median, the mean of the two middle values for
    an even number of runs. An interpolation towards +inf is +inf (half the
    runs settled at 10 s and half never: the median run never settles), and
    exactly on an order statistic the value is that statistic.

    Parameters
    ----------
    values
        One value per run (finite or +inf), at least one.
    q
        Probabilities in [0, 1] (scalar or array).

    Returns
    -------
    ndarray
        One quantile per probability, in the shape of ``q``.

    >>> float(run_quantile([4.0, 1.0, 3.0, 2.0], 0.5))
    2.5
    >>> float(run_quantile([1.0, 2.0, np.inf, np.inf], 0.5))
    inf
    """
    try:
        v = np.sort(np.asarray(values, dtype=np.float64).ravel())
        p = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimulationInputError("quantile: values and probabilities must be numbers") from None
    if v.size == 0 or np.any(np.isnan(v)) or np.any((p < 0.0) | (p > 1.0) | np.isnan(p)):
        raise SimulationInputError("quantile: needs at least one value (no NaN) and probabilities in [0, 1]")
    h = (v.size - 1) * p
    lo = np.floor(h).astype(np.intp)
    hi = np.minimum(lo + 1, v.size - 1)
    frac = h - lo
    a, b = v[lo], v[hi]
    with np.errstate(invalid="ignore"):  # inf - inf where both are inf: handled by the where
        linear = a + frac * (b - a)
    return np.where(frac == 0.0, a, np.where(np.isinf(b), np.inf, linear))


#: points of the formation error kept per run for the quantile bands
ERROR_SAMPLES = 301

#: measured cost of one RK4 step of the network integrator (s): a fixed part and one per link
_STEP_SECONDS = (2.0e-4, 2.0e-6)

#: extra cost of one step for robots with actuator limits (s): the saturated unicycle's
#: right-hand side; measured 300 against 95 microseconds per step for six robots (2026-12-01)
_LIMITED_STEP_SECONDS = 2.5e-4


# ------------------------------------------------------------------ inputs
@dataclass(frozen=True, eq=False)
class Setup:
    """Everything one run needs except its seeds: the scenario-like inputs of :func:`monte_carlo`.

    Attributes
    ----------
    topology, P, D, tau1, tau2
        Team, gains and nominal delays of the paper's eq. 1.
    formation
        ``(n, 2)`` desired positions.
    model
        ``"double_integrator"``, ``"unicycle"`` or ``"physics"`` (:data:`~delayform.model.MODELS`).
    network
        The imperfect network, or None for the ideal one.
    duration, dt
        Length of each run and step (s).
    initial_positions, initial_headings
        Fixed initial state, or None to draw it per run.
    initial_speed
        Initial speed of every agent (the paper's 1e-3).
    limits
        Actuator limits of the robots (:class:`~delayform.simulation.models.robots.RobotLimits`),
        or None for ideal ones: the saturated unicycle driven by what each robot hears.
    radius
        Body radius (m) for contacts; None: the default of
        :class:`~delayform.simulation.models.robots.Robot` (0 for double integrators).
    assignment
        Which robot takes which slot, per run (``simulate(..., assignment=...)``).
    safety
        The safety filter of every run (``"barrier"``), or None.
    actuation_delay
        tau_a (s) of every run: each robot applies its command that late.
    rest_speed
        Speed below which ideal robots hold their heading (``Robot.rest_speed``).
    save_every
        Saving stride of every run (``RunOptions.save_every``); None: simulate's default.
    chassis
        For ``model="physics"``: the robots' mass, tyres and servos
        (:class:`~delayform.model.Chassis`); None: the Create's.
    """

    topology: Topology
    P: float
    D: float
    tau1: float
    tau2: float
    formation: _Array
    model: str = "double_integrator"
    network: Network | None = None
    duration: float = 60.0
    dt: float = 0.01
    initial_positions: _Array | None = None
    initial_headings: _Array | None = None
    initial_speed: float = 1e-3
    limits: Any = None
    radius: float | None = None
    assignment: str = "given"
    safety: Any = None
    actuation_delay: float = 0.0
    rest_speed: float = REST_SPEED
    save_every: int | None = None
    chassis: Any = None

    @property
    def robot(self) -> Robot:
        """The robot of every run (model, limits, body radius, safety filter, actuation delay, chassis)."""
        return Robot(model=self.model, limits=self.limits, radius=self.radius, safety=self.safety,
                     actuation_delay=self.actuation_delay, rest_speed=self.rest_speed,
                     chassis=self.chassis)  # fmt: skip

    def with_changes(self, **changes: Any) -> Setup:
        """A copy with some fields replaced (sweeps).

        Parameters
        ----------
        **changes
            Field names and new values.
        """
        return replace(self, **changes)

    def describe(self) -> dict[str, Any]:
        """JSON-ready description for summaries."""
        return {
            "topology": self.topology.name, "agents": self.topology.n, "P": self.P, "D": self.D,
            "tau1": self.tau1, "tau2": self.tau2, "model": self.model,
            "network": "ideal" if self.network is None else self.network.describe(self.topology.adjacency),
            "robots": "ideal" if self.limits is None else self.limits.describe(),
            "radius": self.robot.body_radius,
            "safety": "none" if self.safety is None else "barrier",
            "actuation_delay": self.actuation_delay,
            "duration": self.duration, "dt": self.dt,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class RunOutcome:
    """The metrics of one run (what a worker sends back: small)."""

    index: int
    settling_time: float
    final_error: float
    initial_error: float
    peak_commands: tuple[float, float]
    error_times: _Array
    errors: _Array
    status: str = "settled"
    min_distance: float = math.inf
    contacts: int = 0


def run_seeds(seed: int, runs: int) -> list[tuple[int, int]]:
    """(initial-state seed, network seed) of each run, from ``SeedSequence(seed).spawn(runs)``.

    Parameters
    ----------
    seed
        Non-negative integer seed of the whole Monte Carlo.
    runs
        Number of runs.

    >>> run_seeds(1, 2) == run_seeds(1, 3)[:2]
    True
    """
    children = np.random.SeedSequence(seed).spawn(runs)
    return [tuple(int(v) for v in child.generate_state(2)) for child in children]  # type: ignore[misc]


def simulate_run(task: tuple[Setup, int, tuple[int, int]]) -> RunOutcome:
    """One Monte Carlo run: ``(setup, run index, (initial seed, network seed))`` -> metrics.

    A module-level function of picklable arguments, so Dask workers can run it.

    Parameters
    ----------
    task
        The setup, the run's index and its two seeds (:func:`run_seeds`).
    """
    setup, index, (initial_seed, network_seed) = task
    network = None if setup.network is None else setup.network.with_seed(network_seed)
    traj = simulate(
        Team(setup.topology, setup.P, setup.D), Delays(setup.tau1, setup.tau2), setup.formation,
        robot=setup.robot, network=network,
        start=Start(setup.initial_positions, setup.initial_headings, setup.initial_speed, initial_seed),
        duration=setup.duration, dt=setup.dt, options=RunOptions(setup.save_every, setup.assignment),
    )  # fmt: skip
    if setup.model != "double_integrator":  # robots: |dv/dt| and |omega|
        peaks = (float(np.abs(traj.inputs[..., 0]).max()), float(np.abs(traj.inputs[..., 1]).max()))
    else:
        peaks = (float(np.hypot(traj.inputs[..., 0], traj.inputs[..., 1]).max()), 0.0)
    keep = np.unique(np.round(np.linspace(0, traj.times.size - 1, min(ERROR_SAMPLES, traj.times.size))).astype(int))
    return RunOutcome(
        index=index,
        settling_time=float(traj.settling_time),
        final_error=float(traj.formation_error[-1]),
        initial_error=float(traj.formation_error[0]),
        peak_commands=peaks,
        error_times=traj.times[keep],
        errors=traj.formation_error[keep],
        status=traj.status,
        min_distance=float(traj.min_distance),
        contacts=len(traj.contacts),
    )


# ------------------------------------------------------------------ result
_METRICS = ("settling_time", "final_error", "peak_command_1", "peak_command_2", "min_distance")


@validated()
@dataclass(frozen=True, eq=False)
class MonteCarloResult(FigureRepr):
    """Distribution of the outcome of a formation over N seeded runs.

    Attributes
    ----------
    setup
        What was simulated.
    runs, seed
        Number of runs and the seed of :func:`run_seeds`.
    times
        ``(S,)`` times of the formation-error samples.
    errors
        ``(runs, S)`` formation error of each run (RMS distance from the
        shape after removing the common offset).
    settling_times
        ``(runs,)`` 2 % settling times (``inf`` for a run that did not settle).
    final_errors, initial_errors
        ``(runs,)`` formation error at the end and at the start.
    peak_commands
        ``(runs, 2)`` largest command over time and agents:
        ``(|u|, 0)`` for double integrators, ``(|dv/dt|, |omega|)`` for unicycles.
    command_names
        Names of the two columns of ``peak_commands``.
    statuses
        ``(runs,)`` status of each run (:data:`delayform.simulation.STATUSES`:
        settled, not settled, diverging, stopped).
    min_distances
        ``(runs,)`` closest approach of two robots in each run (m, exact
        between saved steps: :func:`~delayform.simulation.bodies.approach.closest_approach`).
    contact_counts
        ``(runs,)`` number of contacts (bodies closer than two radii) in each run.
    """

    setup: Setup
    runs: int
    seed: int
    times: _Array
    errors: _Array
    settling_times: _Array
    final_errors: _Array
    initial_errors: _Array
    peak_commands: _Array
    command_names: tuple[str, str] = field(default=("|u|", ""))
    statuses: tuple[str, ...] = ()
    min_distances: _Array = field(default_factory=lambda: np.zeros(0))
    contact_counts: NDArray[np.int_] = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def contact_probability(self) -> float:
        """Fraction of runs in which two robots' bodies touched (0 for point agents)."""
        return float(np.mean(self.contact_counts > 0)) if self.contact_counts.size else 0.0

    @property
    def settled_fraction(self) -> float:
        """Fraction of runs that settled within the duration."""
        return float(np.mean(np.isfinite(self.settling_times)))

    def quantiles(self, q: ArrayLike = (0.05, 0.5, 0.95)) -> _Array:
        """Quantiles of the formation error over time, ``(len(q), S)``.

        Parameters
        ----------
        q
            Probabilities in [0, 1].
        """
        return np.quantile(self.errors, np.asarray(q, dtype=np.float64), axis=0)

    def metric(self, name: str) -> _Array:
        """The per-run values of a metric: ``settling_time``, ``final_error``, ``peak_command_1`` or ``_2``.

        Parameters
        ----------
        name
            One of the four names.
        """
        values = {
            "settling_time": self.settling_times, "final_error": self.final_errors,
            "peak_command_1": self.peak_commands[:, 0], "peak_command_2": self.peak_commands[:, 1],
            "min_distance": self.min_distances,
        }  # fmt: skip
        if name not in values:
            raise SimulationInputError(f"unknown metric {name!r}; choose one of {', '.join(_METRICS)}")
        return values[name]

    def summary(self) -> dict[str, Any]:
        """JSON-ready statistics: per metric the median, 5 % and 95 % quantiles, mean, min and max.

        Quantiles as :func:`quantile` defines them (the ordinary median: the
        mean of the two middle runs for an even count); the settling time of
        runs that did not settle counts as infinite (reported as None in JSON).
        """
        out: dict[str, Any] = {"runs": self.runs, "seed": self.seed, "settled_fraction": self.settled_fraction,
                               "setup": self.setup.describe(), "command_names": list(self.command_names),
                               "statuses": {k: self.statuses.count(k) for k in sorted(set(self.statuses))},
                               "contact_probability": self.contact_probability}  # fmt: skip
        for name in _METRICS:
            if name == "peak_command_2" and not self.command_names[1]:
                continue
            v = self.metric(name)
            finite = v[np.isfinite(v)]
            q05, q50, q95 = (float(x) for x in run_quantile(v, (0.05, 0.5, 0.95)))
            out[name] = {
                "median": q50, "q05": q05, "q95": q95,
                "mean": float(finite.mean()) if finite.size else math.inf,
                "min": float(v.min()), "max": float(v.max()),
            }  # fmt: skip
        return out

    def table(self) -> tuple[tuple[str, str], ...]:
        """Rows ``(quantity, "median [5 %, 95 %]")`` for reports and the command line."""

        def cell(stats: dict[str, float], unit: str) -> str:
            def one(v: float) -> str:
                return f"{v:.4g}{unit}" if np.isfinite(v) else "not settled"

            return f"{one(stats['median'])}  [{one(stats['q05'])}, {one(stats['q95'])}]"

        s = self.summary()
        rows = [
            ("runs (seed)", f"{self.runs} ({self.seed})"),
            ("network", s["setup"]["network"]),
            ("robots", s["setup"]["robots"]),
            ("settled within the duration", f"{100 * self.settled_fraction:.0f} %"),
            ("runs by status", ", ".join(f"{k}: {v}" for k, v in s["statuses"].items())),
            ("settling time: median [5 %, 95 %]", cell(s["settling_time"], " s")),
            ("final formation error", cell(s["final_error"], " m")),
            (f"peak {self.command_names[0]}", cell(s["peak_command_1"], "")),
            ("closest approach of two robots", cell(s["min_distance"], " m")),
        ]
        if s["setup"]["radius"] > 0:
            rows.append((f"runs with contacts (bodies {2 * s['setup']['radius']:g} m across)",
                         f"{100 * self.contact_probability:.0f} %"))  # fmt: skip
        if self.command_names[1]:
            rows.append((f"peak {self.command_names[1]}", cell(s["peak_command_2"], "")))
        return tuple(rows)

    def plot(self, ax: Any = None, *, q: Sequence[float] = (0.05, 0.25, 0.5, 0.75, 0.95)) -> Any:
        """Quantile bands of the formation error over time (log scale); returns the axes.

        Parameters
        ----------
        ax
            Axes to draw on; None makes a figure.
        q
            Symmetric quantiles: outer pairs become bands, the middle one a line.
        """
        from delayform.plots import plot_error_bands

        return plot_error_bands(self.times, self.quantiles(q), tuple(q), ax=ax, title=self.setup.describe()["network"])

    def plot_histograms(self, axes: Any = None) -> Any:
        """Histograms of settling time, final error, peak command and closest approach; returns the axes.

        Parameters
        ----------
        axes
            Four axes to draw on; None makes a figure.
        """
        from delayform.plots import plot_histograms

        panels = [
            ("settling time (s)", self.settling_times),
            ("final formation error (m)", self.final_errors),
            (f"peak {self.command_names[0]}", self.peak_commands[:, 0]),
            ("closest approach of two robots (m)", self.min_distances),
        ]
        return plot_histograms(panels, axes=axes)


# ------------------------------------------------------------------- runs
def estimate_cost(setup: Setup, runs: int) -> tuple[float, float]:
    """Rough (peak bytes of one run, seconds of all runs in one process).

    Parameters
    ----------
    setup
        What one run simulates.
    runs
        Number of runs.
    """
    steps = math.ceil(setup.duration / setup.dt - 1e-9)
    n = setup.topology.n
    links = int(setup.topology.adjacency_sparse.nnz)
    packets = 0
    if setup.network is not None and setup.network.packets:
        period = setup.dt if setup.network.sampling is None else 1.0 / setup.network.sampling.rate
        packets = int(setup.duration / period) + 2
    nbytes = network_memory(links, steps, packets, n) + (steps + 1) * n * 8 * 8
    per_step = _STEP_SECONDS[0] + _STEP_SECONDS[1] * links + (_LIMITED_STEP_SECONDS if setup.limits is not None else 0.0)
    # the safety filter: about 4 x 50 microseconds per step for a small team (docs/benchmarks.md)
    per_step += 2e-4 + 2e-6 * n if setup.safety is not None else 0.0
    seconds = runs * steps * per_step
    if setup.model == "physics":  # the engine's time, on the robot's control ticks
        from delayform.simulation.physics.engine import physics_resources, tick_grid

        period, substeps = tick_grid(setup.robot.chassis)
        extra_bytes, one = physics_resources(n, math.ceil(setup.duration / period - 1e-9), substeps)
        nbytes, seconds = nbytes + extra_bytes, runs * one
    return nbytes, seconds


def guard(setup: Setup, runs: int, workers: int = 1) -> None:
    """Refuse, in one line, a Monte Carlo beyond this machine's memory or time budget (:mod:`delayform.resources`).

    Parameters
    ----------
    setup
        What one run simulates.
    runs
        Number of runs.
    workers
        Runs in parallel: memory is needed for that many at once, time is shared among them.
    """
    nbytes, seconds = estimate_cost(setup, runs)
    at_once = max(1, min(workers, runs))
    require(what=f"a Monte Carlo of {runs} runs", setting="the runs, the duration or dt (or add workers)",
            nbytes=nbytes * at_once, seconds=seconds / max(workers, 1))  # fmt: skip


@validated()
def make_setup(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    formation: ArrayLike | str,
    *,
    model: str = "double_integrator",
    network: Network | None = None,
    duration: float,
    dt: float,
    initial_positions: ArrayLike | None = None,
    initial_headings: ArrayLike | None = None,
    initial_speed: float = 1e-3,
    limits: Any = None,
    radius: float | None = None,
    assignment: str = "given",
    safety: Any = None,
    actuation_delay: float = 0.0,
    chassis: Any = None,
) -> Setup:
    """The checked scenario-like inputs of a Monte Carlo or of a sweep's base point.

    Parameters
    ----------
    topology, P, D, tau1, tau2, formation
        Team, gains of the paper's eq. 1, nominal delays, desired shape (array or name).
    model
        ``"double_integrator"`` or ``"unicycle"``.
    network
        Imperfect network, or None for the ideal one.
    duration, dt
        Length of each run and step (s).
    initial_positions, initial_headings
        Fixed initial state, or None to draw it per run.
    initial_speed
        Initial speed (the paper's 1e-3).
    limits
        Actuator limits of the robots, or None for ideal ones.
    radius
        Body radius (m) for contacts; None: the :class:`~delayform.simulation.models.robots.Robot` default.
    assignment
        ``"given"`` or ``"optimal"`` slots (``simulate(..., assignment=...)``).
    safety
        The safety filter (``"barrier"``) or None.
    actuation_delay
        tau_a >= 0 (s) of every run (``Robot.actuation_delay``).
    chassis
        For ``model="physics"``: mass, tyres and servos (``Robot.chassis``).

    Raises
    ------
    SimulationInputError, NetworkError, GainError, DelayError, FormationError
        The errors :func:`~delayform.simulation.simulate` raises for these inputs.
    """
    if not isinstance(topology, Topology):
        raise SimulationInputError(f"topology must be a Topology, got {type(topology).__name__}")
    setup = Setup(
        topology=topology, P=P, D=D, tau1=tau1, tau2=tau2, formation=check_formation(formation, topology.n),
        model=model, network=network, duration=duration, dt=dt,
        initial_positions=None if initial_positions is None else np.asarray(initial_positions, dtype=np.float64),
        initial_headings=None if initial_headings is None else np.asarray(initial_headings, dtype=np.float64),
        initial_speed=initial_speed, limits=limits, radius=radius, assignment=assignment, safety=safety,
        actuation_delay=actuation_delay, chassis=chassis,
    )  # fmt: skip
    return checked(setup)


def checked(setup: Setup) -> Setup:
    """``setup`` after one two-step run, which raises simulate's own error for any bad input.

    Parameters
    ----------
    setup
        The inputs to check.
    """
    if setup.model not in MODELS:
        raise SimulationInputError(f"unknown model {setup.model!r}; choose one of {', '.join(MODELS)}")
    if setup.network is not None and not isinstance(setup.network, Network):
        raise SimulationInputError(f"network must be a Network, got {type(setup.network).__name__}")
    check_formation(setup.formation, setup.topology.n)
    simulate_run((replace(setup, duration=2 * setup.dt), 0, (0, 0)))
    return setup


def _check_runs(runs: object, seed: object) -> tuple[int, int]:
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise SimulationInputError(f"runs must be a positive integer, got {runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SimulationInputError(f"seed must be a non-negative integer (the Monte Carlo's, in start), got {seed!r}")
    return int(runs), int(seed)


def collect(setup: Setup, runs: int, seed: int, outcomes: Sequence[RunOutcome]) -> MonteCarloResult:
    """Assemble the result from the run outcomes (in any order; sorted by run index).

    Parameters
    ----------
    setup
        What was simulated.
    runs, seed
        As given to :func:`monte_carlo`.
    outcomes
        One :class:`RunOutcome` per run.
    """
    ordered = sorted(outcomes, key=lambda o: o.index)
    names = ("|dv/dt|", "|omega|") if setup.model != "double_integrator" else ("|u|", "")
    return MonteCarloResult(
        setup=setup, runs=runs, seed=seed,
        times=ordered[0].error_times,
        errors=np.array([o.errors for o in ordered]),
        settling_times=np.array([o.settling_time for o in ordered]),
        final_errors=np.array([o.final_error for o in ordered]),
        initial_errors=np.array([o.initial_error for o in ordered]),
        peak_commands=np.array([o.peak_commands for o in ordered]),
        command_names=names,
        statuses=tuple(o.status for o in ordered),
        min_distances=np.array([o.min_distance for o in ordered]),
        contact_counts=np.array([o.contacts for o in ordered], dtype=int),
    )  # fmt: skip


@accepts_loose_calls(MONTE_CARLO_KEYWORDS, default_model="double_integrator")
@validated(SimulationInputError)
def monte_carlo(
    team: Team,
    delays: Delays,
    formation: ArrayLike | str,
    *,
    robot: Robot | None = None,
    network: Network | None = None,
    start: Start | None = None,
    duration: float,
    dt: float,
    runs: int,
    options: RunOptions | None = None,
) -> MonteCarloResult:
    """N seeded runs of the paper's eq. 13 over ``network``: distributions of settling, error and commands.

    Parameters
    ----------
    team, delays, formation, robot, network, duration, dt, options
        As for :func:`~delayform.simulation.simulate`, with the same
        defaults; the network's seed is replaced per run, and
        ``options.executor`` says where the runs go (:class:`SerialExecutor`
        by default; :func:`delayform.simulation.experiments.sweeps.executor` for Dask; its
        ``workers`` attribute, if any, enters the memory and time guard),
        ``options.progress`` is called with ``(runs done, runs)``.
    start
        As for :func:`~delayform.simulation.simulate`; what it does not give
        is drawn per run, and its ``seed`` (a non-negative integer) seeds
        everything random (:func:`run_seeds`).
    runs
        Number of runs, positive.

    Returns
    -------
    MonteCarloResult

    Raises
    ------
    SimulationInputError, NetworkError, GainError, DelayError, FormationError
        Bad inputs (checked once, before any run).
    ResourceLimitError
        A Monte Carlo beyond this machine's memory or time budget (:mod:`delayform.resources`).

    Notes
    -----
    The loose form of earlier versions, ``monte_carlo(topology, P, D, tau1,
    tau2, formation, model=..., runs=..., seed=..., executor=..., ...)``, is
    still taken (:data:`~delayform.simulation.runs.compat.MONTE_CARLO_KEYWORDS`);
    its agent model was ``"double_integrator"`` unless named, and stays so.

    Examples
    --------
    >>> from delayform.model import BernoulliLoss, Delays, Network, Start, Team
    >>> from delayform.topology import ring
    >>> mc = monte_carlo(Team(ring(3), 1.0, 0.5), Delays(0.3, 0.2), "polygon", network=Network(loss=BernoulliLoss(0.2)),
    ...                  start=Start(seed=1), runs=3, duration=5.0, dt=0.05)
    >>> mc.errors.shape[0], mc.settling_times.shape
    (3, (3,))
    """
    robot = Robot() if robot is None else robot
    start = Start() if start is None else start
    options = RunOptions() if options is None else options
    runs, seed = _check_runs(runs, start.seed)
    tau1, tau2 = delays.pair if delays.kind == "uniform" else (delays.tau1, delays.tau2)  # simulate refuses per-link
    actuation = delays.actuation or robot.actuation_delay
    if delays.actuation and robot.actuation_delay and delays.actuation != robot.actuation_delay:
        raise SimulationInputError("two actuation delays, in the delays and in the robot: give it in one place")
    setup = checked(Setup(
        topology=team.topology, P=team.P, D=team.D, tau1=tau1, tau2=tau2,  # type: ignore[arg-type]
        formation=check_formation(formation, team.n), model=robot.model, network=network, duration=duration, dt=dt,
        initial_positions=None if start.positions is None else np.asarray(start.positions),
        initial_headings=None if start.headings is None else np.asarray(start.headings),
        initial_speed=start.speed, limits=robot.limits, radius=robot.radius,  # type: ignore[arg-type]
        assignment=options.assignment, safety=robot.safety, actuation_delay=actuation,
        rest_speed=robot.rest_speed, save_every=options.save_every, chassis=robot.chassis,
    ))  # fmt: skip
    guard(setup, runs, int(getattr(options.executor, "workers", 1)))
    tasks = [(setup, r, s) for r, s in enumerate(run_seeds(seed, runs))]
    outcomes = (options.executor or SerialExecutor()).map(simulate_run, tasks, options.progress)
    return collect(setup, runs, seed, outcomes)
