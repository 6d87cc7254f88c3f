"""Reading scenario files: every table and key checked, one-line errors naming file and key."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from delayform._validation import validated
from delayform.deploy.profiles import PROFILES, robot_profile
from delayform.errors import InputError, NetworkError, ResourceLimitError, RobotProfileError, ScenarioError
from delayform.scenario._reader import _Reader
from delayform.scenario.model import (
    MODELS,
    PAPER_TOML,
    TOPOLOGY_NAMES,
    ChartSpec,
    FormationSpec,
    InitialSpec,
    MapSpec,
    Scenario,
    ScheduleSpec,
    SimulationSpec,
    TopologySpec,
    default_step,
)
from delayform.model.network import (
    BernoulliLoss,
    GilbertElliott,
    Jitter,
    LinkDelays,
    MeasurementNoise,
    Network,
    Sampling,
    SmoothVariation,
)
from delayform.simulation.bodies.assignment import ASSIGNMENTS
from delayform.simulation.models.robots import IROBOT_CREATE, RobotLimits
from delayform.topology import Topology, complete, paper_six, random_digraph, ring, star


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
    except ResourceLimitError as exc:
        # a team too large for the machine stays a budget refusal, with the file in front
        raise ResourceLimitError(f"{reader.source}: topology: {exc}") from None
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
    from delayform.formation import named_formation

    shape = reader.shape("formation.shape", data["shape"])
    spacing = reader.length("formation.spacing", reader.positive("formation.spacing", data.get("spacing", 1.0)))
    try:
        named_formation(shape, n, spacing=spacing)  # e.g. a hexagon needs six agents
    except InputError as exc:
        raise ScenarioError(f"{reader.source}: formation.shape: {exc}") from None
    return FormationSpec(shape=shape, spacing=spacing)


def _simulation(reader: _Reader, data: Mapping[str, Any], tau: tuple[float, float]) -> SimulationSpec:
    reader.keys(data, "simulation", ("model", "duration", "dt", "assignment"))
    default = SimulationSpec()
    model = reader.string("simulation.model", data.get("model", default.model), MODELS)
    duration = reader.positive("simulation.duration", data.get("duration", default.duration))
    # a default step follows the delays given (default_step); one given is checked against them
    dt = reader.positive("simulation.dt", data["dt"]) if "dt" in data else min(default_step(*tau), duration / 2)
    if dt >= duration:
        raise reader.error("simulation.dt", f"a step smaller than simulation.duration = {duration:g}", dt)
    assignment = reader.string("simulation.assignment", data.get("assignment", default.assignment), ASSIGNMENTS)
    return SimulationSpec(model=model, duration=duration, dt=dt, dt_given="dt" in data, assignment=assignment)


_ROBOT_KEYS = (
    "wheel_radius", "axle_length", "max_wheel_speed", "max_speed", "max_turn_rate", "max_acceleration",
    "slow_speed", "turn_time_constant", "radius",
)  # fmt: skip


def _robot(reader: _Reader, data: Mapping[str, Any] | None, model: str) -> tuple[RobotLimits | None, str | None]:
    """The ``[robot]`` table: actuator limits and the profile they start from; (None, None) without the table.

    ``profile = "NAME"`` starts from a real robot's limits
    (:data:`delayform.deploy.PROFILES`), otherwise from IROBOT_CREATE; the
    other keys override single values.
    """
    if data is None:
        return None, None
    reader.keys(data, "robot", ("limits", "profile", "safety", "actuation_delay") + _ROBOT_KEYS)
    enabled = data.get("limits", True)
    if not isinstance(enabled, bool):
        raise reader.error("robot.limits", "true or false", enabled)
    base, name = IROBOT_CREATE, None
    if "profile" in data:
        if not isinstance(data["profile"], str):
            raise reader.error("robot.profile", f"a profile name ({', '.join(PROFILES)})", data["profile"])
        try:
            profile = robot_profile(data["profile"])
        except RobotProfileError as exc:
            raise ScenarioError(f"{reader.source}: robot.profile: {exc}") from None
        base, name = profile.limits, profile.name
    # checked even with limits = false: a table kept for later must not hide a wrong value
    values = {key: reader.positive(f"robot.{key}", data[key]) for key in _ROBOT_KEYS if key in data and key != "radius"}
    if data.get("radius"):  # a zero radius (point robots) is not a limit: it stays the Robot's (_body_radius)
        values["radius"] = reader.positive("robot.radius", data["radius"])
    try:
        robot = replace(base, **values)
    except InputError as exc:  # RobotLimits' own consistency checks (e.g. slow_speed < max_speed)
        raise ScenarioError(f"{reader.source}: robot: {exc}") from None
    if not enabled:
        return None, name
    if model == "double_integrator":
        raise reader.error("robot.limits", "false for simulation.model = 'double_integrator' (limits apply to robots)",
                           enabled)  # fmt: skip
    return robot, name


def _body_radius(reader: _Reader, data: Mapping[str, Any] | None) -> float | None:
    """``[robot] radius`` (m) whether or not limits apply: the bodies' size for contacts; None if absent."""
    if data is None or "radius" not in data:
        return None
    return reader.non_negative("robot.radius", data["radius"])


def _actuation_delay(reader: _Reader, data: Mapping[str, Any] | None) -> float:
    """``[robot] actuation_delay`` (s): how late each robot applies its command; 0 if absent."""
    if data is None or "actuation_delay" not in data:
        return 0.0
    return reader.non_negative("robot.actuation_delay", data["actuation_delay"])


