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
    shape = "polygon"                   # polygon | hexagon | line | block | v ("grid": old name of block)
    spacing = 2.0                       # optional: distance between neighbours in the shape
    # positions = [[x, y], ...]         # one desired position per agent

    [simulation]                        # optional
    model = "unicycle"                  # unicycle | double_integrator | physics
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
    speed = 1e-3                        # the paper's small initial speed (paper, eq. 19)
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

    [network]                           # optional: an imperfect network (delayform.model.network)
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
)
from delayform.scenario.parse import (
    load_scenario,
    paper_scenario,
    parse_network_table,
    parse_scenario,
)
from delayform.scenario.write import scenario_toml

__all__ = [
    "scenario_toml",
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
