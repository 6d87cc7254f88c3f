"""Imperfect networks: the ideal case is today's simulate, per-link delays against an independent
DDE integration, what agents hear under loss, jitter and sampling, and the bursty-loss chain."""

from __future__ import annotations

import bisect

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from delayform.errors import NetworkError
from delayform.formation import formation_forcing, named_formation
from delayform.simulation import simulate
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
from delayform.simulation.delayed.reception import _loss_mask, reception
from delayform.topology import paper_six, ring

TOPO = paper_six()
SHAPE = named_formation("hexagon", 6, spacing=2.0)
X0 = np.array([[-4.0, 1.0], [3.0, 4.0], [0.5, -3.0], [4.0, -1.0], [-2.0, -4.0], [1.0, 2.5]])


def run(network=None, *, tau=(0.3, 0.2), model="double_integrator", duration=20.0, dt=0.05, **kw):
    return simulate(TOPO, 1.0, 0.5, *tau, SHAPE, model=model, initial_positions=X0, initial_headings=np.linspace(-3, 3, 6),
                    duration=duration, dt=dt, network=network, **kw)  # fmt: skip


# ------------------------------------------------------------ the ideal network
@pytest.mark.parametrize("model", ["double_integrator", "unicycle"])
@pytest.mark.parametrize(
    "network",
    [Network(), Network(delays=LinkDelays()), Network(jitter=Jitter(0, 0), loss=BernoulliLoss(0.0),
                                                      noise=MeasurementNoise(), variation=SmoothVariation())],
    ids=["empty", "uniform-delays", "all-off"],
)
def test_ideal_network_gives_todays_simulate(model: str, network: Network) -> None:
    assert network.is_ideal
    ref, got = run(model=model), run(network, model=model)
    for name in ("positions", "headings", "speeds", "inputs"):
        assert np.max(np.abs(getattr(got, name) - getattr(ref, name))) < 1e-12


@pytest.mark.parametrize("tau", [(0.3, 0.2), (0.33, 0.21), (0.0, 0.2), (2.0, 1.0)])
def test_equal_per_link_delays_are_the_uniform_case(tau: tuple[float, float]) -> None:
    net = Network(delays=LinkDelays(tau1=np.full((6, 6), tau[0]), tau2=np.full((6, 6), tau[1])))
    assert not net.is_ideal  # runs the per-link integrator, not the ordinary one
    ref, got = run(tau=tau), run(net, tau=tau)
    assert np.max(np.abs(got.positions - ref.positions)) < 1e-12
    assert np.max(np.abs(got.inputs - ref.inputs)) < 1e-12


def _method_of_steps(d1: np.ndarray, d2: np.ndarray, duration: float, x0: np.ndarray, v0: np.ndarray):
    """Independent DDE solution with per-link delays: solve_ivp (DOP853) segment by segment.

    Each segment is as long as the shortest delay, so every delayed value lies in a
    finished segment and is read from its dense output (constant history before 0).
    """
    n = TOPO.n
    C = TOPO.C_sparse.toarray()
    F = formation_forcing(TOPO, 1.0, SHAPE)
    P, D = 1.0, 0.5
    links = np.argwhere(C > 0)
    delays = sorted(set(d1[C > 0]) | set(d2[C > 0]))
    starts: list[float] = []
    sols: list = []

    def state_at(t: float) -> np.ndarray:
        if t <= 0.0:
            return np.concatenate([x0.ravel(), v0.ravel()])
        i = bisect.bisect_right(starts, t) - 1
        return sols[i](t)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        past = {d: state_at(t - d).reshape(2, n, 2) for d in delays}
        x, v = y.reshape(2, n, 2)
        cx, cv = np.zeros((n, 2)), np.zeros((n, 2))
        for i, k in links:
            cx[i] += C[i, k] * past[d1[i, k]][0, k]
            cv[i] += C[i, k] * past[d2[i, k]][1, k]
        u = P * (cx - x) + D * (cv - v) + F
        return np.concatenate([v.ravel(), u.ravel()])

    h = min(delays)
    y = np.concatenate([x0.ravel(), v0.ravel()])
    t0 = 0.0
    while t0 < duration - 1e-12:
        t1 = min(t0 + h, duration)
        sol = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
        starts.append(t0)
        sols.append(sol.sol)
        y, t0 = sol.y[:, -1], t1
    return state_at


