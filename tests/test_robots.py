"""Robots as they are: actuator limits, the saturated unicycle, and the commands each robot executes.

The saturated unicycle is checked against scipy's solve_ivp (DOP853, error
controlled, by the method of steps) on the same limited dynamics written out
again here from the docstring of ``LimitedUnicycle``; its step convergence
against a 10x finer step; its commands against the limits.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from delayform.errors import ResourceLimitError, SimulationInputError
from delayform.model.limits import FORWARD_BIAS
from delayform.formation import formation_forcing, named_formation
from delayform.simulation import IROBOT_CREATE, RobotCommands, RobotLimits, simulate
from delayform.topology import complete, paper_six

P, D = 1.0, 0.5
POINT_A = (0.3, 0.2)


def limited_rhs(theta, v, u, lim):
    """The saturated unicycle's (omega, dv/dt), written from the LimitedUnicycle docstring."""
    c, s = np.cos(theta), np.sin(theta)
    along, across = c * u[:, 0] + s * u[:, 1], -s * u[:, 0] + c * u[:, 1]
    size = np.hypot(u[:, 0], u[:, 1])
    cap = min(lim.max_speed, lim.wheel_radius * lim.max_wheel_speed)
    acc = np.clip(along, -lim.max_acceleration, lim.max_acceleration)
    acc = np.where(acc * v > 0, acc * np.clip(1 - (np.abs(v) / cap) ** 8, 0, 1), acc)
    vs = np.sqrt(lim.slow_speed**2 + (lim.turn_time_constant * size) ** 2)
    toward = along / np.maximum(size, 1e-300) + FORWARD_BIAS  # towards u's line at rest, forward where across
    wanted = np.clip(across * (v + toward * vs) / (v**2 + vs**2),
                     -lim.max_turn_rate, lim.max_turn_rate)
    rim = lim.wheel_radius * lim.max_wheel_speed
    allowed = np.maximum(rim - lim.axle_length / 2 * np.abs(wanted), 0)
    brake = np.clip((np.abs(v) - allowed) / (0.1 * lim.max_acceleration), 0, 1)
    acc = (1 - brake) * acc - brake * np.sign(v) * lim.max_acceleration
    omega = np.clip(wanted, -np.clip(2 * (rim - np.abs(v)) / lim.axle_length, 0, None),
                    np.clip(2 * (rim - np.abs(v)) / lim.axle_length, 0, None))
    return np.minimum(np.abs(omega), lim.max_turn_rate) * np.sign(omega), acc


def limited_reference(topology, tau1, tau2, desired, x0, theta0, speed0, T, lim):
    """solve_ivp on the saturated unicycle, piece by piece at the delays' breakpoints.

    ``tau1`` and ``tau2`` are scalars (every link) or ``(n, n)`` matrices of per-link delays.
    """
    n, C = topology.n, topology.C
    F = formation_forcing(topology, P, desired)
    v0 = speed0[:, None] * np.column_stack([np.cos(theta0), np.sin(theta0)])
    links = np.argwhere(C != 0)
    d1, d2 = (np.broadcast_to(np.asarray(tau, dtype=float), (n, n)) for tau in (tau1, tau2))
    delays = sorted({float(d1[i, k]) for i, k in links} | {float(d2[i, k]) for i, k in links})
    h = min(delays)
    marks = sorted({round(k * h, 12) for k in range(int(T / h) + 1)} | {T})
    pieces = []

    def cart(y):
        th, v = y[2 * n : 3 * n], y[3 * n :]
        return y[: 2 * n].reshape(n, 2), v[:, None] * np.column_stack([np.cos(th), np.sin(th)])

    def past(t):
        if t <= 0:
            return x0, v0
        for t0, t1, sol in pieces:
            if t0 - 1e-9 <= t <= t1 + 1e-9:
                return cart(sol(t))
        raise AssertionError(t)

    def rhs(t, y):
        X, V = cart(y)
        heard = {d: past(t - d) for d in delays}
        cx, cv = np.zeros((n, 2)), np.zeros((n, 2))
        for i, k in links:
            cx[i] += C[i, k] * heard[float(d1[i, k])][0][k]
            cv[i] += C[i, k] * heard[float(d2[i, k])][1][k]
        u = P * (cx - X) + D * (cv - V) + F
        th, v = y[2 * n : 3 * n], y[3 * n :]
        omega, acc = limited_rhs(th, v, u, lim)
        return np.concatenate([V.ravel(), omega, acc])

    y = np.concatenate([x0.ravel(), theta0, speed0])
    for t0, t1 in zip(marks[:-1], marks[1:]):
        sol = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)
        assert sol.success
        pieces.append((t0, t1, sol.sol))
        y = sol.y[:, -1]
    return y[: 2 * n].reshape(n, 2)


