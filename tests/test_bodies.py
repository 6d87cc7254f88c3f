"""Bodies: the exact closest approach, contacts, the Robot object and its bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import delayform.simulation.bodies.approach as bodies
from delayform.errors import SimulationInputError
from delayform.simulation import IROBOT_CREATE, Robot, closest_approach, paper_simulations, simulate
from delayform.simulation.bodies.approach import sample_min_distance
from delayform.topology import paper_six, ring


def _straight(d0: np.ndarray, w: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robot 0 at rest at the origin, robot 1 on the line d0 + w t (a cubic Hermite reproduces it)."""
    pos = np.zeros((times.size, 2, 2))
    pos[:, 1] = d0 + w * times[:, None]
    vel = np.zeros_like(pos)
    vel[:, 1] = w
    return pos, vel


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-5, 5), st.floats(-5, 5), st.floats(-3, 3), st.floats(-3, 3),
    st.integers(2, 7), st.floats(0.05, 1.0),
)  # fmt: skip
@example(0.5, 0.0, 9.315798751259173e-238, 0.0, 2, 1.0)  # a subnormal-scale motion: Horner overflowed
@example(0.5, 0.0, 5e-324, 0.0, 2, 1.0)
def test_straight_lines_match_the_closed_form(x, y, wx, wy, samples, R):
    """|d0 + w t| is smallest at t* = -d0.w / |w|^2; contact between the roots of |d0 + w t| = R."""
    times = np.linspace(0.0, 4.0, samples)
    d0, w = np.array([x, y]), np.array([wx, wy])
    pos, vel = _straight(d0, w, times)
    got = closest_approach(times, pos, vel, R)
    ww = float(w @ w)
    t_star = float(np.clip(-(d0 @ w) / ww, 0.0, 4.0)) if ww > 0 else 0.0
    exact = float(np.linalg.norm(d0 + w * t_star))
    assert got.min_distance == pytest.approx(exact, abs=1e-9)
    assert got.min_distance <= sample_min_distance(pos) + 1e-12
    if exact < R - 1e-6 and ww > 1e-6:
        # roots of |w|^2 t^2 + 2 d0.w t + |d0|^2 - R^2 = 0, clipped to the run
        b, c = float(d0 @ w), float(d0 @ d0) - R * R
        disc = math.sqrt(b * b - ww * c)
        t_in, t_out = max((-b - disc) / ww, 0.0), min((-b + disc) / ww, 4.0)
        (contact,) = got.contacts
        assert contact.start == pytest.approx(t_in, abs=1e-7)
        assert contact.end == pytest.approx(t_out, abs=1e-7)
        assert contact.closest == pytest.approx(exact, abs=1e-9)
    elif exact > R + 1e-6:
        assert got.contacts == ()


def _fine_brute_force(traj_fine):
    """Per pair and saved fine step: the centre distances (brute force over every pair)."""
    pos = traj_fine.positions
    n = pos.shape[1]
    i, j = np.triu_indices(n, k=1)
    return (i, j), np.linalg.norm(pos[:, i] - pos[:, j], axis=-1)


def test_closest_approach_between_saved_steps_matches_a_finer_step():
    """Saved every 50th step (0.1 s), the interpolant's exact minimum finds what every step shows."""
    kw = dict(seed=0, duration=20.0, dt=0.002)
    fine = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", **kw, save_every=1)
    coarse = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", **kw, save_every=50)
    (i, j), dist = _fine_brute_force(fine)
    brute = float(dist.min())
    assert coarse.min_distance == pytest.approx(brute, abs=2e-5)
    # the saved samples alone miss it by much more
    assert sample_min_distance(coarse.positions) - brute > 10 * abs(coarse.min_distance - brute)
    # contacts: the same pairs, start and end within a fine step of where the fine samples cross
    R = 2 * IROBOT_CREATE.radius
    assert len(coarse.contacts) == len(fine.contacts) > 0
    for c in coarse.contacts:
        col = int(np.flatnonzero((i == c.agents[0]) & (j == c.agents[1]))[0])
        inside = np.flatnonzero(dist[:, col] < R)
        t_inside = fine.times[inside]
        episode = t_inside[(t_inside >= c.start - 0.02) & (t_inside <= c.end + 0.02)]
        assert episode.size > 0
        assert episode[0] - 0.002 - 1e-6 <= c.start <= episode[0] + 1e-9
        assert episode[-1] - 1e-9 <= c.end <= episode[-1] + 0.002 + 1e-6
        during = (fine.times >= episode[0]) & (fine.times <= episode[-1])
        # the samples every 2 ms can only overestimate the closest distance, by little
        assert 0.0 <= dist[during, col].min() - c.closest <= 3e-4