def test_per_link_delays_match_an_independent_integration() -> None:
    rng = np.random.default_rng(5)
    d1 = rng.choice([0.2, 0.3, 0.45, 0.6], size=(6, 6))
    d2 = rng.choice([0.2, 0.25, 0.4], size=(6, 6))
    net = Network(delays=LinkDelays(tau1=d1, tau2=d2))
    traj = run(net, duration=12.0, dt=0.01)
    speed = 1e-3
    v0 = speed * np.column_stack([np.cos(np.linspace(-3, 3, 6)), np.sin(np.linspace(-3, 3, 6))])
    exact = _method_of_steps(d1, d2, 12.0, X0, v0)
    ref = np.array([exact(t)[: 12].reshape(6, 2) for t in traj.times[::20]])
    err = np.max(np.abs(traj.positions[::20] - ref))
    assert err < 1e-4, err
    # and the per-link delays matter: the uniform run at the mean delays is far off
    assert np.max(np.abs(run(tau=(0.3, 0.2), duration=12.0, dt=0.01).positions[::20] - ref)) > 100 * err


def test_ideal_robots_over_equal_per_link_delays_are_the_ideal_robots() -> None:
    """Over a network the unicycle is rebuilt from its double-integrator motion, as ideal robots are without one."""
    net = Network(delays=LinkDelays(tau1=np.full((6, 6), 0.3), tau2=np.full((6, 6), 0.2)))
    robot, rebuilt = run(model="unicycle", duration=30.0), run(net, model="unicycle", duration=30.0)
    for name, tol in (("positions", 1e-12), ("speeds", 1e-12), ("inputs", 1e-10)):
        # omega = (V x U) / |V|^2 reaches 5e3 at the start (v = 1e-3): rounding of V grows by 1 / |V|
        a, b = getattr(rebuilt, name), getattr(robot, name)
        assert np.max(np.abs(a - b) / (1.0 + np.abs(b))) < tol, name
    assert np.max(np.abs(np.angle(np.exp(1j * (rebuilt.headings - robot.headings))))) < 1e-10
    assert rebuilt.status == robot.status == "settled"


def test_an_unstable_run_stops_before_it_overflows() -> None:
    """Point c is unstable (dominant root +0.084): the run stops and says so, with no overflow."""
    traj = simulate(TOPO, 1.0, 0.5, 1.0, 2.0, SHAPE, model="double_integrator", initial_positions=X0,
                    duration=2000.0, dt=0.05, network=Network(loss=BernoulliLoss(0.2)))  # fmt: skip
    assert traj.times[-1] < 2000.0 and np.all(np.isfinite(traj.positions))
    assert traj.status != "settled"


# ------------------------------------------------------------ loss at point a
def test_loss_zero_converges_like_the_ideal_run() -> None:
    ideal = run(duration=60.0)
    assert Network(loss=BernoulliLoss(0.0)).is_ideal
    # packets every step (hold between steps) without loss: the same convergence
    held = run(Network(loss=BernoulliLoss(0.0), sampling=Sampling(20.0)), duration=60.0)
    assert held.settling_time == pytest.approx(ideal.settling_time, rel=0.05)
    assert held.formation_error[-1] < 1e-3 * held.formation_error[0]
    assert np.max(np.abs(held.final_positions - ideal.final_positions)) < 0.05


