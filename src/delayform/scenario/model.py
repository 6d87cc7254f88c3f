"""The scenario: a team, its gains and delays, and what to compute (frozen dataclasses); the paper's example."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from delayform._validation import validated
from delayform.errors import ScenarioError
from delayform.scenario._reader import _check_sizes, _Reader
from delayform.model.network import (
    LinkDelays,
    Network,
)
from delayform.simulation.models.robots import Robot, RobotLimits
from delayform.topology import Topology

TOPOLOGY_NAMES = ("paper_six", "ring", "complete", "star", "random_digraph")
MODELS = ("unicycle", "double_integrator", "physics")

#: The paper's example (Section "Simulation Examples"): the six robots of
#: the paper's Fig. 2, P = 1, D = 0.5, point a, a hexagon, the chart window [0, 8]^2
#: with points a..e. ``delayform paper`` and examples/paper.toml use it.
PAPER_TOML = """\
name = "paper"
description = "Cepeda-Gomez and Perico: six robots of the paper's Fig. 2, P = 1, D = 0.5, point a, hexagon"

[topology]
name = "paper_six"

[gains]
P = 1.0
D = 0.5

[delays]
tau1 = 0.3
tau2 = 0.2

[formation]
shape = "hexagon"
spacing = 2.0

[simulation]
model = "unicycle"
duration = 150.0
dt = 0.01

[initial]
seed = 0
speed = 1e-3

[chart]
tau1_max = 8.0
tau2_max = 8.0
points = { a = [0.3, 0.2], b = [2.0, 1.0], c = [1.0, 2.0], d = [1.0, 5.5], e = [3.5, 2.0] }

[map]
tau1 = [0.0, 8.0]
tau2 = [0.0, 8.0]
size = [81, 81]

