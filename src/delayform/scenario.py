"""Scenario files: one TOML file describes a team, its gains and delays, and what to compute.

A scenario is the input of every ``delayform`` subcommand. The schema (every
table and key; anything else is an error)::

    name = "paper"                      # optional, default: the file's stem
    description = "..."                 # optional

    [topology]                          # required; exactly one of name / adjacency / edges
    name = "ring"                       # paper_six | ring | complete | star | random_digraph
    n = 12                              # agents (named builders except paper_six; optional with edges)
    p = 0.05                            # random_digraph only: probability of each extra edge
    seed = 1                            # random_digraph only
    # adjacency = [[0, 1], [1, 0]]      # a_ik = 1 when agent i receives from agent k
    # edges = [[0, 1], [1, 0]]          # pairs (informer, receiver), agents 0..n-1

    [gains]                             # required
    P = 1.0
    D = 0.5

    [delays]                            # required: the operating point
    tau1 = 0.3                          # seconds, on positions
    tau2 = 0.2                          # seconds, on velocities

    [formation]                         # required; exactly one of shape / positions
    shape = "polygon"                   # a named shape of delayform.formation
    spacing = 2.0                       # optional: distance between neighbours in the shape
    # positions = [[x, y], ...]         # one desired position per agent

    [simulation]                        # optional
    model = "unicycle"                  # unicycle | double_integrator
    duration = 150.0                    # seconds
    dt = 0.01                           # seconds

    [robot]                             # optional: actuator limits; robots are ideal without it
    limits = true                       # false: ideal robots although the table is there
    max_speed = 0.5                     # m/s; every key defaults to delayform.simulation.IROBOT_CREATE
    max_turn_rate = 3.88                # rad/s
    max_acceleration = 0.5              # m/s^2
    max_wheel_speed = 13.9              # rad/s
    wheel_radius = 0.036                # m
    axle_length = 0.258                 # m

    [initial]                           # optional; random positions and headings from seed
    seed = 0
    speed = 1e-3                        # the paper's small initial speed (eq. transform2)
    # positions = [[x, y], ...]         # explicit initial positions, one per agent
    # headings = [...]                  # explicit initial headings (radians), one per agent

    [chart]                             # optional: the CTCR window and marked points
    tau1_max = 8.0
    tau2_max = 8.0
    points = { a = [0.3, 0.2] }         # label -> [tau1, tau2]

    [map]                               # optional: the dominant-root grid
    tau1 = [0.0, 8.0]                   # [first, last]
    tau2 = [0.0, 8.0]
    size = [81, 81]                     # grid points along tau1, tau2

    [schedule]                          # optional: delay scheduling bounds
    tau_min = [0.3, 0.2]                # what the hardware gives (defaults to [delays])
    tau_max = [8.0, 8.0]                # defaults to the chart window

    [network]                           # optional: an imperfect network (delayform.simulation.network)
    seed = 0                            # seed of everything random in the network
    delay_spread = 0.2                  # per-link delays drawn in tau (1 +- 0.2)
    # tau1 = [[...], ...]               # or per-link delay matrices, entry [i][k]: what i hears from k
    # tau2 = [[...], ...]
    jitter = [0.05, 0.05]               # bounds (s) of the random jitter on positions, velocities
    variation = { amplitude = [0.05, 0.05], period = 10.0 }   # smooth delay variation
    loss = 0.1                          # independent loss probability (or n x n, per link), or bursty:
    # loss = { p_good_to_bad = 0.05, p_bad_to_good = 0.3, loss_good = 0.0, loss_bad = 1.0 }
    rate = 20.0                         # sampled transmission: packets per second (zero-order hold)
    noise = [0.01, 0.01]                # measurement noise: std of position (m), velocity (m/s)

Validation happens on load: an unknown key, a value of the wrong type, a
missing field or sizes that do not agree raise :class:`ScenarioError` with
one line naming the file, the key and what was expected.

Examples
--------
>>> s = parse_scenario({"topology": {"name": "ring", "n": 4}, "gains": {"P": 1, "D": 0.5},
...                     "delays": {"tau1": 0.1, "tau2": 0.2}, "formation": {"shape": "line"}})
>>> s.topology.n, s.P, s.tau2, s.simulation.model
(4, 1.0, 0.2, 'unicycle')
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from delayform.errors import InputError, NetworkError, ScenarioError
from delayform.simulation.network import (
    BernoulliLoss,
    GilbertElliott,
    Jitter,
    LinkDelays,
    MeasurementNoise,
    Network,
    Sampling,
    SmoothVariation,
)
from delayform.simulation.robots import IROBOT_CREATE, RobotLimits
from delayform.topology import Topology, complete, paper_six, random_digraph, ring, star

__all__ = [
    "Scenario",
    "TopologySpec",
    "FormationSpec",
    "SimulationSpec",
    "InitialSpec",
    "ChartSpec",
    "MapSpec",
    "ScheduleSpec",
    "load_scenario",
    "parse_scenario",
    "parse_network_table",
    "paper_scenario",
    "PAPER_TOML",
    "TOPOLOGY_NAMES",
    "MODELS",
]

TOPOLOGY_NAMES = ("paper_six", "ring", "complete", "star", "random_digraph")
MODELS = ("unicycle", "double_integrator")

#: The paper's example (Section "Simulation Examples"): the six robots of
#: Fig. topol, P = 1, D = 0.5, point a, a hexagon, the chart window [0, 8]^2
#: with points a..e. ``delayform paper`` and examples/paper.toml use it.
PAPER_TOML = """\
name = "paper"
description = "Cepeda-Gomez and Perico: six robots of Fig. topol, P = 1, D = 0.5, point a, hexagon"

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
        Gains of eq. protocol.
    tau1, tau2
        The operating delays (seconds).
    formation, simulation, initial, chart, map, schedule
        The optional tables, with their defaults filled in.
    robot
        Actuator limits of the robots (the ``[robot]`` table), or None for ideal robots.
    network
        The ``[network]`` table as a :class:`~delayform.simulation.network.Network`, or None.
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
            New gains of eq. protocol.
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
            # the hardware delays are the operating ones: schedule from what the user gave
            lo = (new.tau1, new.tau2)
            hi = (max(new.schedule.tau_max[0], lo[0]), max(new.schedule.tau_max[1], lo[1]))
            new = replace(new, schedule=ScheduleSpec(tau_min=lo, tau_max=hi))
        if formation is not None:
            from delayform.formation import SHAPES

            shape = reader.string("formation.shape", formation, tuple(SHAPES))
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


