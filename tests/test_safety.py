"""The safety filter: its QP against Clarabel, zero contacts where unfiltered runs collide, deadlock."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from delayform.errors import SimulationInputError
from delayform.formation import named_formation
from delayform.simulation import Robot, simulate
from delayform.simulation.bodies.safety import BarrierFilter, barrier_commands
from delayform.topology import paper_six, random_digraph, ring

R = 0.17  # the Create's body radius


def _pair_constraint(x, v, r, o, safe, k):
    """Row and right side of -n.(u_r - u_o) <= c for the barrier h = |dp| - Ds (safety module doc)."""
    dp, dv = x[r] - x[o], v[r] - v[o]
    d = np.linalg.norm(dp)
    n = dp / d
    c = (dv @ dv - (n @ dv) ** 2) / d + 2 * k * (n @ dv) + k * k * (d - safe)
    return -n, c


def _clarabel_qp(u_hat: np.ndarray, A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min |u - u_hat|^2 s.t. A u <= b, by the Clarabel interior-point solver (independent of ours)."""
    import clarabel

    P = sp.csc_matrix(2.0 * np.eye(u_hat.size))
    q = -2.0 * u_hat
    cones = [clarabel.NonnegativeConeT(A.shape[0])]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-12
    sol = clarabel.DefaultSolver(P, q, sp.csc_matrix(A), b, cones, settings).solve()
    assert str(sol.status) in ("Solved", "AlmostSolved")
    return np.array(sol.x)


def test_each_robots_command_is_the_qp_solution_clarabel_finds():
    """The closed form (candidates of a 2-D QP) against a real QP solver, robot by robot."""
    rng = np.random.default_rng(4)
    checked = joint = 0
    for _ in range(60):
        n = int(rng.integers(2, 9))
        x = rng.uniform(-1.0, 1.0, (n, 2))
        v = rng.normal(scale=0.8, size=(n, 2))
        u_hat = rng.normal(scale=2.0, size=(n, 2))
        safe = 0.36
        k = 2.0
        u, active, infeasible = barrier_commands(x, v, u_hat, safe, k)
        if infeasible.any():
            # a robot's halves conflicted: the joint QP; every pair's full constraint must hold
            for r, o in zip(*np.triu_indices(n, k=1)):
                a, c = _pair_constraint(x, v, r, o, safe, k)
                assert a @ (u[r] - u[o]) <= c + 1e-6 * (1 + abs(c))
            joint += 1
            continue
        for r in range(n):
            # robot r's half of every pair's constraint (module doc), built here from the formula
            rows, rhs = [], []
            for o in range(n):
                if o == r:
                    continue
                a, c = _pair_constraint(x, v, r, o, safe, k)
                rows.append(a)
                rhs.append(c / 2)
            A, b = np.array(rows), np.array(rhs)
            if np.all(A @ u_hat[r] <= b + 1e-9 * (1 + np.abs(b))):
                assert not active[r] and np.array_equal(u[r], u_hat[r])
                continue
            assert active[r]
            ref = _clarabel_qp(u_hat[r], A, b)
            assert np.allclose(u[r], ref, atol=1e-6 * (1 + np.abs(ref).max())), (u[r], ref)
            assert np.all(A @ u[r] <= b + 1e-7 * (1 + np.abs(b)))
            checked += 1
    assert checked > 30 and joint > 0


def _distances_at_every_step(traj) -> np.ndarray:
    pos = traj.positions
    i, j = np.triu_indices(traj.n, k=1)
    return np.linalg.norm(pos[:, i] - pos[:, j], axis=-1)


@pytest.mark.parametrize("tau", [(0.3, 0.2), (2.0, 1.0)], ids=["point a", "point b"])
def test_the_papers_runs_collide_without_the_filter_and_not_with_it(tau):
    z = named_formation("hexagon", 6, spacing=2.0)
    kw = dict(duration=100.0, dt=0.02)
    bare = simulate(paper_six(), 1.0, 0.5, *tau, z, **kw)
    safe = simulate(paper_six(), 1.0, 0.5, *tau, z, safety="barrier", **kw)
    assert bare.contacts and not safe.contacts
    # the constraint at every step: centres at least the sum of the radii apart
    assert _distances_at_every_step(safe).min() >= 2 * R and safe.min_distance >= 2 * R
    assert safe.safety.was_active and safe.status == "settled" and safe.stated_order == 2
    assert any("safety filter" in w for w in safe.warnings)