def test_loss_on_every_link_of_an_agent_freezes_what_it_hears() -> None:
    """Agent 2 loses everything: it hears its informers' initial states, and moves as that frozen input dictates."""
    lost = np.zeros((6, 6))
    lost[2] = 1.0
    net = Network(loss=BernoulliLoss(lost), jitter=Jitter(0.05, 0.05), seed=3)
    rec = reception(net, TOPO, 0.3, 0.2, dt=0.05, steps=400)
    into = rec.receivers == 2
    for s in range(2):
        assert np.all(rec.send[s][..., into] == 0.0) and np.all(rec.packet[s][..., into] == -1)
        assert np.any(rec.send[s][..., ~into] > 0.0)
    traj = run(net, duration=20.0, dt=0.05)
    # closed form: x'' = P (c - x) + D (w - v) + F with constant c, w, per coordinate
    C = TOPO.C_sparse.toarray()
    speed = 1e-3
    v0 = speed * np.column_stack([np.cos(np.linspace(-3, 3, 6)), np.sin(np.linspace(-3, 3, 6))])
    F = formation_forcing(TOPO, 1.0, SHAPE)
    c, w = C[2] @ X0, C[2] @ v0
    M = np.array([[0.0, 1.0], [-1.0, -0.5]])
    target = c + F[2] + 0.5 * w  # the rest point of x: P x = P c + D w + F
    for t, x in zip(traj.times[::40], traj.positions[::40, 2], strict=True):
        for axis in range(2):
            z = expm(M * t) @ np.array([X0[2, axis] - target[axis], v0[2, axis]])
            assert abs(x[axis] - (target[axis] + z[0])) < 1e-5


def test_loss_03_at_point_a_monte_carlo_reports_the_spread() -> None:
    from delayform.simulation.experiments.montecarlo import monte_carlo

    mc = monte_carlo(TOPO, 1.0, 0.5, 0.3, 0.2, SHAPE, network=Network(loss=BernoulliLoss(0.3)), runs=20, seed=7,
                     duration=40.0, dt=0.05, initial_positions=X0)  # fmt: skip
    s = mc.summary()["settling_time"]
    assert mc.settled_fraction == 1.0  # point a is stable with margin: 30 % loss does not break it
    assert s["q05"] < s["median"] < s["q95"]  # the seeds spread the outcome
    assert np.unique(mc.settling_times).size > 5
    ideal = run(duration=40.0)
    assert s["median"] > ideal.settling_time  # holding old values slows the formation down
    assert dict(mc.table())["settled within the duration"] == "100 %"


# ------------------------------------------------------------ what is heard
@settings(max_examples=30)
@given(
    p=st.floats(0.0, 0.9),
    bound=st.floats(0.0, 0.15),
    rate=st.one_of(st.none(), st.sampled_from([2.0, 5.0, 20.0])),
    seed=st.integers(0, 2**16),
    bursty=st.booleans(),
)
def test_hold_last_value_properties(p: float, bound: float, rate: float | None, seed: int, bursty: bool) -> None:
    loss = GilbertElliott(p / 4 + 0.01, 0.3) if bursty else BernoulliLoss(p)
    net = Network(loss=loss, jitter=Jitter(bound, bound), sampling=None if rate is None else Sampling(rate), seed=seed)
    dt, steps = 0.05, 120
    rec = reception(net, ring(4), 0.3, 0.2, dt=dt, steps=steps)
    t = (np.arange(steps + 1)[:, None] + np.array([0.0, 0.5, 1.0])[None]) * dt
    for s, tau in enumerate((0.3, 0.2)):
        send, packet = rec.send[s], rec.packet[s]
        flat = send.reshape(-1, send.shape[-1])
        assert np.all(np.diff(flat, axis=0) >= 0.0)  # hold-last-value: never an older sample
        assert np.all(send <= np.maximum(t[..., None] - (tau - bound), 0.0) + 1e-9)  # nothing before it could arrive
        if net.packets:  # before the first packet: the initial state, which is also packet 0's sample
            assert np.all((send == 0.0) == ((packet == -1) | (packet == 0)))
        else:
            assert np.all(packet == -1)