def moving_start(seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-3, 3, (6, 2)), 0.4 + rng.uniform(-0.3, 0.3, 6), 0.3 + rng.uniform(0, 0.1, 6)


# ------------------------------------------------------------ the limits
def test_irobot_create_defaults_and_bad_limits():
    lim = IROBOT_CREATE
    # Create OI: 500 mm/s per wheel and for the centre; 258 mm wheel base
    assert lim.max_speed == 0.5 and lim.wheel_radius * lim.max_wheel_speed == pytest.approx(0.5)
    assert lim.max_turn_rate == pytest.approx(2 * 0.5 / 0.258)
    for bad in (dict(max_speed=-1.0), dict(axle_length=0.0), dict(max_turn_rate=math.inf),
                dict(max_acceleration="fast"), dict(wheel_radius=True)):  # fmt: skip
        with pytest.raises(SimulationInputError, match=next(iter(bad))):
            RobotLimits(**bad)


def test_saturated_run_matches_error_controlled_integration_at_second_order():
    """Observed order against solve_ivp on the same saturated dynamics: stated order 2."""
    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    x0, th0, v0 = moving_start(5)
    lim = replace(IROBOT_CREATE, max_turn_rate=1.0)
    T = 2.0
    ref = limited_reference(topo, *POINT_A, desired, x0, th0, v0, T, lim)
    # a robot reverses through v = 0 at t = 0.74 s, where the softened turn law changes over v_s ~ tau_h |u|
    # (a heading loop up to ~1 / tau_h = 20 /s) and the turn-rate clip switches: steps from 0.01 s resolve it
    dts = np.array([0.01, 0.005, 0.0025, 0.00125, 0.000625])
    errors = []
    for dt in dts:
        traj = simulate(topo, P, D, *POINT_A, desired, initial_positions=x0, initial_headings=th0,
                        initial_speed=v0, limits=lim, duration=T, dt=dt)
        errors.append(np.abs(traj.positions[-1] - ref).max())
    assert traj.stated_order == 2
    # the limits were active (otherwise this would test the smooth case)
    names = {e.limit_name for e in traj.commands.exceedances()}
    assert {"turn rate", "acceleration"} <= names, names
    # the switches of the limits fall anywhere in a step, so the error falls unevenly;
    # the least-squares slope over five halvings is the stated order
    order = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert abs(order - 2) < 0.25 and errors[-1] < 1e-5, (order, errors)


def test_paper_robots_with_create_limits_converge_in_the_step_and_respect_every_limit():
    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    kw = dict(duration=5.0, seed=0, limits=IROBOT_CREATE)
    coarse = simulate(topo, P, D, *POINT_A, desired, dt=0.01, **kw)
    fine = simulate(topo, P, D, *POINT_A, desired, dt=0.001, save_every=10, **kw)
    np.testing.assert_allclose(fine.times, coarse.times)
    assert np.abs(coarse.positions - fine.positions).max() < 1e-3
    for run in (coarse, fine):
        assert run.commands.limited and run.commands.executed_within_limits()
        lim = run.limits
        assert np.abs(run.speeds).max() <= lim.max_speed * (1 + 1e-6)
        wheels = np.maximum(np.abs(run.commands.wheel_left), np.abs(run.commands.wheel_right))
        assert wheels.max() <= lim.max_wheel_speed * (1 + 1e-6)
    # the ideal commands of the paper's start are far beyond a Create's
    assert "turn rate" in coarse.commands.summary()