# -------------------------------------------------------------- validation
class _Reader:
    """Typed access to parsed TOML that raises one-line ScenarioErrors naming file and key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, key: str, expected: str, got: object = ..., *, found: str | None = None) -> ScenarioError:
        """``<file>: <key>: expected <expected>, got <value>`` (``found`` is said as is)."""
        tail = f", got {found}" if found is not None else ("" if got is ... else f", got {_show(got)}")
        return ScenarioError(f"{self.source}: {key}: expected {expected}{tail}")

    def table(self, data: Mapping[str, Any], key: str, *, required: bool) -> Mapping[str, Any] | None:
        value = data.get(key.rsplit(".", 1)[-1])
        if value is None:
            if required:
                raise ScenarioError(f"{self.source}: [{key}]: missing required table")
            return None
        if not isinstance(value, Mapping):
            raise self.error(key, "a table", value)
        return value

    def keys(self, data: Mapping[str, Any], prefix: str, allowed: tuple[str, ...]) -> None:
        for key in data:
            if key not in allowed:
                where = f"{prefix}.{key}" if prefix else key
                raise ScenarioError(
                    f"{self.source}: {where}: unknown key (expected one of: {', '.join(allowed)})"
                )

    def string(self, key: str, value: object, choices: tuple[str, ...] | None = None) -> str:
        if not isinstance(value, str):
            raise self.error(key, "a string" if choices is None else f"one of {', '.join(choices)}", value)
        if choices is not None and value not in choices:
            raise self.error(key, f"one of {', '.join(choices)}", value)
        return value

    def integer(self, key: str, value: object, *, minimum: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, "an integer", value)
        if minimum is not None and value < minimum:
            raise self.error(key, f"an integer >= {minimum}", value)
        return value

    def number(self, key: str, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, "a number", value)
        out = float(value)
        if not math.isfinite(out):
            raise self.error(key, "a finite number", value)
        return out

    def gain(self, key: str, value: object) -> float:
        from delayform._validation import GAIN_RANGE

        out = self.number(key, value)
        if out <= 0.0:
            raise self.error(key, "a positive number (eq. protocol)", value)
        if not GAIN_RANGE[0] <= out <= GAIN_RANGE[1]:
            raise self.error(key, f"a gain between {GAIN_RANGE[0]:g} and {GAIN_RANGE[1]:g}", value)
        return out

    def positive(self, key: str, value: object) -> float:
        out = self.number(key, value)
        if out <= 0.0:
            raise self.error(key, "a positive number", value)
        return out

    def non_negative(self, key: str, value: object) -> float:
        out = self.number(key, value)
        if out < 0.0:
            raise self.error(key, "a non-negative number (seconds)", value)
        return out

    def pair(self, key: str, value: object, *, what: str = "number") -> tuple[float, float]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(key, f"an array of two {what}s", value)
        return (self.non_negative(f"{key}[0]", value[0]), self.non_negative(f"{key}[1]", value[1]))

    def points(self, key: str, value: object, n: int | None) -> tuple[tuple[float, float], ...]:
        if not isinstance(value, list) or not value:
            raise self.error(key, "a non-empty array of [x, y] pairs", value)
        out = []
        for i, row in enumerate(value):
            if not isinstance(row, list) or len(row) != 2:
                raise self.error(f"{key}[{i}]", "a pair [x, y]", row)
            out.append((self.number(f"{key}[{i}][0]", row[0]), self.number(f"{key}[{i}][1]", row[1])))
        if n is not None and len(out) != n:
            raise self.error(key, f"{n} rows, one per agent", found=f"{len(out)} rows")
        return tuple(out)


def _show(value: object) -> str:
    """A short rendering of a TOML value for an error message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _topology(reader: _Reader, data: Mapping[str, Any]) -> tuple[Topology, TopologySpec]:
    reader.keys(data, "topology", ("name", "n", "p", "seed", "adjacency", "edges"))
    given = [k for k in ("name", "adjacency", "edges") if k in data]
    if len(given) != 1:
        raise ScenarioError(
            f"{reader.source}: topology: expected exactly one of name, adjacency, edges"
            + (f", got {', '.join(given)}" if given else "")
        )
    kind = given[0]
    extra = {"adjacency": ("n", "p", "seed"), "edges": ("p", "seed")}.get(kind, ())
    for key in extra:
        if key in data:
            raise ScenarioError(f"{reader.source}: topology.{key}: not allowed with topology.{kind}")
    try:
        if kind == "adjacency":
            topo, spec = _adjacency(reader, data["adjacency"])
        elif kind == "edges":
            topo, spec = _edges(reader, data["edges"], data.get("n"))
        else:
            topo, spec = _named(reader, data)
        # Lemma 3: without a spanning tree no gains or delays give a formation.
        topo.require_spanning_tree()
        return topo, spec
    except ScenarioError:
        raise
    except InputError as exc:
        # The topology module names the problem; we add the file and the key.
        raise ScenarioError(f"{reader.source}: topology.{kind}: {exc}") from None


