"""Actuation delay with the safety filter and over an imperfect network (issue 21, items 3 and 4).

Independent checks: the filter's prediction against a quadrature of the
interpolated commands (scipy) and against the run itself; the run over
per-link delays against a separate integration of the delayed system written
here (method of steps: the executed acceleration is known from the past, so
x and v advance explicitly, exactly for piecewise-linear accelerations).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from delayform.errors import SimulationInputError
from delayform.formation import formation_forcing, named_formation
from delayform.simulation import IROBOT_CREATE, simulate
from delayform.simulation.delayed.actuation import CommandBuffer
from delayform.model.network import LinkDelays, Network
from delayform.simulation.models.robots import Robot
from delayform.topology import paper_six


# ============================================================ the prediction
@pytest.mark.parametrize(("ta", "dt", "k"), [(0.3, 0.01, 50), (0.237, 0.02, 40), (0.3, 0.01, 12)])
def test_prediction_integrates_the_commands_in_flight(ta: float, dt: float, k: int) -> None:
    rng = np.random.default_rng(1)
    buf = CommandBuffer(ta, dt, 200, (3, 2))
    cmds = rng.normal(size=(k, 3, 2))
    for j in range(k):
        buf.store(j, cmds[j])
    x, v = rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
    xp, vp = buf.predict(x, v)

    def a(s: float, r: int, c: int) -> float:  # executed at t_k + s: made at t_k + s - ta, the last one held
        m = k + (s - ta) / dt
        if m < 0.0:
            return 0.0
        i = min(int(np.floor(m)), k - 1)
        nxt = cmds[min(i + 1, k - 1), r, c]
        return float(cmds[i, r, c] + (m - i) * (nxt - cmds[i, r, c]))

    for r in range(3):
        for c in range(2):
            pts = [s for s in ta - dt * (k - np.arange(k + 1)) if 0 < s < ta]
            dv = quad(a, 0.0, ta, args=(r, c), points=pts, limit=500)[0]
            dx = quad(lambda s: (ta - s) * a(s, r, c), 0.0, ta, points=pts, limit=500)[0]
            assert vp[r, c] == pytest.approx(v[r, c] + dv, abs=1e-10)
            assert xp[r, c] == pytest.approx(x[r, c] + ta * v[r, c] + dx, abs=1e-10)


def test_prediction_is_where_the_run_goes() -> None:
    # the run's executed acceleration at t_j + ta is the command made at t_j: refill a buffer from it
    top, ta, dt = paper_six(), 0.2, 0.01
    run = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", duration=8.0, dt=dt,
                   actuation_delay=ta)  # fmt: skip
    lag = round(ta / dt)
    for k in (60, 300, 500):
        buf = CommandBuffer(ta, dt, run.times.size, (6, 2))
        for j in range(k):
            buf.store(j, run.inputs[j + lag])
        xp, vp = buf.predict(run.positions[k], run.velocities[k])
        # only the held last piece differs: O(dt^2) times the command's rate of change
        assert np.abs(xp - run.positions[k + lag]).max() < 1e-4
        assert np.abs(vp - run.velocities[k + lag]).max() < 1e-3


# ============================================================ the filter with a late command
def _crowded(**robot: object):
    # six double integrators on a line, 1 m apart, sent to a hexagon: unfiltered, they collide
    start = np.column_stack([np.arange(6.0), np.zeros(6)])
    return simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(model="double_integrator", **robot),
                    initial_positions=start, initial_speed=0.0, duration=30.0, dt=0.01)  # fmt: skip


@pytest.mark.parametrize("ta", [0.05, 0.15])
def test_filter_keeps_bodies_apart_under_an_actuation_delay(ta: float) -> None:
    free = _crowded(radius=0.17, actuation_delay=ta)
    safe = _crowded(radius=0.17, actuation_delay=ta, safety="barrier")
    assert free.contacts and not safe.contacts
    assert safe.safety is not None and safe.safety.was_active
    # every saved step from t = ta on (before it the robots coast, nothing executes a command):
    # the bodies stay apart, and the safe distance holds to the filter's own margin
    d = np.linalg.norm(safe.positions[:, :, None] - safe.positions[:, None, :], axis=-1)
    d[:, np.arange(6), np.arange(6)] = np.inf
    after = safe.times >= ta
    assert d[after].min() >= safe.safety.safe_distance - 0.02 and d.min() >= 2 * 0.17


def test_filter_changes_nothing_where_robots_stay_apart() -> None:
    far = 12.0 * named_formation("hexagon", 6)  # slots 12 m apart: no constraint ever binds
    kw = dict(model="double_integrator", radius=0.17, actuation_delay=0.1)
    run = dict(initial_positions=1.2 * far + [3.0, -2.0], duration=20.0, dt=0.01)
    a = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, far, robot=Robot(**kw), **run)
    b = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, far, robot=Robot(**kw, safety="barrier"), **run)
    assert b.safety is not None and not b.safety.was_active
    np.testing.assert_array_equal(a.positions, b.positions)


def test_filter_with_limits_and_an_actuation_delay_is_refused_with_the_reason() -> None:
    with pytest.raises(SimulationInputError, match="double integrators only"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.01,
                 robot=Robot(limits=IROBOT_CREATE, safety="barrier", actuation_delay=0.1))  # fmt: skip


# ============================================================ over an imperfect network
def _reference(top, P, D, T1, T2, ta, desired, x0, h, steps):
    """x_i'' = u_i(t - ta) with per-link delays T1[i, k], T2[i, k] (multiples of h), u = 0 before t = 0."""
    C = top.C_sparse.toarray()
    n = C.shape[0]
    F = formation_forcing(top, P, desired)
    X = np.zeros((steps + 1, n, 2))
    V = np.zeros((steps + 1, n, 2))
    U = np.zeros((steps + 1, n, 2))  # the command made at t_j
    X[0] = x0
    d1, d2, lag = np.rint(T1 / h).astype(int), np.rint(T2 / h).astype(int), round(ta / h)
    ii, kk = np.nonzero(C)

    def command(j: int) -> np.ndarray:
        cx, cv = np.zeros((n, 2)), np.zeros((n, 2))
        np.add.at(cx, ii, C[ii, kk, None] * X[np.maximum(j - d1[ii, kk], 0), kk])
        np.add.at(cv, ii, C[ii, kk, None] * V[np.maximum(j - d2[ii, kk], 0), kk])
        return P * (cx - X[j]) + D * (cv - V[j]) + F

    for j in range(steps):
        U[j] = command(j)
        # executed on [t_j, t_{j+1}]: linear from the command of j - lag to that of j + 1 - lag (0 before 0)
        a0 = U[j - lag] if j - lag >= 0 else 0.0
        a1 = U[j + 1 - lag] if j + 1 - lag > 0 else 0.0
        V[j + 1] = V[j] + h * (a0 + a1) / 2
        X[j + 1] = X[j] + h * V[j] + h * h * (2 * a0 + a1) / 6
    return X


def test_actuation_delay_over_per_link_delays_matches_an_independent_integration() -> None:
    top, P, D, ta = paper_six(), 1.0, 0.5, 0.1
    rng = np.random.default_rng(4)
    T1 = np.round(rng.uniform(0.2, 0.4, (6, 6)), 2)
    T2 = np.round(rng.uniform(0.1, 0.3, (6, 6)), 2)
    desired = named_formation("hexagon", 6)
    x0 = rng.uniform(-3, 3, (6, 2))
    net = Network(delays=LinkDelays(tau1=T1, tau2=T2))
    run = simulate(top, P, D, 0.3, 0.2, desired, model="double_integrator", network=net, initial_positions=x0,
                   initial_speed=0.0, duration=10.0, dt=0.01, actuation_delay=ta)  # fmt: skip
    ref = _reference(top, P, D, T1, T2, ta, desired, x0, 0.0025, 4000)
    scale = np.abs(ref[-1] - ref[0]).max()
    assert np.abs(run.positions[-1] - ref[-1]).max() < 2e-3 * scale
    # and it is not the run without the actuation delay
    plain = simulate(top, P, D, 0.3, 0.2, desired, model="double_integrator", network=net, initial_positions=x0,
                     initial_speed=0.0, duration=10.0, dt=0.01)  # fmt: skip
    assert np.abs(plain.positions[-1] - ref[-1]).max() > 20 * np.abs(run.positions[-1] - ref[-1]).max()


def test_uniform_links_are_the_ordinary_integrator_with_an_actuation_delay() -> None:
    top = paper_six()
    net = Network(delays=LinkDelays(tau1=np.full((6, 6), 0.3), tau2=np.full((6, 6), 0.2)))
    kw = dict(duration=10.0, dt=0.01, actuation_delay=0.1)
    for robot in ({"model": "double_integrator"}, {"limits": IROBOT_CREATE}):
        a = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", network=net, **robot, **kw)
        b = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", **robot, **kw)
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-10)


def test_lossy_network_with_an_actuation_delay_runs_and_differs() -> None:
    from delayform.model.network import BernoulliLoss

    kw = dict(model="double_integrator", duration=20.0, dt=0.01)
    net = Network(loss=BernoulliLoss(0.2), seed=2)
    late = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", network=net, actuation_delay=0.1, **kw)
    now = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", network=net, **kw)
    assert late.actuation_delay == 0.1 and np.all(np.isfinite(late.positions))
    assert np.abs(late.positions - now.positions).max() > 1e-3
    assert np.all(late.inputs[late.times < 0.1 - 1e-9] == 0.0)  # nothing executes before tau_a


def test_monte_carlo_runs_carry_the_actuation_delay() -> None:
    from delayform.simulation.experiments.montecarlo import monte_carlo, run_seeds
    from delayform.model.network import BernoulliLoss

    net = Network(loss=BernoulliLoss(0.2))
    mc = monte_carlo(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", network=net, runs=2, seed=3, duration=8.0, dt=0.02,
                     actuation_delay=0.1)  # fmt: skip
    assert mc.setup.actuation_delay == 0.1 and mc.setup.describe()["actuation_delay"] == 0.1
    # each run is simulate's run with the same seeds and the actuation delay
    (s0, n0) = run_seeds(3, 2)[0]
    one = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator",
                   network=net.with_seed(n0), seed=s0, duration=8.0, dt=0.02, actuation_delay=0.1)  # fmt: skip
    assert mc.errors[0][-1] == pytest.approx(float(one.formation_error[-1]), rel=1e-12)