def test_limits_slow_a_stable_pair_and_the_summary_names_the_limit():
    pair = complete(2)
    desired = np.array([[0.0, 0.0], [1.0, 0.0]])
    kw = dict(initial_positions=[[-2.0, 0.5], [2.0, -0.5]], initial_headings=[2.0, 0.3], duration=60.0, dt=0.02)
    ideal = simulate(pair, P, D, *POINT_A, desired, **kw)
    slow = simulate(pair, P, D, *POINT_A, desired, limits=replace(IROBOT_CREATE, max_acceleration=0.05), **kw)
    assert ideal.status == "settled" and ideal.settling_time < 15.0
    assert not slow.settling_time < 3 * ideal.settling_time  # much slower, or not at all
    found = {e.limit_name: e for e in slow.commands.exceedances()}
    assert found["acceleration"].limit == 0.05 and found["acceleration"].needed > 1.0
    assert "acceleration" in slow.commands.summary() and "the limit is 0.05" in slow.commands.summary()
    if slow.status != "settled":
        assert any("acceleration" in w for w in slow.warnings)


# ---------------------------------------------- ideal robots' commands
def test_ideal_robot_reverses_through_zero_speed_without_turning():
    """Two robots on the x axis: their velocity reverses along the axis, so the heading
    never changes (omega = 0) and v changes sign (eq. transform2's limit at v -> 0)."""
    pair = complete(2)
    traj = simulate(pair, P, D, 0.0, 0.0, np.array([[0.0, 0.0], [1.0, 0.0]]),
                    initial_positions=[[-1.0, 0.0], [1.0, 0.0]], initial_headings=[0.0, 0.0],
                    initial_speed=[-1.0, 1.0], duration=10.0, dt=0.01)  # fmt: skip
    assert np.all(traj.headings == 0.0) and np.all(traj.inputs[..., 1] == 0.0)
    assert traj.speeds[:, 1].min() < -0.1 < 0.1 < traj.speeds[:, 1].max()
    # the double integrator's velocity along x equals the robot's v cos(theta)
    np.testing.assert_allclose(traj.velocities[:, 1, 0], traj.speeds[:, 1], atol=1e-12)


def test_ideal_robots_hold_their_heading_at_rest():
    traj = simulate(paper_six(), P, D, *POINT_A, "hexagon", duration=150.0, dt=0.05, seed=0)
    rest = (np.abs(traj.speeds) < 1e-3) & (np.hypot(*np.moveaxis(traj.velocities, -1, 0)) < 1e-3)
    late = traj.times > 120.0
    assert rest[late].all()  # arrived
    assert np.all(traj.inputs[late, :, 1] == 0.0)  # no spinning in place
    assert np.ptp(np.unwrap(traj.headings[late], axis=0), axis=0).max() == 0.0


def test_commands_files_and_figure(tmp_path):
    traj = simulate(paper_six(), P, D, *POINT_A, "hexagon", duration=3.0, dt=0.05, limits=IROBOT_CREATE)
    cmd = traj.commands
    assert isinstance(cmd, RobotCommands) and cmd.n == 6
    table = np.loadtxt(cmd.to_csv(tmp_path / "c.csv"), delimiter=",", skiprows=1)
    assert table.shape == (61 * 6, 9) and set(table[:, 1]) == set(range(1, 7))
    np.testing.assert_allclose(table[:, 2], cmd.speed.reshape(-1), rtol=1e-9)
    # wheel speeds are the differential drive's: (v -+ omega L / 2) / r
    L, r = IROBOT_CREATE.axle_length, IROBOT_CREATE.wheel_radius
    np.testing.assert_allclose(cmd.wheel_right, (cmd.speed + cmd.turn_rate * L / 2) / r)
    with np.load(cmd.to_npz(tmp_path / "c.npz")) as npz:
        saved = dict(npz)
    np.testing.assert_array_equal(saved["omega"], cmd.turn_rate)
    axes = cmd.plot()
    assert len(axes) == 3 and axes[0].get_ylabel() == "v (m/s)"
    limit_lines = [ln for ln in axes[1].lines if ln.get_linestyle() == "--"]
    assert sorted(ln.get_ydata()[0] for ln in limit_lines) == pytest.approx([-IROBOT_CREATE.max_turn_rate,
                                                                              IROBOT_CREATE.max_turn_rate])  # fmt: skip