def _adjacency(reader: _Reader, value: object) -> tuple[Topology, TopologySpec]:
    key = "topology.adjacency"
    if not isinstance(value, list) or not value:
        raise reader.error(key, "a non-empty array of rows of 0/1", value)
    n = len(value)
    rows = []
    for i, row in enumerate(value):
        if not isinstance(row, list):
            raise reader.error(f"{key}[{i}]", "a row of 0/1", row)
        if len(row) != n:
            raise reader.error(f"{key}[{i}]", f"{n} entries (a square matrix)", found=f"{len(row)} entries")
        for k, entry in enumerate(row):
            if isinstance(entry, bool) or entry not in (0, 1):
                raise reader.error(f"{key}[{i}][{k}]", "0 or 1", entry)
        rows.append(tuple(int(e) for e in row))
    topo = Topology.from_adjacency(np.array(rows, dtype=np.float64), name="adjacency")
    return topo, TopologySpec(adjacency=tuple(rows))


def _edges(reader: _Reader, value: object, n_value: object) -> tuple[Topology, TopologySpec]:
    key = "topology.edges"
    if not isinstance(value, list) or not value:
        raise reader.error(key, "a non-empty array of [informer, receiver] pairs", value)
    edges = []
    for i, pair in enumerate(value):
        if not isinstance(pair, list) or len(pair) != 2:
            raise reader.error(f"{key}[{i}]", "a pair [informer, receiver]", pair)
        a = reader.integer(f"{key}[{i}][0]", pair[0], minimum=0)
        b = reader.integer(f"{key}[{i}][1]", pair[1], minimum=0)
        edges.append((a, b))
    n = None if n_value is None else reader.integer("topology.n", n_value, minimum=2)
    largest = max(max(e) for e in edges)
    if n is not None and largest >= n:
        raise reader.error(key, f"agent indices 0..{n - 1} (topology.n = {n})", largest)
    topo = Topology.from_edges(edges, n, name="edges")
    return topo, TopologySpec(n=topo.n, edges=tuple(edges))