[schedule]
tau_min = [0.3, 0.2]
tau_max = [8.0, 8.0]
"""


# ---------------------------------------------------------------- the result
@dataclass(frozen=True)
class TopologySpec:
    """How the topology was given, kept for reports (the built one is ``Scenario.topology``)."""

    name: str | None = None
    n: int | None = None
    p: float | None = None
    seed: int | None = None
    adjacency: tuple[tuple[int, ...], ...] | None = None
    edges: tuple[tuple[int, int], ...] | None = None

    def describe(self) -> str:
        """One line for tables: the builder and its arguments."""
        if self.adjacency is not None:
            return f"adjacency matrix, {len(self.adjacency)} agents"
        if self.edges is not None:
            return f"edge list, {len(self.edges)} edges"
        args = [f"n={self.n}"] if self.n is not None and self.name != "paper_six" else []
        args += [f"p={self.p:g}"] if self.p is not None else []
        args += [f"seed={self.seed}"] if self.seed is not None else []
        return f"{self.name}({', '.join(args)})" if args else str(self.name)


@dataclass(frozen=True)
class FormationSpec:
    """The desired formation: a named shape (with its spacing) or explicit positions."""

    shape: str | None = None
    spacing: float = 1.0
    positions: tuple[tuple[float, float], ...] | None = None

    def describe(self) -> str:
        """One line for tables."""
        if self.positions is not None:
            return f"{len(self.positions)} explicit positions"
        return f"{self.shape} (spacing {self.spacing:g})"


@dataclass(frozen=True)
class SimulationSpec:
    """Agent model and integration grid of a simulation."""

    model: str = "unicycle"
    duration: float = 100.0
    dt: float = 0.01
    #: whether the file gave the step; a default step follows the delays (:func:`default_step`)
    dt_given: bool = field(default=True, compare=False)
    #: which robot takes which slot (delayform.simulation.bodies.assignment.ASSIGNMENTS)
    assignment: str = "given"


#: the step used when the file gives none (s)
DEFAULT_STEP = 0.01


def default_step(tau1: float, tau2: float) -> float:
    """The default step: 0.01 s, or the shortest non-zero delay when that is shorter.

    The simulator reads delayed states on its grid, so a non-zero delay needs at
    least one step; a step the user did not give must not be what refuses a
    short delay the user did give.
    """
    return min([DEFAULT_STEP] + [t for t in (tau1, tau2) if t > 0.0])


@dataclass(frozen=True)
class InitialSpec:
    """Initial conditions: random from ``seed`` unless positions / headings are given."""

    seed: int = 0
    speed: float = 1e-3
    positions: tuple[tuple[float, float], ...] | None = None
    headings: tuple[float, ...] | None = None


@dataclass(frozen=True)
class ChartSpec:
    """The CTCR window [0, tau1_max] x [0, tau2_max] and labelled points to mark."""

    tau1_max: float = 8.0
    tau2_max: float = 8.0
    points: tuple[tuple[str, float, float], ...] = ()


@dataclass(frozen=True)
class MapSpec:
    """A rectangular grid of delay pairs for the dominant-root map."""

    tau1: tuple[float, float] = (0.0, 8.0)
    tau2: tuple[float, float] = (0.0, 8.0)
    size: tuple[int, int] = (81, 81)

    def tau1_values(self) -> np.ndarray:
        """The grid along tau1."""
        return np.linspace(self.tau1[0], self.tau1[1], self.size[0])

    def tau2_values(self) -> np.ndarray:
        """The grid along tau2."""
        return np.linspace(self.tau2[0], self.tau2[1], self.size[1])


@dataclass(frozen=True)
class ScheduleSpec:
    """Bounds of delay scheduling: delays may only grow from ``tau_min`` up to ``tau_max``."""

    tau_min: tuple[float, float]
    tau_max: tuple[float, float]

    def starting_at(self, tau_min: tuple[float, float]) -> ScheduleSpec:
        """The bounds from new hardware delays, the upper bound following them.

        The box keeps its size when the new lower bound moves past the old
        upper one (``schedule --tau-min 9,9`` on the paper's [0.3, 8] x [0.2, 8]
        searches [9, 16.7] x [9, 16.8]); it never shrinks below the old upper bound.
        """
        hi = tuple(max(old_hi, lo + (old_hi - old_lo))
                   for lo, old_lo, old_hi in zip(tau_min, self.tau_min, self.tau_max, strict=True))  # fmt: skip
        return ScheduleSpec(tau_min=tau_min, tau_max=(hi[0], hi[1]))


def _without_matrices(net: Network, *, tau1: bool, tau2: bool) -> Network | None:
    """``net`` without its per-link delay matrix of the named streams (None when nothing else is left).

    What a single delay on every link replaces: ``--tau1`` on the command line,
    or a matrix equal on every link said as one number.
    """
    d = net.delays
    if d is None:
        return net
    kept = LinkDelays(tau1=None if tau1 else d.tau1, tau2=None if tau2 else d.tau2, spread=d.spread)
    out = replace(net, delays=None if kept.is_uniform else kept)
    return None if out.is_ideal else out


@validated(ScenarioError, methods=False)  # with_changes checks overrides like the file, naming its keys
@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated scenario: everything a ``delayform`` subcommand needs.

    Attributes
    ----------
    name, description
        For titles and reports.
    topology
        The built communication topology.
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        The operating delays (seconds).
    formation, simulation, initial, chart, map, schedule
        The optional tables, with their defaults filled in.
    robot
        Actuator limits of the robots (the ``[robot]`` table), or None for ideal robots.
    robot_profile
        Name of the real robot the ``[robot]`` table starts from (``profile = "NAME"``,
        :data:`delayform.deploy.PROFILES`), or None.
    radius
        ``[robot] radius`` (m), the bodies' size for contacts, or None for the
        default of :class:`~delayform.simulation.models.robots.Robot`.
    safety
        ``[robot] safety``: the safety filter's name (``"barrier"``), or None.
    actuation_delay
        ``[robot] actuation_delay`` (s, default 0): each robot applies its
        command that late (:attr:`~delayform.simulation.models.robots.Robot.actuation_delay`);
        the simulation and the dominant roots use it.
    network
        The ``[network]`` table as a :class:`~delayform.model.network.Network`, or None.
    topology_spec
        How the topology was described in the file.
    source
        The file it came from (or ``"<paper>"`` for the embedded default).
    """

    name: str
    description: str
    topology: Topology
    P: float
    D: float
    tau1: float
    tau2: float
    formation: FormationSpec
    simulation: SimulationSpec
    initial: InitialSpec
    chart: ChartSpec
    map: MapSpec
    schedule: ScheduleSpec
    topology_spec: TopologySpec = field(default_factory=TopologySpec)
    source: str = "<scenario>"
    robot: RobotLimits | None = None
    network: Network | None = None
    robot_profile: str | None = None
    radius: float | None = None
    safety: str | None = None
    actuation_delay: float = 0.0

    @property
    def link_delays(self) -> tuple[float | np.ndarray, float | np.ndarray]:
        """(tau1, tau2) as every link sees them: ``[network] tau1 / tau2`` matrices where given, else ``[delays]``.

        A matrix entry ``[i, k]`` is what agent i hears from k (entries off
        the links are ignored by the analyses). ``[network] delay_spread``
        draws other delays per run: :attr:`link_spread` says so.
        """
        d = self.network.delays if self.network is not None else None
        t1 = self.tau1 if d is None or d.tau1 is None else np.asarray(d.tau1, dtype=np.float64)
        t2 = self.tau2 if d is None or d.tau2 is None else np.asarray(d.tau2, dtype=np.float64)
        return t1, t2

    @property
    def link_spread(self) -> float:
        """``[network] delay_spread`` of the streams without a delay matrix (0: every run has the same delays)."""
        d = self.network.delays if self.network is not None else None
        return 0.0 if d is None or (d.tau1 is not None and d.tau2 is not None) else float(d.spread)

    def link_values(self, matrix: np.ndarray, name: str) -> np.ndarray:
        """The entries of a per-link ``(n, n)`` matrix on the team's links (``[i, k]``: what i hears from k).

        Raises
        ------
        ScenarioError
            When the matrix is not n x n for this team (e.g. after ``--topology``).
        """
        n = self.topology.n
        if np.shape(matrix) != (n, n):
            raise ScenarioError(f"{self.source}: network.{name} is {np.shape(matrix)[0]} x {np.shape(matrix)[-1]}, "
                                f"the team has {n} agents: one entry per pair of agents")  # fmt: skip
        rows, cols = self.topology.adjacency_sparse.nonzero()
        keep = rows != cols  # no agent hears itself over the network
        return np.asarray(matrix, dtype=np.float64)[rows[keep], cols[keep]]

    def per_link_description(self, *, spread: bool = True) -> str | None:
        """One phrase naming the per-link delays that differ between links, or None when every link has one pair.

        Parameters
        ----------
        spread
            Count ``[network] delay_spread`` (delays drawn per run) as delays
            that differ; False for a command that sets the delays itself (the
            spread is relative to them).
        """
        parts = []
        for name, t in zip(("tau1", "tau2"), self.link_delays, strict=True):
            if np.ndim(t):
                on = self.link_values(t, name)
                if on.size and np.ptp(on) > 0.0:
                    parts.append(f"network.{name} (per-link, {on.min():g} to {on.max():g} s)")
        if spread and self.link_spread:
            parts.append(f"network.delay_spread = {self.link_spread:g} (per-link delays drawn per run)")
        return ", ".join(parts) if parts else None

    def at_one_delay_pair(self, what: str, instead: str, *, spread: bool = True) -> Scenario:
        """The scenario as one delay pair on every link, for a command whose theory is the paper's eq. 3.

        ``[network] tau1 / tau2`` matrices with the same delay on every link of
        the team are that delay: it becomes ``tau1`` / ``tau2`` and the matrix
        leaves the network (the same system, said once). Matrices that differ
        between links (and ``delay_spread``, with ``spread``) are another
        system: refused rather than answered for ``[delays]``.

        Parameters
        ----------
        what
            The command or computation, for the message.
        instead
            The commands that do take per-link delays.
        spread
            Refuse ``[network] delay_spread`` too (default); False where the
            command sets the delays and the spread follows them (sweeps, the explorer).

        Raises
        ------
        ScenarioError
            One line naming the per-link keys, the ``[delays]`` that would
            otherwise be answered for, and ``instead``.
        """
        described = self.per_link_description(spread=spread)
        if described is not None:
            raise ScenarioError(
                f"the scenario's [network] sets per-link delays, {described}; {what} takes one delay pair on every "
                f"link, and answering for [delays] ({self.tau1:g}, {self.tau2:g}) s would be another question: use {instead}"
            )
        return self.with_uniform_links_folded()

    def with_uniform_links_folded(self) -> Scenario:
        """The scenario with each per-link delay matrix equal on every link said as its one delay.

        The matrix's delay becomes ``tau1`` / ``tau2`` (as ``--tau1`` / ``--tau2``
        would say it: the matrix leaves the network and scheduling starts
        there); a matrix that differs between links is kept.
        """
        pair: dict[str, float] = {}
        for name, t in zip(("tau1", "tau2"), self.link_delays, strict=True):
            on = self.link_values(t, name) if np.ndim(t) else None
            if on is not None and (not on.size or np.ptp(on) == 0.0):  # a team without links: [delays] stands
                pair[name] = float(on[0]) if on.size else getattr(self, name)
        return self.with_changes(**pair) if pair else self

    @property
    def robot_spec(self) -> Robot:
        """The ``[robot]`` table (and ``simulation.model``) as one :class:`~delayform.model.Robot` (with the profile's chassis for ``"physics"``)."""
        model = self.simulation.model
        limits = self.robot if model != "double_integrator" else None  # limits apply to robots only
        chassis = None
        if model == "physics" and self.robot_profile is not None:  # the profile's mass, tyres and servos
            from delayform.model.profiles import robot_profile

            chassis = robot_profile(self.robot_profile).physics_chassis()
        return Robot(model=model, limits=limits, radius=self.radius, safety=self.safety,
                     actuation_delay=self.actuation_delay, chassis=chassis)  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """The scenario as plain JSON-ready values, for summaries and report tables."""
        return {
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "topology": self.topology_spec.describe(),
            "agents": self.topology.n,
            "P": self.P,
            "D": self.D,
            "tau1": self.tau1,
            "tau2": self.tau2,
            "formation": self.formation.describe(),
            "model": self.simulation.model,
            "duration": self.simulation.duration,
            "dt": self.simulation.dt,
            "seed": self.initial.seed,
            "robot_limits": None if self.robot is None else self.robot.describe(),
            "robot_profile": self.robot_profile,
            "chart_window": [self.chart.tau1_max, self.chart.tau2_max],
            "map_grid": {"tau1": list(self.map.tau1), "tau2": list(self.map.tau2), "size": list(self.map.size)},
            "schedule": {"tau_min": list(self.schedule.tau_min), "tau_max": list(self.schedule.tau_max)},
            "network": "ideal" if self.network is None else self.network.describe(),
        }

    def with_changes(
        self,
        *,
        topology: Topology | None = None,
        P: float | None = None,
        D: float | None = None,
        tau1: float | None = None,
        tau2: float | None = None,
        formation: str | None = None,
    ) -> Scenario:
        """A copy with command-line overrides applied and checked like the file was.

        Parameters
        ----------
        topology
            A new topology (its size need not fit the formation: that is
            checked only when the formation is built, see
            :meth:`desired_positions`).
        P, D
            New gains of the paper's eq. 1.
        tau1, tau2
            New operating delays; delay scheduling then starts from them
            (``schedule.tau_min`` becomes the new delays, ``tau_max`` grows to
            contain them).
        formation
            A named shape replacing the formation (its spacing kept).

        Raises
        ------
        ScenarioError
            When an override is invalid.
        """
        reader = _Reader(self.source)
        new = replace(
            self,
            topology=self.topology if topology is None else topology,
            P=self.P if P is None else reader.gain("gains.P", P),
            D=self.D if D is None else reader.gain("gains.D", D),
            tau1=self.tau1 if tau1 is None else reader.non_negative("delays.tau1", tau1),
            tau2=self.tau2 if tau2 is None else reader.non_negative("delays.tau2", tau2),
        )
        if tau1 is not None or tau2 is not None:
            if new.network is not None:  # one delay on every link: it replaces that stream's per-link matrix
                new = replace(new, network=_without_matrices(new.network, tau1=tau1 is not None, tau2=tau2 is not None))
            # the hardware delays are the operating ones: schedule from what the user gave
            new = replace(new, schedule=new.schedule.starting_at((new.tau1, new.tau2)))
            if not new.simulation.dt_given:  # a default step follows the new delays too
                step = min(default_step(new.tau1, new.tau2), new.simulation.duration / 2)
                new = replace(new, simulation=replace(new.simulation, dt=step))
        if formation is not None:
            shape = reader.shape("formation.shape", formation)
            new = replace(new, formation=FormationSpec(shape=shape, spacing=self.formation.spacing))
        # the step is checked against overridden delays by simulate() itself, after a
        # command line has also overridden the step
        if topology is not None:
            new = replace(new, topology_spec=TopologySpec(name=topology.name))
        return new

    def desired_positions(self) -> np.ndarray:
        """The desired formation as an ``(n, 2)`` array (named shapes built for this team).

        Raises
        ------
        ScenarioError
            When the formation or the initial conditions do not fit the team
            (e.g. a hexagon for twelve agents after ``--topology ring --n 12``).
        """
        from delayform.formation import named_formation

        _check_sizes(_Reader(self.source), self.topology.n, self.formation, self.initial)
        if self.formation.positions is not None:
            return np.array(self.formation.positions, dtype=np.float64)
        return named_formation(self.formation.shape, self.topology.n, spacing=self.formation.spacing)

    def initial_positions(self) -> np.ndarray | None:
        """Explicit initial positions, or None for random ones drawn from ``initial.seed``."""
        if self.initial.positions is None:
            return None
        _check_sizes(_Reader(self.source), self.topology.n, self.formation, self.initial)
        return np.array(self.initial.positions, dtype=np.float64)

    def initial_headings(self) -> np.ndarray | None:
        """Explicit initial headings, or None for random ones drawn from ``initial.seed``."""
        if self.initial.headings is None:
            return None
        return np.array(self.initial.headings, dtype=np.float64)
