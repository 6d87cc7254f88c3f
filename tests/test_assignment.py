"""Slot assignment against brute force over every permutation, and its effect on a run."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from delayform.errors import ScenarioError, SimulationInputError
from delayform.formation import centroid_weights, final_centroid, named_formation
from delayform.simulation import simulate
from delayform.simulation.bodies.assignment import assign_slots, assignment_cost
from delayform.topology import paper_six, ring

PERMS = np.array(list(itertools.permutations(range(6))))


def _brute_force(topo, z, x0, v0):
    """Smallest total squared start-to-final distance over all 720 slot permutations."""
    w = centroid_weights(topo)
    m = final_centroid(topo, 1.0, 0.5, 0.3, 0.2, x0, v0)
    # J by hand: final positions z_sigma + m - w^T z_sigma (eq. formation at rest)
    zs = z[PERMS]  # (720, 6, 2)
    final = zs + (m - np.einsum("i,pik->pk", w, zs))[:, None, :]
    return ((x0[None] - final) ** 2).sum(axis=(1, 2))


@pytest.mark.parametrize("topo", [paper_six(), ring(6)], ids=["paper_six (directed)", "ring (balanced)"])
def test_optimal_slots_match_brute_force_over_all_permutations(topo):
    z = named_formation("hexagon", 6, spacing=2.0)
    certified = 0
    for seed in range(25):
        rng = np.random.default_rng(seed)
        x0, v0 = rng.uniform(-5, 5, (6, 2)), rng.normal(scale=0.3, size=(6, 2))
        got = assign_slots(topo, 1.0, 0.5, 0.3, 0.2, z, x0, v0)
        costs = _brute_force(topo, z, x0, v0)
        assert got.cost == pytest.approx(costs.min(), rel=1e-10, abs=1e-10)
        assert got.cost == pytest.approx(costs[np.flatnonzero((PERMS == got.slots).all(axis=1))[0]], rel=1e-12)
        assert got.lower_bound <= costs.min() + 1e-9
        certified += got.certified
    if topo.name.startswith("ring"):
        assert certified == 25  # balanced: an exact linear assignment
    else:
        assert certified >= 10  # the dual bound closes the gap for most draws


def test_a_run_with_optimal_slots_ends_where_predicted():
    """The directed team's final centroid is predicted right: the run ends at the predicted positions."""
    topo, z = paper_six(), named_formation("hexagon", 6, spacing=2.0)
    traj = simulate(topo, 1.0, 0.5, 0.3, 0.2, z, model="double_integrator", duration=120.0, dt=0.05,
                    assignment="optimal", initial_speed=0.2, seed=3)  # fmt: skip
    rng = np.random.default_rng(3)
    x0, th0 = rng.uniform(-5, 5, size=(6, 2)), rng.uniform(-np.pi, np.pi, size=6)
    v0 = 0.2 * np.column_stack([np.cos(th0), np.sin(th0)])
    expect = assign_slots(topo, 1.0, 0.5, 0.3, 0.2, z, x0, v0)
    assert np.array_equal(traj.slots, expect.slots) and not np.array_equal(expect.slots, np.arange(6))
    assert np.allclose(traj.final_positions, expect.final_positions, atol=1e-4)
    given = simulate(topo, 1.0, 0.5, 0.3, 0.2, z, model="double_integrator", duration=120.0, dt=0.05,
                     initial_speed=0.2, seed=3)  # fmt: skip
    travelled = lambda t: float(((t.final_positions - t.positions[0]) ** 2).sum())  # noqa: E731
    assert travelled(traj) < travelled(given)
    assert travelled(traj) == pytest.approx(expect.cost, rel=1e-5)
    assert assignment_cost(np.arange(6), z, x0, centroid_weights(topo), traj.final_centroid) == pytest.approx(
        travelled(given), rel=1e-5)


def test_unknown_assignment_is_one_clear_error(tmp_path):
    with pytest.raises(SimulationInputError, match="unknown assignment 'best'"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.1, assignment="best")
    from delayform.scenario import load_scenario

    path = tmp_path / "s.toml"
    path.write_text('[topology]\nname = "ring"\nn = 4\n[gains]\nP = 1.0\nD = 0.5\n[delays]\ntau1 = 0.3\ntau2 = 0.2\n'
                    '[formation]\nshape = "polygon"\nspacing = 2.0\n[simulation]\nassignment = "clever"\n')  # fmt: skip
    with pytest.raises(ScenarioError, match="simulation.assignment"):
        load_scenario(path)
    path.write_text(path.read_text().replace('"clever"', '"optimal"'))
    assert load_scenario(path).simulation.assignment == "optimal"