def _named(reader: _Reader, data: Mapping[str, Any]) -> tuple[Topology, TopologySpec]:
    name = reader.string("topology.name", data["name"], TOPOLOGY_NAMES)
    allowed = {"paper_six": (), "random_digraph": ("n", "p", "seed")}.get(name, ("n",))
    for key in ("n", "p", "seed"):
        if key in data and key not in allowed:
            raise ScenarioError(f"{reader.source}: topology.{key}: not used by topology '{name}'")
    if name == "paper_six":
        return paper_six(), TopologySpec(name=name, n=6)
    if "n" not in data:
        raise ScenarioError(f"{reader.source}: topology.n: missing (topology '{name}' needs a size)")
    n = reader.integer("topology.n", data["n"], minimum=2)
    if name == "random_digraph":
        if "p" not in data:
            raise ScenarioError(f"{reader.source}: topology.p: missing (random_digraph needs a probability)")
        p = reader.number("topology.p", data["p"])
        if not 0.0 <= p <= 1.0:
            raise reader.error("topology.p", "a probability in [0, 1]", data["p"])
        seed = reader.integer("topology.seed", data.get("seed", 0), minimum=0)
        return random_digraph(n, p, seed=seed), TopologySpec(name=name, n=n, p=p, seed=seed)
    builder = {"ring": ring, "complete": complete, "star": star}[name]
    return builder(n), TopologySpec(name=name, n=n)


def _formation(reader: _Reader, data: Mapping[str, Any], n: int) -> FormationSpec:
    reader.keys(data, "formation", ("shape", "spacing", "positions"))
    if ("shape" in data) == ("positions" in data):
        raise ScenarioError(f"{reader.source}: formation: expected exactly one of shape, positions")
    if "positions" in data:
        if "spacing" in data:
            raise ScenarioError(f"{reader.source}: formation.spacing: only for a named shape")
        return FormationSpec(positions=reader.points("formation.positions", data["positions"], n))
    from delayform.formation import SHAPES, named_formation

    shape = reader.string("formation.shape", data["shape"], tuple(SHAPES))
    spacing = reader.positive("formation.spacing", data.get("spacing", 1.0))
    if spacing > 1e6:  # metres: beyond this the positions lose their precision in a simulation
        raise reader.error("formation.spacing", "a spacing of at most 1e6 (metres)", spacing)
    try:
        named_formation(shape, n, spacing=spacing)  # e.g. a hexagon needs six agents
    except InputError as exc:
        raise ScenarioError(f"{reader.source}: formation.shape: {exc}") from None
    return FormationSpec(shape=shape, spacing=spacing)


def _simulation(reader: _Reader, data: Mapping[str, Any]) -> SimulationSpec:
    reader.keys(data, "simulation", ("model", "duration", "dt"))
    default = SimulationSpec()
    model = reader.string("simulation.model", data.get("model", default.model), MODELS)
    duration = reader.positive("simulation.duration", data.get("duration", default.duration))
    dt = reader.positive("simulation.dt", data.get("dt", default.dt))
    if dt >= duration:
        raise reader.error("simulation.dt", f"a step smaller than simulation.duration = {duration:g}", dt)
    return SimulationSpec(model=model, duration=duration, dt=dt)


_ROBOT_KEYS = (
    "wheel_radius", "axle_length", "max_wheel_speed", "max_speed", "max_turn_rate", "max_acceleration",
    "slow_speed", "turn_time_constant",
)  # fmt: skip


def _robot(reader: _Reader, data: Mapping[str, Any] | None, model: str) -> RobotLimits | None:
    """The ``[robot]`` table: actuator limits, defaults from IROBOT_CREATE; None without the table."""
    if data is None:
        return None
    reader.keys(data, "robot", ("limits",) + _ROBOT_KEYS)
    enabled = data.get("limits", True)
    if not isinstance(enabled, bool):
        raise reader.error("robot.limits", "true or false", enabled)
    if not enabled:
        return None
    if model != "unicycle":
        raise reader.error("robot.limits", "false for simulation.model = 'double_integrator' (limits apply to robots)",
                           enabled)  # fmt: skip
    values = {key: reader.positive(f"robot.{key}", data[key]) for key in _ROBOT_KEYS if key in data}
    return replace(IROBOT_CREATE, **values)