# -------------------------------------------------- resources and divergence
def test_huge_delays_run_in_a_bounded_history():
    import time

    start = time.perf_counter()
    for model in ("double_integrator", "unicycle"):
        traj = simulate(paper_six(), P, D, 1e6, 1e6, "hexagon", model=model, duration=5.0, dt=0.01)
        assert np.all(np.isfinite(traj.positions)) and traj.times[-1] == pytest.approx(5.0)
    traj = simulate(paper_six(), P, D, 1e6, 1e6, "hexagon", limits=IROBOT_CREATE, duration=2.0, dt=0.01)
    assert np.all(np.isfinite(traj.positions))
    # tau1 = 50 s once asked for 60 GiB of per-delay step maps: now a few lags, whatever the delay
    traj = simulate(paper_six(), P, D, 50.0, 0.2, "hexagon", model="double_integrator", duration=150.0, dt=0.01)
    assert np.all(np.isfinite(traj.positions))
    assert time.perf_counter() - start < 5.0
    # with both delays beyond the run, each robot only sees the constant initial history
    traj = simulate(paper_six(), P, D, 1e6, 50.0, "hexagon", model="double_integrator", duration=5.0, dt=0.01)
    same = simulate(paper_six(), P, D, 7.0, 50.0, "hexagon", model="double_integrator", duration=5.0, dt=0.01)
    np.testing.assert_array_equal(traj.positions, same.positions)


@pytest.mark.parametrize("kwargs, setting", [
    (dict(duration=1e7, dt=1e-4), "duration"),
    (dict(duration=1e5, dt=1e-3, model="double_integrator"), "dt"),
])  # fmt: skip
def test_runs_beyond_the_machine_are_refused_up_front(kwargs, setting):
    import time

    start = time.perf_counter()
    with pytest.raises(ResourceLimitError, match=setting) as info:
        simulate(paper_six(), P, D, *POINT_A, "hexagon", **kwargs)
    assert time.perf_counter() - start < 5.0
    assert "\n" not in str(info.value) and "would" in str(info.value)


def test_unstable_run_stops_cleanly_and_says_so():
    traj = simulate(paper_six(), P, D, 1.0, 2.0, "hexagon", duration=600.0, dt=0.05, seed=1)
    assert traj.status in ("stopped", "diverging") and traj.warnings
    assert math.isinf(traj.settling_time)
    for arr in (traj.positions, traj.speeds, traj.headings, traj.inputs, traj.formation_error):
        assert np.all(np.isfinite(arr))
    assert traj.status == "stopped" and traj.times[-1] < 600.0 and "diverged" in traj.warnings[0]
    short = simulate(paper_six(), P, D, 1.0, 2.0, "hexagon", duration=100.0, dt=0.05, seed=1)
    assert short.status == "diverging" and "grew" in short.warnings[0]


# ------------------------------------------- robots with limits over a network
def test_limited_robots_over_the_ideal_or_a_uniform_per_link_network_are_todays_limited_run():
    from delayform.model.network import LinkDelays, Network

    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    x0, th0, v0 = moving_start(2)
    kw = dict(initial_positions=x0, initial_headings=th0, initial_speed=v0, limits=IROBOT_CREATE,
              duration=6.0, dt=0.02)  # fmt: skip
    ref = simulate(topo, P, D, *POINT_A, desired, **kw)
    uniform = Network(delays=LinkDelays(tau1=np.full((6, 6), POINT_A[0]), tau2=np.full((6, 6), POINT_A[1])))
    assert not uniform.is_ideal  # the per-link integrator, not the ordinary one
    for net in (Network(), uniform):
        got = simulate(topo, P, D, *POINT_A, desired, network=net, **kw)
        for name in ("positions", "headings", "speeds", "inputs"):
            assert np.max(np.abs(getattr(got, name) - getattr(ref, name))) < 1e-12, name
        assert np.max(np.abs(got.commands.wheel_left - ref.commands.wheel_left)) < 1e-12
        assert got.status == ref.status and got.stated_order == 2


