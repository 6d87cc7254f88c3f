"""Scenario files: the shipped examples load, and every malformed file gets one line naming the key."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from delayform.errors import InputError, ScenarioError
from delayform.scenario import PAPER_TOML, load_scenario, paper_scenario, parse_scenario
from delayform.topology import paper_six, ring

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: A valid minimal scenario; each malformed case below edits it.
BASE = """\
[topology]
name = "ring"
n = 4

[gains]
P = 1.0
D = 0.5

[delays]
tau1 = 0.3
tau2 = 0.2

[formation]
positions = [[0, 0], [1, 0], [1, 1], [0, 1]]
"""


def _edit(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new)


#: (case id, file text, the key the one-line message must name)
MALFORMED: list[tuple[str, str, str]] = [
    ("unknown top-level key", "colour = 1\n" + BASE, "colour"),
    ("unknown key in gains", _edit("D = 0.5", "D = 0.5\nK = 2"), "gains.K"),
    ("missing gains table", _edit("[gains]\nP = 1.0\nD = 0.5\n", ""), "[gains]"),
    ("missing P", _edit("P = 1.0\n", ""), "gains.P"),
    ("P is a string", _edit("P = 1.0", 'P = "one"'), "gains.P"),
    ("D negative", _edit("D = 0.5", "D = -0.5"), "gains.D"),
    ("P is a boolean", _edit("P = 1.0", "P = true"), "gains.P"),
    ("tau1 negative", _edit("tau1 = 0.3", "tau1 = -0.3"), "delays.tau1"),
    ("missing tau2", _edit("tau2 = 0.2\n", ""), "delays.tau2"),
    ("delays not a table", _edit("[delays]\ntau1 = 0.3\ntau2 = 0.2\n", "").replace(
        "[topology]", 'delays = "short"\n[topology]'), "delays"),
    ("two topology kinds", _edit("n = 4", "n = 4\nedges = [[0, 1]]"), "topology"),
    ("unknown topology name", _edit('name = "ring"', 'name = "torus"'), "topology.name"),
    ("ring without size", _edit("n = 4\n", ""), "topology.n"),
    ("size not an integer", _edit("n = 4", "n = 4.5"), "topology.n"),
    ("size too small", _edit("n = 4", "n = 1"), "topology.n"),
    ("adjacency not square", _edit('name = "ring"\nn = 4', "adjacency = [[0, 1], [1, 0, 0]]"),
     "topology.adjacency[1]"),
    ("adjacency not binary", _edit('name = "ring"\nn = 4', "adjacency = [[0, 2], [1, 0]]"),
     "topology.adjacency[0][1]"),
    ("adjacency self-loop", _edit('name = "ring"\nn = 4', "adjacency = [[1, 1], [1, 0]]"),
     "topology.adjacency"),
    ("agent without informer", _edit('name = "ring"\nn = 4', "adjacency = [[0, 1], [0, 0]]"),
     "topology.adjacency"),
    ("no spanning tree", _edit('name = "ring"\nn = 4',
     "adjacency = [[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]]"), "topology"),
    ("edge index beyond n", _edit('name = "ring"\nn = 4', "edges = [[0, 1], [1, 0], [3, 4]]\nn = 4"),
     "topology.edges"),
    ("edge not a pair", _edit('name = "ring"\nn = 4', "edges = [[0, 1, 2]]"), "topology.edges[0]"),
    ("paper_six with a size", _edit('name = "ring"', 'name = "paper_six"'), "topology.n"),
    ("random digraph probability > 1", _edit('name = "ring"\nn = 4',
     'name = "random_digraph"\nn = 5\np = 1.5'), "topology.p"),
    ("random digraph without p", _edit('name = "ring"\nn = 4', 'name = "random_digraph"\nn = 5'),
     "topology.p"),
    ("formation of the wrong size", _edit("[1, 1], [0, 1]]", "[1, 1]]"), "formation.positions"),
    ("formation shape and positions", _edit("[formation]", '[formation]\nshape = "line"'), "formation"),
    ("formation position not a pair", _edit("[1, 0], [1, 1]", "[1, 0, 2], [1, 1]"),
     "formation.positions[1]"),
    ("missing formation", BASE.split("[formation]")[0], "[formation]"),
    ("unknown model", BASE + '[simulation]\nmodel = "tank"\n', "simulation.model"),
    ("zero step", BASE + "[simulation]\ndt = 0\n", "simulation.dt"),
    ("step longer than a delay", BASE + "[simulation]\ndt = 0.25\n", "simulation.dt"),
    ("step longer than duration", BASE + "[simulation]\nduration = 1.0\ndt = 2.0\n", "simulation.dt"),
    ("headings of the wrong size", BASE + "[initial]\nheadings = [0.0, 1.0]\n", "initial.headings"),
    ("initial positions of the wrong size", BASE + "[initial]\npositions = [[0, 0]]\n",
     "initial.positions"),
    ("negative seed", BASE + "[initial]\nseed = -1\n", "initial.seed"),
    ("chart point not a pair", BASE + "[chart]\npoints = { a = [0.3] }\n", "chart.points.a"),
    ("chart window negative", BASE + "[chart]\ntau1_max = -2\n", "chart.tau1_max"),
    ("chart point outside the window", BASE + "[chart]\ntau1_max = 2.0\npoints = { z = [3.0, 1.0] }\n",
     "chart.points.z"),
    ("map size not integers", BASE + "[map]\nsize = [10.5, 10]\n", "map.size[0]"),
    ("map range reversed", BASE + "[map]\ntau1 = [3.0, 1.0]\n", "map.tau1"),
    ("schedule bounds inverted", BASE + "[schedule]\ntau_min = [1.0, 1.0]\ntau_max = [0.5, 2.0]\n",
     "schedule.tau_max"),
    ("unknown key in simulation", BASE + "[simulation]\nsteps = 10\n", "simulation.steps"),
    ("robot limit negative", BASE + "[robot]\nmax_speed = -0.5\n", "robot.max_speed"),
    ("robot limit not a number", BASE + '[robot]\nmax_turn_rate = "fast"\n', "robot.max_turn_rate"),
    ("robot unknown key", BASE + "[robot]\nmax_jerk = 1.0\n", "robot.max_jerk"),
    ("robot limits on double integrators", BASE + '[simulation]\nmodel = "double_integrator"\n[robot]\n'
     "max_speed = 1.0\n", "robot.limits"),
    ("not TOML", BASE + "this is = = not toml\n", "not valid TOML"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "key"), [c[1:] for c in MALFORMED], ids=[c[0] for c in MALFORMED])
def test_malformed_scenario_names_file_and_key(tmp_path: Path, text: str, key: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert key in message
    # users who only know the built-ins still catch it
    assert isinstance(info.value, ValueError) and isinstance(info.value, InputError)


def test_unknown_formation_shape_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(BASE.replace("positions = [[0, 0], [1, 0], [1, 1], [0, 1]]", 'shape = "blob"'))
    with pytest.raises(ScenarioError, match="formation.shape"):
        load_scenario(path)
    # a known shape that does not fit the team: a hexagon of four
    path.write_text(BASE.replace("positions = [[0, 0], [1, 0], [1, 1], [0, 1]]", 'shape = "hexagon"'))
    with pytest.raises(ScenarioError, match="formation.shape: .*hexagon"):
        load_scenario(path)


def test_missing_file_is_a_scenario_error(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "absent.toml")


def test_base_scenario_loads_with_defaults(tmp_path: Path) -> None:
    path = tmp_path / "team.toml"
    path.write_text(BASE)
    s = load_scenario(path)
    assert s.name == "team" and s.source == str(path)
    assert s.topology.n == 4
    np.testing.assert_array_equal(s.topology.C, ring(4).C)
    assert (s.P, s.D, s.tau1, s.tau2) == (1.0, 0.5, 0.3, 0.2)
    assert s.formation.positions == ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0))
    assert s.simulation.model == "unicycle" and s.initial.speed == 1e-3
    # scheduling starts from the operating delays unless told otherwise
    assert s.schedule.tau_min == (0.3, 0.2)
    assert s.schedule.tau_max == (s.chart.tau1_max, s.chart.tau2_max)


def test_edge_list_and_adjacency_give_the_same_team(tmp_path: Path) -> None:
    team = paper_six()
    rows = [[int(v) for v in row] for row in team.adjacency]
    a = parse_scenario(tomllib.loads(BASE.replace('name = "ring"\nn = 4', f"adjacency = {rows}")
                                     .replace("positions = [[0, 0], [1, 0], [1, 1], [0, 1]]",
                                              "positions = " + str([[i, 0] for i in range(6)]))))
    edges = [list(e) for e in team.edges()]
    b = parse_scenario(tomllib.loads(BASE.replace('name = "ring"\nn = 4', f"edges = {edges}")
                                     .replace("positions = [[0, 0], [1, 0], [1, 1], [0, 1]]",
                                              "positions = " + str([[i, 0] for i in range(6)]))))
    np.testing.assert_array_equal(a.topology.C, team.C)
    np.testing.assert_array_equal(b.topology.C, team.C)


def test_paper_example_file_is_the_embedded_default() -> None:
    from_file = load_scenario(EXAMPLES / "paper.toml")
    embedded = paper_scenario()
    assert tomllib.loads((EXAMPLES / "paper.toml").read_text()) == tomllib.loads(PAPER_TOML)
    assert from_file.summary() | {"source": ""} == embedded.summary() | {"source": ""}
    # Section "Simulation Examples": P = 1, D = 0.5, point a, points a..e of Fig. stability
    assert (embedded.P, embedded.D, embedded.tau1, embedded.tau2) == (1.0, 0.5, 0.3, 0.2)
    assert [p[0] for p in embedded.chart.points] == ["a", "b", "c", "d", "e"]
    np.testing.assert_allclose(np.sort_complex(embedded.topology.eigenvalues),
                               np.sort_complex(paper_six().eigenvalues))


@pytest.mark.parametrize("name", ["paper", "ring12", "random50", "paper_create"])
def test_shipped_examples_load(name: str) -> None:
    s = load_scenario(EXAMPLES / f"{name}.toml")
    assert s.name == name
    assert s.topology.has_spanning_tree()
    assert (s.robot is not None) == (name == "paper_create")
    if s.robot is not None:
        from delayform.simulation import IROBOT_CREATE

        assert s.robot.max_speed == IROBOT_CREATE.max_speed and s.robot.axle_length == IROBOT_CREATE.axle_length


def test_overrides_are_checked() -> None:
    s = paper_scenario()
    t = s.with_changes(tau1=1.0, P=2.0)
    assert (t.tau1, t.tau2, t.P, t.D) == (1.0, 0.2, 2.0, 0.5)
    assert s.tau1 == 0.3  # frozen: the original is unchanged
    with pytest.raises(ScenarioError, match="delays.tau2"):
        s.with_changes(tau2=-1.0)
    with pytest.raises(ScenarioError, match="gains.D"):
        s.with_changes(D=0.0)


def test_override_topology_must_fit_explicit_positions(tmp_path: Path) -> None:
    path = tmp_path / "team.toml"
    path.write_text(BASE)
    s = load_scenario(path)
    changed = s.with_changes(topology=ring(5))  # fine for a chart; the formation is checked when built
    with pytest.raises(ScenarioError, match="formation.positions"):
        changed.desired_positions()