def _initial(reader: _Reader, data: Mapping[str, Any], n: int) -> InitialSpec:
    reader.keys(data, "initial", ("seed", "speed", "positions", "headings"))
    seed = reader.integer("initial.seed", data.get("seed", 0), minimum=0)
    speed = reader.positive("initial.speed", data.get("speed", 1e-3))
    positions = None
    if "positions" in data:
        positions = reader.points("initial.positions", data["positions"], n)
    headings = None
    if "headings" in data:
        value = data["headings"]
        if not isinstance(value, list):
            raise reader.error("initial.headings", f"an array of {n} angles (radians)", value)
        if len(value) != n:
            raise reader.error("initial.headings", f"{n} angles, one per agent", found=f"{len(value)} angles")
        headings = tuple(reader.number(f"initial.headings[{i}]", h) for i, h in enumerate(value))
    return InitialSpec(seed=seed, speed=speed, positions=positions, headings=headings)


def _chart(reader: _Reader, data: Mapping[str, Any]) -> ChartSpec:
    reader.keys(data, "chart", ("tau1_max", "tau2_max", "points"))
    tau1_max = reader.positive("chart.tau1_max", data.get("tau1_max", 8.0))
    tau2_max = reader.positive("chart.tau2_max", data.get("tau2_max", 8.0))
    points_value = data.get("points", {})
    if not isinstance(points_value, Mapping):
        raise reader.error("chart.points", "a table label = [tau1, tau2]", points_value)
    points = tuple(
        (label, *reader.pair(f"chart.points.{label}", value)) for label, value in points_value.items()
    )
    for label, a, b in points:
        # NU is only known inside the window the curves were traced in
        if a > tau1_max or b > tau2_max:
            raise reader.error(f"chart.points.{label}", f"a delay pair inside the window [0, {tau1_max:g}] x [0, {tau2_max:g}]", [a, b])
    return ChartSpec(tau1_max=tau1_max, tau2_max=tau2_max, points=points)


def _map(reader: _Reader, data: Mapping[str, Any], chart: ChartSpec) -> MapSpec:
    reader.keys(data, "map", ("tau1", "tau2", "size"))
    tau1 = reader.pair("map.tau1", data.get("tau1", [0.0, chart.tau1_max]))
    tau2 = reader.pair("map.tau2", data.get("tau2", [0.0, chart.tau2_max]))
    for key, (lo, hi) in (("map.tau1", tau1), ("map.tau2", tau2)):
        if hi <= lo:
            raise reader.error(key, "[first, last] with first < last", [lo, hi])
    size_value = data.get("size", [81, 81])
    if not isinstance(size_value, list) or len(size_value) != 2:
        raise reader.error("map.size", "an array of two integers", size_value)
    size = (
        reader.integer("map.size[0]", size_value[0], minimum=2),
        reader.integer("map.size[1]", size_value[1], minimum=2),
    )
    return MapSpec(tau1=tau1, tau2=tau2, size=size)


def _schedule(
    reader: _Reader, data: Mapping[str, Any], tau: tuple[float, float], chart: ChartSpec
) -> ScheduleSpec:
    reader.keys(data, "schedule", ("tau_min", "tau_max"))
    tau_min = reader.pair("schedule.tau_min", data.get("tau_min", list(tau)))
    tau_max = reader.pair("schedule.tau_max", data.get("tau_max", [chart.tau1_max, chart.tau2_max]))
    if tau_max[0] < tau_min[0] or tau_max[1] < tau_min[1]:
        raise reader.error("schedule.tau_max", f"bounds >= schedule.tau_min = {list(tau_min)}", list(tau_max))
    return ScheduleSpec(tau_min=tau_min, tau_max=tau_max)


def _check_step(reader: _Reader, dt: float, tau1: float, tau2: float) -> None:
    """The simulator reads delayed states on its grid: a non-zero delay needs at least one step."""
    shortest = min((t for t in (tau1, tau2) if t > 0.0), default=None)
    if shortest is not None and dt > shortest:
        raise reader.error("simulation.dt", f"a step no longer than the shortest non-zero delay {shortest:g}", dt)