def _scattered_start(n: int, seed: int) -> np.ndarray:
    """Robots on a shuffled grid of 1.5 m cells, jittered: apart at the start, crossing on the way."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    cells = np.array([(a, b) for a in range(side) for b in range(side)], dtype=float)[rng.permutation(side * side)[:n]]
    return 1.5 * (cells - side / 2) + rng.uniform(-0.3, 0.3, (n, 2))


@pytest.mark.parametrize("n", [6, 20, pytest.param(50, marks=pytest.mark.slow)])
def test_random_teams_have_zero_contacts_with_the_filter(n):
    """Random digraphs into a block: the unfiltered run collides, the filtered one never does."""
    topo = random_digraph(n, 3.0 / n, seed=n)
    kw = dict(duration=12.0, dt=0.05, initial_positions=_scattered_start(n, n), initial_speed=0.3, seed=n)
    bare = simulate(topo, 1.0, 0.5, 0.3, 0.2, "block", robot=Robot(model="double_integrator", radius=R), **kw)
    safe = simulate(topo, 1.0, 0.5, 0.3, 0.2, "block",
                    robot=Robot(model="double_integrator", radius=R, safety="barrier"), **kw)  # fmt: skip
    assert bare.contacts, "the unfiltered run must collide for this test to mean something"
    assert not safe.contacts and safe.min_distance >= 2 * R
    assert _distances_at_every_step(safe).min() >= 2 * R  # the constraint at every step


def test_where_no_constraint_binds_the_run_is_the_unfiltered_run():
    z = named_formation("hexagon", 6, spacing=2.0)
    start = z + np.array([0.3, -0.2])  # every robot near its slot, far from the others
    kw = dict(duration=30.0, dt=0.05, initial_positions=start, model="double_integrator")
    bare = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, z, **kw)
    safe = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, z, safety=BarrierFilter(), **kw)
    assert not safe.safety.was_active
    assert np.allclose(safe.positions, bare.positions, rtol=0, atol=1e-10)


def test_head_on_robots_deadlock_and_say_so():
    """Two robots swapping places on a line: the barrier brakes both on the line, forever."""
    z = np.array([[2.0, 0.0], [-2.0, 0.0]])
    traj = simulate(ring(2), 1.0, 0.5, 0.0, 0.0, z, initial_positions=-z, initial_speed=0.0,
                    initial_headings=np.zeros(2), robot=Robot(model="double_integrator", radius=R, safety="barrier"),
                    duration=60.0, dt=0.05)  # fmt: skip
    assert traj.status == "deadlock" and not traj.contacts
    assert traj.warnings[0].startswith("deadlock: the robots stopped short")
    assert abs(traj.positions[-1, 0, 0] - traj.positions[-1, 1, 0]) >= 2 * R


# the class, not a filter: the checking layer refuses it by type
@pytest.mark.parametrize("bad, message", [("shield", "unknown safety filter"), (BarrierFilter, "safety must be a string or a BarrierFilter")])
def test_unknown_safety_filter_is_one_clear_error(bad, message):
    with pytest.raises(SimulationInputError, match=message):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.1, safety=bad)


@pytest.mark.parametrize("field, value", [("rate", 0.0), ("rate", np.inf), ("margin", -0.1)])
def test_bad_filter_settings(field, value):
    with pytest.raises(SimulationInputError, match=f"safety.{field}"):
        BarrierFilter(**{field: value})


def test_cli_safety_filter_reports_its_cost_and_the_scenario_key(tmp_path):
    import json

    from test_cli import run

    proc = run("simulate", "--safety", "barrier", "--duration", "40", "--dt", "0.05", "--no-csv", "--json",
               "--out", str(tmp_path / "a"), cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0 and "collided" not in proc.stderr, proc.stderr
    out = json.loads(proc.stdout)
    assert out["contacts"] == [] and out["contacts_without_filter"] > 0
    assert out["safety"]["active_fraction"] > 0 and out["min_distance"] >= 0.34
    from delayform.scenario import load_scenario

    path = tmp_path / "s.toml"
    path.write_text('[topology]\nname = "ring"\nn = 4\n[gains]\nP = 1.0\nD = 0.5\n[delays]\ntau1 = 0.3\ntau2 = 0.2\n'
                    '[formation]\nshape = "polygon"\nspacing = 2.0\n[robot]\nlimits = false\nsafety = "barrier"\n')  # fmt: skip
    sc = load_scenario(path)
    assert sc.robot is None and sc.robot_spec.safety == BarrierFilter()
    from delayform.app import scenario_toml

    again = tmp_path / "again.toml"
    again.write_text(scenario_toml(sc))
    assert load_scenario(again).robot_spec == sc.robot_spec


def _halves(x, v, r, safe, k):
    """Robot r's half of every pair's constraint, built from the formula (module doc)."""
    rows, rhs = [], []
    for o in range(x.shape[0]):
        if o != r:
            a, c = _pair_constraint(x, v, r, o, safe, k)
            rows.append(a)
            rhs.append(c / 2)
    return np.array(rows), np.array(rhs)


def test_many_sided_polygons_and_clusters_against_clarabel():
    """Crowds of 30-60 robots, each facing up to tens of sides: a free robot's command is Clarabel's
    over all its halves; with squeezed robots (their clusters' joint QP) every pair's constraint holds."""
    rng = np.random.default_rng(11)
    safe, k = 0.36, 2.0
    checked = squeezed_runs = most_sides = 0
    for trial in range(6):
        n = int(rng.integers(30, 50))
        cells = np.array([(a, b) for a in range(7) for b in range(7)], dtype=float)[rng.permutation(49)[:n]]
        x = (8.0 / 7.0) * cells + rng.uniform(-0.2, 0.2, (n, 2))  # apart, about 1.1 m from each other
        v = rng.normal(scale=1.0 if trial % 2 else 0.3, size=(n, 2))
        u_hat = rng.normal(scale=10.0 if trial % 2 else 4.0, size=(n, 2))
        u, active, infeasible = barrier_commands(x, v, u_hat, safe, k)
        for r, o in zip(*np.triu_indices(n, k=1)):
            a, c = _pair_constraint(x, v, r, o, safe, k)
            assert a @ (u[r] - u[o]) <= c + 1e-6 * (1 + abs(c))
        assert np.array_equal(np.abs(u - u_hat).max(axis=1) > 1e-9 * (1 + np.abs(u_hat).max(axis=1)), active)
        if infeasible.any():
            squeezed_runs += 1
            continue
        for r in np.flatnonzero(active):
            A, b = _halves(x, v, r, safe, k)
            most_sides = max(most_sides, int((A @ u_hat[r] > b).sum()))
            ref = _clarabel_qp(u_hat[r], A, b)
            assert np.allclose(u[r], ref, atol=1e-6 * (1 + np.abs(ref).max())), (r, u[r], ref)
            checked += 1
    assert checked > 50 and squeezed_runs > 0 and most_sides >= 6, (checked, squeezed_runs, most_sides)


def test_the_neighbour_list_keeps_every_pair_that_can_bind():
    """Above 64 robots the KD-tree's pairs give the all-pairs filter's commands exactly."""
    from delayform.simulation.models.robots import DoubleIntegrator
    from delayform.simulation.bodies.safety import FilteredAgent

    rng = np.random.default_rng(5)
    n = 90
    x = np.concatenate([rng.uniform(-25.0, 25.0, (n - 20, 2)), rng.uniform(-2.0, 2.0, (20, 2))])  # a crowd inside
    v = rng.normal(scale=0.5, size=(n, 2))
    agent = FilteredAgent(DoubleIntegrator(x, v), BarrierFilter(), R)
    for step in range(4):
        xs = x + 0.3 * step * v
        u_hat = rng.normal(scale=2.0, size=(n, 2))
        state = np.column_stack([xs, v])
        _, cart, extra = agent.rhs(state, u_hat)
        ref, active, _ = barrier_commands(xs, v, u_hat, agent.safe, 2.0)
        assert agent.neighbours.pairs.shape[0] < n * (n - 1) // 2  # the list did leave pairs out
        assert np.allclose(cart, ref, rtol=0, atol=1e-9) and np.array_equal(extra[-2] > 0.5, active)
        assert active.sum() >= 5


@pytest.mark.parametrize("tau", [(0.3, 0.2), (2.0, 1.0)], ids=["point a", "point b"])
def test_small_teams_linear_path_with_the_filter_is_the_generic_loop(tau, monkeypatch):
    """The blocked linear path where the filter is idle (simulation.delayed.filtered) against the generic
    RK4 loop filtering every stage: same motion to rounding, same steps at which the filter acted."""
    import delayform.simulation.runs.integrators as models

    z = named_formation("hexagon", 6, spacing=2.0)
    kw = dict(duration=40.0, dt=0.02, safety="barrier")
    fast = simulate(paper_six(), 1.0, 0.5, *tau, z, **kw)
    monkeypatch.setattr(models, "integrate_filtered", lambda *a, **k: None)  # the generic loop
    slow = simulate(paper_six(), 1.0, 0.5, *tau, z, **kw)
    assert fast.safety.was_active and fast.safety.infeasible.any()  # both kinds of filtered step happened
    assert np.abs(fast.positions - slow.positions).max() < 1e-9
    assert np.array_equal(fast.safety.active, slow.safety.active)
    assert np.array_equal(fast.safety.infeasible, slow.safety.infeasible)
    assert fast.status == slow.status and not fast.contacts


def test_the_whole_teams_joint_qp_against_clarabel_over_every_constraint_warm_or_cold():
    """The joint QP (active set, exact polish, warm guess from a nearby state) against Clarabel given
    every pair's full constraint at once (built here from the formula); warm and cold agree to rounding."""
    from delayform.simulation.bodies.safety import ActiveSet, _cluster_qp, _pair_terms

    rng = np.random.default_rng(12)
    safe, k = 0.36, 2.0
    warm_hits = 0
    for trial in range(4):
        n = 40
        cells = np.array([(a, b) for a in range(7) for b in range(7)], dtype=float)[rng.permutation(49)[:n]]
        x = 0.45 * cells + rng.uniform(-0.03, 0.03, (n, 2))  # a jam: many constraints bind
        v = rng.normal(scale=0.5, size=(n, 2))
        u_hat = rng.normal(scale=4.0, size=(n, 2))
        pairs = np.column_stack(np.triu_indices(n, k=1)).astype(np.intp)
        everyone = np.ones(n, dtype=bool)
        memory = ActiveSet()
        for step in range(3):  # the state moves a little: the memory is the previous step's
            xs, us = x + 0.01 * step * v, u_hat + 0.05 * step
            normal, c, _, _ = _pair_terms(xs, v, us, pairs, safe, k)
            dp = np.column_stack([normal.real, normal.imag])
            had = memory.codes.size
            warm = _cluster_qp(pairs, dp, c, us, everyone, memory)
            cold = _cluster_qp(pairs, dp, c, us, everyone)
            assert warm is not None and cold is not None
            assert np.abs(warm - cold).max() <= 1e-9 * (1 + np.abs(cold).max())
            warm_hits += had > 0
            A = np.zeros((pairs.shape[0], 2 * n))
            b = np.zeros(pairs.shape[0])
            for row, (r, o) in enumerate(pairs):
                a, b[row] = _pair_constraint(xs, v, r, o, safe, k)
                A[row, 2 * r : 2 * r + 2], A[row, 2 * o : 2 * o + 2] = a, -a
            ref = _clarabel_qp(us.ravel(), A, b).reshape(n, 2)
            assert np.allclose(warm, ref, atol=1e-6 * (1 + np.abs(ref).max())), np.abs(warm - ref).max()
            assert (A @ warm.ravel() - b <= 1e-9 * (1 + np.abs(b))).all()
            assert (A @ us.ravel() > b).sum() > 20  # the jam: many constraints break at u_hat
    assert warm_hits >= 8


def test_a_large_team_with_an_actuation_delay_filters_over_its_neighbour_list():
    """Above 64 robots the delayed-command path takes the KD-tree's pairs as the undelayed one does."""
    team = random_digraph(70, 0.1, seed=1)
    kw = dict(model="double_integrator", actuation_delay=0.05, duration=1.0, dt=0.05, safety="barrier")
    tr = simulate(team, 1.0, 0.5, 0.3, 0.2, "block", **kw)
    assert np.isfinite(tr.positions).all() and not tr.contacts