def test_limited_robots_with_per_link_delays_match_solve_ivp_at_the_stated_order():
    """Per-link constant delays, limits active: against solve_ivp by the method of steps (per-link reads)."""
    from delayform.model.network import LinkDelays, Network

    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    x0, th0, v0 = moving_start(5)
    rng = np.random.default_rng(7)
    d1 = rng.choice([0.2, 0.3, 0.45], size=(6, 6))
    d2 = rng.choice([0.2, 0.25, 0.4], size=(6, 6))
    lim = replace(IROBOT_CREATE, max_turn_rate=1.0)
    T = 3.0
    ref = limited_reference(topo, d1, d2, desired, x0, th0, v0, T, lim)
    net = Network(delays=LinkDelays(tau1=d1, tau2=d2))
    dts = np.array([0.04, 0.02, 0.01, 0.005, 0.0025])
    errors = []
    for dt in dts:
        traj = simulate(topo, P, D, *POINT_A, desired, initial_positions=x0, initial_headings=th0,
                        initial_speed=v0, limits=lim, duration=T, dt=dt, network=net)  # fmt: skip
        errors.append(np.abs(traj.positions[-1] - ref).max())
    assert traj.stated_order == 2
    assert {"turn rate", "acceleration"} <= {e.limit_name for e in traj.commands.exceedances()}
    order = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert abs(order - 2) < 0.25 and errors[2] < 1e-3 and errors[-1] < 1e-5, (order, errors)
    # the per-link delays matter: the uniform run at point a is far from the reference
    uniform = simulate(topo, P, D, *POINT_A, desired, initial_positions=x0, initial_headings=th0,
                       initial_speed=v0, limits=lim, duration=T, dt=0.0025)  # fmt: skip
    assert np.abs(uniform.positions[-1] - ref).max() > 100 * errors[-1]


def test_no_executed_command_beyond_a_limit_under_30_percent_loss():
    from delayform.model.network import BernoulliLoss, Jitter, Network

    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    net = Network(loss=BernoulliLoss(0.3), jitter=Jitter(0.05, 0.05), seed=4)
    traj = simulate(topo, P, D, *POINT_A, desired, seed=1, limits=IROBOT_CREATE, duration=40.0, dt=0.02, network=net)
    cmd = traj.commands
    assert cmd.limited and cmd.executed_within_limits()
    assert np.abs(traj.speeds).max() <= IROBOT_CREATE.max_speed * (1 + 1e-6)
    assert np.maximum(np.abs(cmd.wheel_left), np.abs(cmd.wheel_right)).max() <= IROBOT_CREATE.max_wheel_speed * (1 + 1e-6)
    # the limits were needed (the ideal demands exceed them) and the lossy run still forms
    assert cmd.exceedances() and traj.formation_error[-1] < 0.1 * traj.formation_error[0]


def test_monte_carlo_with_limits_and_loss_is_reproducible_from_the_seed():
    from delayform.simulation import monte_carlo
    from delayform.model.network import BernoulliLoss, Network

    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    kw = dict(network=Network(loss=BernoulliLoss(0.3)), runs=3, duration=10.0, dt=0.05, limits=IROBOT_CREATE,
              model="unicycle")  # fmt: skip
    a, b = (monte_carlo(topo, P, D, *POINT_A, desired, seed=11, **kw) for _ in range(2))
    other = monte_carlo(topo, P, D, *POINT_A, desired, seed=12, **kw)
    for name in ("errors", "settling_times", "final_errors", "peak_commands"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert not np.array_equal(a.errors, other.errors)
    # peak commands (|dv/dt|, |omega|) are the executed ones, within the limits
    bound = np.array([IROBOT_CREATE.max_acceleration, IROBOT_CREATE.max_turn_rate]) * (1 + 1e-6)
    assert a.command_names[1] and np.all(a.peak_commands <= bound), a.peak_commands