def test_large_team_kd_tree_search_equals_all_pairs(monkeypatch):
    traj = simulate(ring(90), 1.0, 0.5, 0.1, 0.1, "polygon", model="double_integrator",
                    duration=4.0, dt=0.1, seed=7)  # fmt: skip
    args = (traj.times, traj.positions, traj.velocities, 0.6)
    tree = closest_approach(*args)
    monkeypatch.setattr(bodies, "_ALL_PAIRS", 1000)
    every = closest_approach(*args)
    assert tree.min_distance == every.min_distance and tree.contacts == every.contacts
    assert len(tree.contacts) > 0
    assert tree.min_distance <= sample_min_distance(traj.positions)


def _dense_hermite(times: np.ndarray, pos: np.ndarray, vel: np.ndarray, per: int) -> tuple[np.ndarray, np.ndarray]:
    """The cubic Hermite interpolant evaluated at ``per`` points per interval (brute force)."""
    s = np.linspace(0.0, 1.0, per, endpoint=False)
    h = np.diff(times)[:, None, None, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    b = [c[None, :, None, None] for c in (h00, h10, h01, h11)]
    x = b[0] * pos[:-1, None] + b[1] * h * vel[:-1, None] + b[2] * pos[1:, None] + b[3] * h * vel[1:, None]
    t = times[:-1, None] + np.diff(times)[:, None] * s
    return np.append(t.ravel(), times[-1]), np.concatenate([x.reshape(-1, *pos.shape[1:]), pos[-1:]])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_long_contacts_skip_exact_minima_and_match_brute_force(seed, monkeypatch):
    """Robots circling through each other, in contact for many samples: most intervals in contact
    skip their exact minimum (:meth:`_Search.finish`), yet every contact's closest approach, its time
    and the run's minimum match the interpolant evaluated densely, and the contacts' spans match the
    dense samples in contact."""
    rng = np.random.default_rng(seed)
    n, R = 4, 0.8
    times = np.sort(np.concatenate([[0.0, 6.0], rng.uniform(0.0, 6.0, 398)]))
    centre, radius = rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(0.3, 1.0, n)
    omega, phase = rng.uniform(0.5, 2.0, n) * rng.choice([-1, 1], n), rng.uniform(0, 2 * np.pi, n)
    angle = omega * times[:, None] + phase
    pos = centre + radius[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    vel = (radius * omega)[:, None] * np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
    solved = []
    real = bodies._interval_minima

    def spy(sq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # rows in contact at a sample: |d(0)|^2 or |d(1)|^2 (the sum of the coefficients) below R^2
        solved.append(int(np.count_nonzero(np.minimum(sq[:, 0], sq.sum(axis=1)) < R * R)))
        return real(sq)

    monkeypatch.setattr(bodies, "_interval_minima", spy)
    got = closest_approach(times, pos, vel, R)
    t, x = _dense_hermite(times, pos, vel, 400)
    (i, j), _ = _fine_brute_force(type("T", (), {"positions": x}))
    dist = np.linalg.norm(x[:, i] - x[:, j], axis=-1)
    # exact minima never exceed the dense ones, and the dense grid is within (step)^2 of them
    assert 0.0 <= dist.min() - got.min_distance <= 1e-6
    assert len(got.contacts) > 0
    in_contact = 0
    for c in got.contacts:
        col = int(np.flatnonzero((i == c.agents[0]) & (j == c.agents[1]))[0])
        during = (t >= c.start) & (t <= c.end)
        assert 0.0 <= dist[during, col].min() - c.closest <= 1e-6
        at = np.argmin(np.abs(t - c.closest_at))
        assert dist[at, col] == pytest.approx(c.closest, abs=1e-5)
        assert np.all(dist[during, col] < R + 1e-9)  # in contact throughout
        assert c == bodies.Contact(**vars(c)) and repr(c) == repr(bodies.Contact(**vars(c)))  # built unchecked
        in_contact += int(np.count_nonzero((times[:-1] < c.end) & (times[1:] > c.start)))
    # outside the contacts the bodies are apart, up to the dense grid's step at the ends
    outside = np.ones_like(dist, dtype=bool)
    for c in got.contacts:
        col = int(np.flatnonzero((i == c.agents[0]) & (j == c.agents[1]))[0])
        outside[(t >= c.start - 1e-3) & (t <= c.end + 1e-3), col] = False
    assert np.all(dist[outside] >= R)
    assert sum(solved) < in_contact / 2  # the shortcut skipped most intervals in contact


_coords = st.floats(-3, 3)


@settings(max_examples=200, deadline=None)
@given(st.lists(_coords, min_size=8, max_size=8))
def test_hull_bound_never_exceeds_the_dense_minimum(c):
    """The Bezier-hull lower bound of an interval's separation against the cubic evaluated densely."""
    z0, z1, m0, m1 = (np.array([complex(c[2 * q], c[2 * q + 1])]) for q in range(4))
    s = np.linspace(0.0, 1.0, 2001)
    d = (2 * s**3 - 3 * s**2 + 1) * z0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * z1 + (s**3 - s**2) * m1
    bound = float(bodies._hull_bound(z0, z1, m0, m1)[0])
    assert 0.0 <= bound <= np.abs(d).min() + 1e-12
    if abs(z0 - z1)[0] + abs(m0)[0] + abs(m1)[0] < 1e-3 * abs(z0)[0]:
        assert bound == pytest.approx(abs(z0)[0], rel=1e-2)  # a pair moving together: tight


def test_the_papers_ideal_robots_collide_and_say_so():
    a, _ = paper_simulations(duration=40.0, dt=0.05)
    assert a.collided and a.radius == IROBOT_CREATE.radius
    assert any("collided" in w for w in a.warnings)
    assert a.min_distance < 2 * a.radius
    assert all(c.closest < c.contact_distance and c.start < c.closest_at < c.end for c in a.contacts)


def test_point_agents_have_no_contacts_and_robot_object_equals_shortcuts():
    kw = dict(duration=20.0, dt=0.05)
    short = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", **kw)
    obj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(model="double_integrator"), **kw)
    assert short.contacts == () and short.radius == 0.0
    assert np.array_equal(short.positions, obj.positions)
    big = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(model="double_integrator", radius=0.45), **kw)
    assert np.array_equal(big.positions, obj.positions) and big.collided


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: Robot(radius=-0.1), "non-negative"),
        (lambda: Robot(radius=math.inf), "finite"),
        (lambda: Robot(radius=math.nan), "finite"),
        (lambda: Robot(radius="big"), "number"),
        (lambda: Robot(model="tank"), "unknown model"),
        (lambda: Robot(model="double_integrator", limits=IROBOT_CREATE), "limits apply"),
    ],
)
def test_robot_bad_input(make, message):
    with pytest.raises(SimulationInputError, match=message):
        make()