def _check_sizes(reader: _Reader, n: int, formation: FormationSpec, initial: InitialSpec) -> None:
    if formation.shape is not None:
        from delayform.formation import named_formation

        try:
            named_formation(formation.shape, n, spacing=formation.spacing)
        except InputError as exc:
            raise ScenarioError(
                f"{reader.source}: formation.shape: {exc}; choose a shape that fits {n} agents (e.g. --formation polygon)"
            ) from None
    if formation.positions is not None and len(formation.positions) != n:
        raise reader.error("formation.positions", f"{n} rows, one per agent", found=f"{len(formation.positions)} rows")
    if initial.positions is not None and len(initial.positions) != n:
        raise reader.error("initial.positions", f"{n} rows, one per agent", found=f"{len(initial.positions)} rows")
    if initial.headings is not None and len(initial.headings) != n:
        raise reader.error("initial.headings", f"{n} angles, one per agent", found=f"{len(initial.headings)} angles")


_TOP_KEYS = (
    "name", "description", "topology", "gains", "delays", "formation",
    "simulation", "initial", "robot", "chart", "map", "schedule", "network",
)  # fmt: skip


def parse_scenario(data: Mapping[str, Any], *, source: str = "<scenario>", default_name: str = "scenario") -> Scenario:
    """Validate parsed TOML (a mapping) into a :class:`Scenario`.

    Parameters
    ----------
    data
        The mapping ``tomllib`` returns.
    source
        Named in every error message (the file path).
    default_name
        The scenario's name when the data has none.

    Raises
    ------
    ScenarioError
        One line: ``<source>: <key>: expected ...``.
    """
    reader = _Reader(source)
    reader.keys(data, "", _TOP_KEYS)
    name = reader.string("name", data.get("name", default_name))
    description = reader.string("description", data.get("description", ""))

    topology, spec = _topology(reader, reader.table(data, "topology", required=True))
    n = topology.n

    gains = reader.table(data, "gains", required=True)
    reader.keys(gains, "gains", ("P", "D"))
    for key in ("P", "D"):
        if key not in gains:
            raise ScenarioError(f"{source}: gains.{key}: missing (a positive gain of eq. protocol)")
    P, D = reader.gain("gains.P", gains["P"]), reader.gain("gains.D", gains["D"])

    delays = reader.table(data, "delays", required=True)
    reader.keys(delays, "delays", ("tau1", "tau2"))
    for key in ("tau1", "tau2"):
        if key not in delays:
            raise ScenarioError(f"{source}: delays.{key}: missing (a non-negative delay in seconds)")
    tau1 = reader.non_negative("delays.tau1", delays["tau1"])
    tau2 = reader.non_negative("delays.tau2", delays["tau2"])

    formation = _formation(reader, reader.table(data, "formation", required=True), n)
    simulation = _simulation(reader, reader.table(data, "simulation", required=False) or {})
    _check_step(reader, simulation.dt, tau1, tau2)
    initial = _initial(reader, reader.table(data, "initial", required=False) or {}, n)
    robot = _robot(reader, reader.table(data, "robot", required=False), simulation.model)
    chart = _chart(reader, reader.table(data, "chart", required=False) or {})
    grid = _map(reader, reader.table(data, "map", required=False) or {}, chart)
    schedule = _schedule(reader, reader.table(data, "schedule", required=False) or {}, (tau1, tau2), chart)
    return Scenario(
        name=name, description=description, topology=topology, P=P, D=D, tau1=tau1, tau2=tau2,
        formation=formation, simulation=simulation, initial=initial, chart=chart, map=grid,
        schedule=schedule, topology_spec=spec, source=source, robot=robot,
        network=parse_network_table(reader, reader.table(data, "network", required=False), n),
    )  # fmt: skip


#: a scenario file is a page of TOML; anything far larger is a mistake (a data file, a device)
_MAX_FILE_BYTES = 16 * 2**20


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a TOML scenario file.

    Parameters
    ----------
    path
        The ``.toml`` file; unknown keys are errors.

    Raises
    ------
    ScenarioError
        When the file cannot be read, is not TOML, or does not fit the
        schema of this module; the one-line message names the file and key.
    """
    path = Path(path)
    source = str(path)
    try:
        if path.is_dir():
            raise ScenarioError(f"{source}: is a directory, expected a scenario file (.toml)")
        if path.exists() and not path.is_file():  # a device or pipe (/dev/zero) would never end
            raise ScenarioError(f"{source}: not a regular file")
        if path.exists() and path.stat().st_size > _MAX_FILE_BYTES:
            raise ScenarioError(f"{source}: {path.stat().st_size} bytes, too large for a scenario file "
                                f"(at most {_MAX_FILE_BYTES // 2**20} MiB)")  # fmt: skip
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{source}: cannot read scenario file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{source}: not a UTF-8 text file") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from None
    return parse_scenario(data, source=source, default_name=path.stem)


def paper_scenario() -> Scenario:
    """The paper's example (:data:`PAPER_TOML`), the default of every subcommand."""
    return parse_scenario(tomllib.loads(PAPER_TOML), source="<paper>", default_name="paper")