def test_newest_packet_against_brute_force() -> None:
    net = Network(loss=BernoulliLoss(0.4), jitter=Jitter(0.25, 0.1), sampling=Sampling(10.0), seed=11)
    dt, steps = 0.05, 60
    rec = reception(net, ring(3), 0.3, 0.2, dt=dt, steps=steps)
    # rebuild the same draws and search by brute force, query by query
    seeds = np.random.SeedSequence(11).spawn(5)
    rng_jitter, rng_loss = np.random.default_rng(seeds[2]), np.random.default_rng(seeds[3])
    m = np.arange(int((steps + 1) * dt * 10.0) + 1)
    for s, (tau, bound) in enumerate(((0.3, 0.25), (0.2, 0.1))):
        arrival = m[:, None] / 10.0 + tau + bound * rng_jitter.uniform(-1, 1, size=(m.size, 3))
        lost = rng_loss.random((m.size, 3)) < 0.4
        rng_noise_draws = np.random.default_rng(seeds[4])  # noise stream untouched here
        del rng_noise_draws
        for k in range(0, steps + 1, 7):
            for j, c in enumerate((0.0, 0.5, 1.0)):
                q = (k + c) * dt
                for e in range(3):
                    ok = [i for i in m if arrival[i, e] <= q + 1e-9 * dt and not lost[i, e]]
                    assert rec.packet[s][k, j, e] == (max(ok) if ok else -1)


def test_sampling_with_constant_delay_is_a_zero_order_hold() -> None:
    rate, d = 4.0, 0.3
    rec = reception(Network(sampling=Sampling(rate)), ring(3), d, d, dt=0.05, steps=200)
    t = (np.arange(201)[:, None] + np.array([0.0, 0.5, 1.0])) * 0.05
    expected = np.maximum(np.floor((t - d) * rate + 1e-7), 0.0) / rate
    assert np.allclose(rec.send[0], expected[..., None])


def test_gilbert_elliott_statistics_match_the_chain() -> None:
    ge = GilbertElliott(0.02, 0.25)
    lost = _loss_mask(ge, np.zeros(4, dtype=np.intp), np.zeros(4, dtype=np.intp), 100_000, np.random.default_rng(2))
    assert lost.mean() == pytest.approx(ge.loss_rate, abs=0.01)
    # with loss_bad = 1, loss_good = 0 a burst is a sojourn in the bad state: geometric, mean 1 / p_bad_to_good
    edges = np.diff(lost[:, 0].astype(int))
    bursts = np.count_nonzero(edges == 1)
    assert lost[:, 0].sum() / bursts == pytest.approx(1 / 0.25, rel=0.1)
    bern = _loss_mask(BernoulliLoss(0.3), np.zeros(4, dtype=np.intp), np.zeros(4, dtype=np.intp), 50_000, np.random.default_rng(2))
    assert bern.mean() == pytest.approx(0.3, abs=0.01)


def test_noise_reaches_the_formation_and_is_seeded() -> None:
    noisy = Network(noise=MeasurementNoise(position=0.05), seed=1)
    a, b, c = run(noisy, duration=30.0), run(noisy, duration=30.0), run(noisy.with_seed(2), duration=30.0)
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    assert 1e-3 < a.formation_error[-1] < 0.2  # the shape is kept up to the noise, not exactly