def test_overlapping_slots_are_refused_before_simulating():
    with pytest.raises(SimulationInputError, match="slots .* closer than two robot radii"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(radius=1.5), duration=1e9, dt=1e-6)
    with pytest.raises(SimulationInputError, match="not both"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(), model="unicycle", duration=1.0, dt=0.1)


# ------------------------------------------------------------ command line
def test_cli_says_plainly_that_robots_collided_and_refuses_overlapping_bodies(tmp_path):
    import json

    from test_cli import assert_one_line_error, run

    proc = run("simulate", "--duration", "30", "--dt", "0.05", "--no-csv", "--json", "--out", str(tmp_path / "a"),
               cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("delayform: note: the robots collided:"), proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["radius"] == 0.17 and summary["contacts"]
    assert summary["min_distance"] < 0.34
    proc = run("simulate", "--radius", "5", "--duration", "1", "--out", str(tmp_path / "b"), cwd=tmp_path)
    assert_one_line_error(proc, "slots", "radii")
    assert not (tmp_path / "b").exists()
    proc = run("simulate", "--radius", "-1", "--duration", "1", "--out", str(tmp_path / "c"), cwd=tmp_path)
    assert proc.returncode == 2 and "radius" in proc.stderr and not (tmp_path / "c").exists()


def test_refused_runs_leave_no_folder_at_any_depth(tmp_path) -> None:
    """simulate and report make --out (and its parents) only once the computation's own checks pass."""
    from test_cli import assert_one_line_error, run

    nested = tmp_path / "a" / "b"
    proc = run("simulate", "--radius", "5", "--duration", "1", "--out", str(nested), cwd=tmp_path)
    assert_one_line_error(proc, "slots", "radii")  # refused by simulate itself, not by the command line
    proc = run("report", "--actuation-delay", "0.1", "--out", str(nested), cwd=tmp_path)
    assert_one_line_error(proc, "actuation delay")
    assert not (tmp_path / "a").exists()
    proc = run("simulate", "--duration", "0.5", "--no-csv", "--out", str(nested), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr  # a run that passes makes the folder with its first write
    assert (nested / "sim_operating.npz").is_file()