# ------------------------------------------------------------ [network]
_NETWORK_KEYS = ("seed", "delay_spread", "tau1", "tau2", "jitter", "variation", "loss", "rate", "noise")


def parse_network_table(reader: _Reader, data: Mapping[str, Any] | None, n: int) -> Network | None:
    """The ``[network]`` table (module doc) as a :class:`~delayform.simulation.network.Network`.

    Parameters
    ----------
    reader
        Names the file in error messages.
    data
        The table, or None when the file has none.
    n
        Number of agents (size of delay and loss matrices).

    Raises
    ------
    ScenarioError
        One line naming ``network.<key>`` and what was expected.
    """
    if data is None:
        return None
    reader.keys(data, "network", _NETWORK_KEYS)

    def matrix(key: str, what: str = "delays (s)") -> list[list[float]] | None:
        if key not in data:
            return None
        value = data[key]
        if not isinstance(value, list) or len(value) != n or not all(isinstance(r, list) and len(r) == n for r in value):
            raise reader.error(f"network.{key}", f"a {n} x {n} array of {what}, row i: what agent i hears", value)
        return [[reader.number(f"network.{key}[{i}][{k}]", x) for k, x in enumerate(r)] for i, r in enumerate(value)]

    def pair(key: str, value: object) -> tuple[float, float]:
        return reader.pair(f"network.{key}", value)

    try:
        seed = reader.integer("network.seed", data.get("seed", 0), minimum=0)
        tau1, tau2 = matrix("tau1"), matrix("tau2")
        spread = reader.non_negative("network.delay_spread", data.get("delay_spread", 0.0))
        delays = LinkDelays(tau1=tau1, tau2=tau2, spread=spread) if (tau1 or tau2 or spread) else None
        jitter = Jitter(*pair("jitter", data["jitter"])) if "jitter" in data else None
        variation = None
        if "variation" in data:
            table = data["variation"]
            if not isinstance(table, Mapping):
                raise reader.error("network.variation", "a table { amplitude = [a1, a2], period = T }", table)
            reader.keys(table, "network.variation", ("amplitude", "period"))
            amplitude = pair("variation.amplitude", table.get("amplitude", [0.0, 0.0]))
            variation = SmoothVariation(*amplitude, period=reader.positive("network.variation.period", table.get("period", 10.0)))
        loss: BernoulliLoss | GilbertElliott | None = None
        if "loss" in data:
            value = data["loss"]
            if isinstance(value, Mapping):
                keys = ("p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad")
                reader.keys(value, "network.loss", keys)
                for key in keys[:2]:
                    if key not in value:
                        raise ScenarioError(f"{reader.source}: network.loss.{key}: missing (bursty loss needs both transition probabilities)")
                loss = GilbertElliott(**{k: reader.number(f"network.loss.{k}", v) for k, v in value.items()})
            elif isinstance(value, list):  # one probability per link, row i: what agent i hears
                loss = BernoulliLoss(matrix("loss", what="probabilities"))
            else:
                loss = BernoulliLoss(reader.number("network.loss", value))
        sampling = Sampling(reader.positive("network.rate", data["rate"])) if "rate" in data else None
        noise = None
        if "noise" in data:
            value = data["noise"]
            if not isinstance(value, list) or len(value) != 2:
                raise reader.error("network.noise", "[position std (m), velocity std (m/s)]", value)
            noise = MeasurementNoise(reader.number("network.noise[0]", value[0]), reader.number("network.noise[1]", value[1]))
        return Network(delays=delays, variation=variation, jitter=jitter, loss=loss, sampling=sampling, noise=noise, seed=seed)
    except NetworkError as exc:
        # the network model names the part; we add the file
        raise ScenarioError(f"{reader.source}: network.{exc}") from None