def test_smoothly_varying_delays_match_an_independent_integration() -> None:
    """Continuous streams read x_k(t - d(t)); solve_ivp by steps with the same d(t) per link agrees."""
    topo, shape = ring(3), named_formation("polygon", 3)
    net = Network(variation=SmoothVariation(0.1, 0.05, period=4.0), seed=2)
    assert not net.packets and not net.is_ideal
    x0 = np.array([[2.0, 0.0], [-1.0, 2.0], [0.0, -2.0]])
    traj = simulate(topo, 1.0, 0.5, 0.4, 0.3, shape, model="double_integrator", initial_positions=x0,
                    initial_headings=np.zeros(3), initial_speed=0.0, duration=10.0, dt=0.01, network=net)  # fmt: skip
    rec = reception(net, topo, 0.4, 0.3, dt=0.01, steps=1)
    # recover each link's phase from the send times the integrator used: d(t) = t - send
    C, F = topo.C_sparse.toarray(), formation_forcing(topo, 1.0, shape)
    phases = np.random.default_rng(np.random.SeedSequence(2).spawn(5)[1]).uniform(0, 2 * np.pi, size=(2, 3))
    d0 = 0.4 + 0.1 * np.sin(phases[0])
    assert np.allclose(0.0 - rec.send[0][0, 0], d0)  # the same draws: phases of the network's seed
    starts: list[float] = []
    sols: list = []

    def state_at(t: float) -> np.ndarray:
        if t <= 0.0:
            return np.concatenate([x0.ravel(), np.zeros(6)])
        return sols[bisect.bisect_right(starts, t) - 1](t)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        x, v = y.reshape(2, 3, 2)
        cx, cv = np.zeros((3, 2)), np.zeros((3, 2))
        for e, (i, k) in enumerate(zip(rec.receivers, rec.informers, strict=True)):
            d1 = 0.4 + 0.1 * np.sin(2 * np.pi * t / 4.0 + phases[0, e])
            d2 = 0.3 + 0.05 * np.sin(2 * np.pi * t / 4.0 + phases[1, e])
            cx[i] += C[i, k] * state_at(t - d1).reshape(2, 3, 2)[0, k]
            cv[i] += C[i, k] * state_at(t - d2).reshape(2, 3, 2)[1, k]
        return np.concatenate([v.ravel(), (1.0 * (cx - x) + 0.5 * (cv - v) + F).ravel()])

    y, t0 = np.concatenate([x0.ravel(), np.zeros(6)]), 0.0
    while t0 < 10.0 - 1e-12:  # segments no longer than the shortest delay, 0.25 s
        sol = solve_ivp(rhs, (t0, min(t0 + 0.25, 10.0)), y, method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
        starts.append(t0)
        sols.append(sol.sol)
        y, t0 = sol.y[:, -1], min(t0 + 0.25, 10.0)
    ref = np.array([state_at(t)[:6].reshape(3, 2) for t in traj.times[::50]])
    assert np.max(np.abs(traj.positions[::50] - ref)) < 1e-4


# ------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: BernoulliLoss(1.5), "probability"),
        (lambda: BernoulliLoss([[0.1, 2.0], [0.0, 0.0]]), "probabilities"),
        (lambda: LinkDelays(spread=1.0), "spread"),
        (lambda: LinkDelays(tau1=[[0.1, -1.0], [0.0, 0.0]]), "non-negative"),
        (lambda: LinkDelays(tau1=[1.0, 2.0]), "square"),
        (lambda: SmoothVariation(1.0, 0.0, period=2.0), "rate"),
        (lambda: Sampling(0.0), "positive"),
        (lambda: MeasurementNoise(position=float("nan")), "finite"),
        (lambda: Network(loss=0.3), "BernoulliLoss"),
        (lambda: Network(seed=-1), "seed"),
        (lambda: run(Network(delays=LinkDelays(tau1=np.ones((3, 3))))), "6 x 6"),
        (lambda: run(Network(jitter=Jitter(0.3, 0.0))), "below the step"),
        (lambda: run(Network(delays=LinkDelays(tau1=np.full((6, 6), 0.01))), tau=(0.3, 0.2)), "below the step"),
    ],
)
def test_bad_networks_raise_network_error(make, match: str) -> None:
    with pytest.raises(NetworkError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_a_network_run_beyond_memory_is_refused_up_front() -> None:
    from delayform.errors import ResourceLimitError

    with pytest.raises(ResourceLimitError, match="of memory") as info:
        simulate(ring(2000), 1.0, 0.5, 0.3, 0.2, "polygon", model="double_integrator", duration=1e4, dt=0.01,
                 network=Network(loss=BernoulliLoss(0.1)))  # fmt: skip
    assert "\n" not in str(info.value)