def _safety(reader: _Reader, data: Mapping[str, Any] | None) -> str | None:
    """``[robot] safety``: a safety filter's name (:data:`~delayform.simulation.bodies.safety.SAFETY_FILTERS`) or None."""
    if data is None or "safety" not in data:
        return None
    from delayform.simulation.bodies.safety import SAFETY_FILTERS

    name = reader.string("robot.safety", data["safety"], SAFETY_FILTERS + ("none",))
    return None if name == "none" else name


def _initial(reader: _Reader, data: Mapping[str, Any], n: int) -> InitialSpec:
    reader.keys(data, "initial", ("seed", "speed", "positions", "headings"))
    seed = reader.integer("initial.seed", data.get("seed", 0), minimum=0)
    speed = reader.positive("initial.speed", data.get("speed", 1e-3))
    reader.length("initial.speed", speed, unit="m/s")
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
        headings = tuple(reader.length(f"initial.headings[{i}]", h, unit="radians") for i, h in enumerate(value))
    return InitialSpec(seed=seed, speed=speed, positions=positions, headings=headings)


#: the chart window's default edge (s), widened to the operating delays when they lie beyond it
DEFAULT_WINDOW = 8.0


def _chart(reader: _Reader, data: Mapping[str, Any], tau: tuple[float, float]) -> ChartSpec:
    reader.keys(data, "chart", ("tau1_max", "tau2_max", "points"))
    # defaults follow the values given: the window holds the operating delays with room around
    # them (half as much again), so that the chart shows the point and the schedule a box
    tau1_max = reader.positive("chart.tau1_max", data.get("tau1_max", max(DEFAULT_WINDOW, 1.5 * tau[0])))
    tau2_max = reader.positive("chart.tau2_max", data.get("tau2_max", max(DEFAULT_WINDOW, 1.5 * tau[1])))
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
    # the default upper bound follows the lower one the user gave (or the delays)
    default_max = [max(chart.tau1_max, tau_min[0]), max(chart.tau2_max, tau_min[1])]
    tau_max = reader.pair("schedule.tau_max", data.get("tau_max", default_max))
    if tau_max[0] < tau_min[0] or tau_max[1] < tau_min[1]:
        raise reader.error("schedule.tau_max", f"bounds >= schedule.tau_min = {list(tau_min)}", list(tau_max))
    return ScheduleSpec(tau_min=tau_min, tau_max=tau_max)


def _check_step(reader: _Reader, dt: float, tau1: float, tau2: float) -> None:
    """The simulator reads delayed states on its grid: a non-zero delay needs at least one step."""
    shortest = min((t for t in (tau1, tau2) if t > 0.0), default=None)
    if shortest is not None and dt > shortest:
        raise reader.error("simulation.dt", f"a step no longer than the shortest non-zero delay {shortest:g}", dt)


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
            raise ScenarioError(f"{source}: gains.{key}: missing (a positive gain of the paper's eq. 1)")
    P, D = reader.gain("gains.P", gains["P"]), reader.gain("gains.D", gains["D"])

    delays = reader.table(data, "delays", required=True)
    reader.keys(delays, "delays", ("tau1", "tau2"))
    for key in ("tau1", "tau2"):
        if key not in delays:
            raise ScenarioError(f"{source}: delays.{key}: missing (a non-negative delay in seconds)")
    tau1 = reader.non_negative("delays.tau1", delays["tau1"])
    tau2 = reader.non_negative("delays.tau2", delays["tau2"])

    formation = _formation(reader, reader.table(data, "formation", required=True), n)
    simulation = _simulation(reader, reader.table(data, "simulation", required=False) or {}, (tau1, tau2))
    _check_step(reader, simulation.dt, tau1, tau2)
    initial = _initial(reader, reader.table(data, "initial", required=False) or {}, n)
    robot, profile_name = _robot(reader, reader.table(data, "robot", required=False), simulation.model)
    radius = _body_radius(reader, reader.table(data, "robot", required=False))
    safety = _safety(reader, reader.table(data, "robot", required=False))
    actuation_delay = _actuation_delay(reader, reader.table(data, "robot", required=False))
    chart = _chart(reader, reader.table(data, "chart", required=False) or {}, (tau1, tau2))
    grid = _map(reader, reader.table(data, "map", required=False) or {}, chart)
    schedule = _schedule(reader, reader.table(data, "schedule", required=False) or {}, (tau1, tau2), chart)
    return Scenario(
        name=name, description=description, topology=topology, P=P, D=D, tau1=tau1, tau2=tau2,
        formation=formation, simulation=simulation, initial=initial, chart=chart, map=grid,
        schedule=schedule, topology_spec=spec, source=source, robot=robot, robot_profile=profile_name, radius=radius, safety=safety,
        actuation_delay=actuation_delay,
        network=parse_network_table(reader, reader.table(data, "network", required=False), n),
    )  # fmt: skip


#: a scenario file is a page of TOML; anything far larger is a mistake (a data file, a device)
_MAX_FILE_BYTES = 16 * 2**20


@validated(ScenarioError)
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
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Windows editors) is not TOML
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
    scenario = parse_scenario(tomllib.loads(PAPER_TOML), source="<paper>", default_name="paper")
    # nothing of it was given by the user: its step, too, follows delays given on the command line
    return replace(scenario, simulation=replace(scenario.simulation, dt_given=False))


# ------------------------------------------------------------ [network]
_NETWORK_KEYS = ("seed", "delay_spread", "tau1", "tau2", "jitter", "variation", "loss", "rate", "noise")


def parse_network_table(reader: _Reader, data: Mapping[str, Any] | None, n: int) -> Network | None:
    """The ``[network]`` table (module doc) as a :class:`~delayform.model.network.Network`.

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
