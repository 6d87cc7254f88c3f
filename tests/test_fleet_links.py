"""The scenario's network on real messages, per link: the controller's buffer, the simulator's draws, a run.

The references are independent of the code under test: the one-pair
playout path of the controller (for equal per-link delays), the simulator's
own reception schedule (:func:`delayform.simulation.delayed.reception.reception`)
for which packet a robot hears on a link at a time, and the simulator's run
of the same team over the same network for the decay of the formation error.
"""

from __future__ import annotations

import math
import socket
from pathlib import Path

import numpy as np
import pytest

from delayform.deploy import FormationController, NeighbourMessage
from delayform.errors import ControllerInputError
from delayform.fleet.plan import link_plan, packet_count
from delayform.model.network import BernoulliLoss, Jitter, LinkDelays, MeasurementNoise, Network, Sampling, SmoothVariation
from delayform.simulation.delayed.reception import reception
from delayform.topology import complete, paper_six

# per-link delays of three robots, row i what robot i receives (diagonal unused)
TAU1 = np.array([[0.0, 0.25, 0.40], [0.30, 0.0, 0.20], [0.35, 0.45, 0.0]])
TAU2 = np.array([[0.0, 0.15, 0.30], [0.20, 0.0, 0.10], [0.25, 0.30, 0.0]])


def _random_messages(rng: np.random.Generator, senders: tuple[int, ...], count: int) -> list[NeighbourMessage]:
    stamps = np.round(rng.uniform(-1.0, 6.0, size=count), 2)  # repeated stamps happen: they replace
    return [NeighbourMessage(int(rng.choice(senders)), float(t), *map(float, rng.normal(size=4))) for t in stamps]


def test_equal_matrices_give_the_one_pair_commands_bit_for_bit() -> None:
    """Random messages in any order, random ticks: one pair, equal matrices, per-message delays equal to the link's."""
    from delayform.deploy import robot_profile

    rng = np.random.default_rng(12)
    topo = paper_six()
    limits = robot_profile("create3").limits
    for robot in (1, 4):
        one = FormationController.from_design(topo, 1.0, 1.5, 0.3, 0.2, "hexagon", robot=robot, limits=limits)
        full = FormationController.from_design(topo, 1.0, 1.5, np.full((6, 6), 0.3), np.full((6, 6), 0.2), "hexagon",
                                               robot=robot, limits=limits)  # fmt: skip
        own = FormationController.from_design(topo, 1.0, 1.5, np.full((6, 6), 0.3), np.full((6, 6), 0.2), "hexagon",
                                              robot=robot, limits=limits)  # fmt: skip
        assert full.link_delays == {k: (0.3, 0.2) for k in one.neighbours}
        msgs = _random_messages(rng, tuple(range(1, 7)), 600)
        for start in range(0, 600, 50):
            for m in msgs[start:start + 50]:
                one.receive(m)
                full.receive(m)
                own.receive(m, (0.3, 0.2))
            for t in np.sort(rng.uniform(start / 100, start / 100 + 0.5, size=5)):
                state = (float(t), *map(float, rng.normal(size=3)), float(rng.uniform(-0.3, 0.3)))
                a, b, c = one.tick(*state), full.tick(*state), own.tick(*state)
                assert a == b == c  # NamedTuples of floats: bit-identical


def test_per_link_delays_pick_each_link_s_message() -> None:
    topo = complete(3)
    ctrl = FormationController.from_design(topo, 1.0, 1.5, TAU1, TAU2, "polygon", robot=1)
    assert ctrl.link_delays == {2: (0.25, 0.15), 3: (0.40, 0.30)}
    for m in range(100):  # a message every 10 ms from both neighbours
        for k in (2, 3):
            ctrl.receive(NeighbourMessage(k, m * 0.01, float(m), 0.0, float(-m), 0.0))
    heard = ctrl.heard(0.8)
    assert heard[2] == pytest.approx((0.55, 0.65))
    assert heard[3] == pytest.approx((0.40, 0.50))


def test_per_message_delays_hold_the_newest_due_message() -> None:
    """Jitter: a message due before an older one is used, and the older one never again (hold-last-value)."""
    ctrl = FormationController(robot=1, P=1.0, D=1.0, tau1=0.3, tau2=0.2, weights={2: 1.0})
    ctrl.receive(NeighbourMessage(2, 0.0, 0.0, 0.0, 0.0, 0.0))
    ctrl.receive(NeighbourMessage(2, 0.1, 1.0, 0.0, 0.0, 0.0), (0.5, 0.2))  # due at 0.6
    ctrl.receive(NeighbourMessage(2, 0.2, 2.0, 0.0, 0.0, 0.0), (0.25, math.inf))  # due at 0.45; velocity lost
    assert ctrl.heard(0.44)[2] == (0.0, 0.1)
    assert ctrl.heard(0.46)[2] == (0.2, 0.1)
    assert ctrl.heard(0.7)[2] == (0.2, 0.1)  # 0.1 came due later than the newer 0.2: never used
    for bad in ((-0.1, 0.2), (math.nan, 0.2), (0.1,), "x"):
        with pytest.raises(ControllerInputError):
            ctrl.receive(NeighbourMessage(2, 0.3, 0.0, 0.0, 0.0, 0.0), bad)  # type: ignore[arg-type]
    with pytest.raises(ControllerInputError, match="does not hear"):
        FormationController(robot=1, P=1.0, D=1.0, tau1=0.3, tau2=0.2, weights={2: 1.0}, link_delays={3: (0.1, 0.1)})
    with pytest.raises(ControllerInputError, match="3 x 3"):
        FormationController.from_design(complete(3), 1.0, 1.0, np.zeros((2, 2)), TAU2, "polygon", robot=1)


def test_the_plan_s_link_delays_are_the_simulator_s() -> None:
    """Drawn with a spread: the continuous streams' send times at t = 0 are minus each link's delay."""
    topo = paper_six()
    net = Network(delays=LinkDelays(spread=0.3), seed=21)
    rec = reception(net, topo, 0.3, 0.2, dt=0.01, steps=1)
    plan = link_plan(net, topo, 0.3, 0.2, dt=0.01, duration=0.01)
    assert np.array_equal(plan.receivers, rec.receivers) and np.array_equal(plan.informers, rec.informers)
    assert np.array_equal(plan.tau1, -rec.send[0][0, 0]) and np.array_equal(plan.tau2, -rec.send[1][0, 0])
    assert np.ptp(plan.tau1) > 0.05  # the spread did spread them
    fixed = link_plan(Network(delays=LinkDelays(TAU1, TAU2)), complete(3), 0.3, 0.2, dt=0.01, duration=1.0)
    m1, m2 = fixed.delay_matrices(3)
    assert np.array_equal(m1, TAU1) and np.array_equal(m2, TAU2)


NETWORKS = {
    "every-step": dict(jitter=Jitter(0.06, 0.04), loss=BernoulliLoss(0.25), noise=MeasurementNoise(0.01, 0.02)),
    "sampled": dict(jitter=Jitter(0.06, 0.04), loss=BernoulliLoss(0.25), sampling=Sampling(40.0),
                    noise=MeasurementNoise(0.01, 0.02)),  # fmt: skip
    # delays varying smoothly: heard continuously (x(t - d(t)) in the simulator), then as packets with jitter
    "varying": dict(variation=SmoothVariation(0.05, 0.04, 1.5)),
    "varying-sampled": dict(variation=SmoothVariation(0.05, 0.04, 1.5), jitter=Jitter(0.02, 0.01), sampling=Sampling(40.0)),
}


@pytest.mark.parametrize("parts", list(NETWORKS.values()), ids=list(NETWORKS))
def test_the_controller_hears_the_packet_the_simulator_hears(parts: dict, tmp_path: Path) -> None:
    """Per-link delays, jitter, variation and loss: at every stage time of the simulator, on every link, the same packet.

    The fleet's own path: the plan, the draws file each robot reads, its receiving side, its controller.
    Continuous streams (no packets in the simulator): the fleet hears the newest
    message sent at or before the simulator's send time ``t - d(t)``.
    """
    from delayform.fleet.agents import ReceivingSide
    from delayform.fleet.run import _save_draws

    topo = complete(3)
    net = Network(delays=LinkDelays(TAU1, TAU2), seed=9, **parts)
    dt, duration = 0.02, 3.0
    steps = round(duration / dt)
    rec = reception(net, topo, 0.3, 0.2, dt=dt, steps=steps)
    plan = link_plan(net, topo, 0.3, 0.2, dt=dt, duration=duration)
    assert plan.jitter is not None
    for s in range(2):
        assert (rec.noise[s] is None) == (plan.noise is None)
        if plan.noise is not None:
            assert np.array_equal(plan.noise[s], rec.noise[s])
    packets = packet_count(duration, dt, plan.period)
    assert plan.jitter.shape == (2, packets, plan.receivers.size)
    tau1, tau2 = plan.delay_matrices(3)
    queries = ((np.arange(steps + 1)[:, None] + np.array([0.0, 0.5, 1.0])) * dt)
    compared = 0
    for i in range(3):
        ctrl = FormationController.from_design(topo, 1.0, 1.5, tau1, tau2, "polygon", robot=i + 1)
        mine = plan.of_receiver(i + 1)
        side = ReceivingSide(ctrl.link_delays, plan.period, _save_draws(plan, mine, i + 1, tmp_path))
        for e in mine:  # packet m of informer k, at rest at the origin: what arrives is the network's noise
            k = int(plan.informers[e]) + 1
            for m in range(packets):
                message, delays = side.apply(NeighbourMessage(k, m * plan.period, 0.0, 0.0, 0.0, 0.0))
                lost = plan.lost is not None and plan.lost[0, m, e]
                assert delays[0] == (math.inf if lost else plan.tau1[e] + plan.jitter[0, m, e])
                if plan.noise is not None:
                    assert (message.x, message.vy) == (plan.noise[0, m, e, 0], plan.noise[1, m, e, 1])
                if delays[0] < math.inf or delays[1] < math.inf:
                    ctrl.receive(message, delays)
        for kk in range(steps + 1):
            for j in range(3):
                heard = ctrl.heard(float(queries[kk, j]))
                for e in mine:
                    k = int(plan.informers[e]) + 1
                    for s in range(2):
                        packet = rec.packet[s][kk, j, e]
                        if not net.packets:  # a continuous stream: the newest message sent by t - d(t)
                            sent = rec.send[s][kk, j, e] / plan.period
                            if sent < 0.0 or abs(sent - round(sent)) < 1e-9:  # the initial history, or a tie
                                continue
                            packet = math.floor(sent)
                        if packet >= 0:  # before the first packet both use the initial state
                            assert heard[k][s] == pytest.approx(packet * plan.period, abs=1e-12), (i, k, s, kk, j)
                            compared += 1
    assert compared > 0.75 * 3 * (steps + 1) * 6 * 2


def test_a_varying_delay_heard_continuously_is_the_simulator_s_at_its_reception_time() -> None:
    """Closed form: the value sent at s is heard at t with t - d - a sin(w t + phase) = s (the link's phase unknown).

    Whatever the phase, the extra delay lies within the amplitude and solves
    the equation to 1e-9 s; its spread over packets covers most of +-a.
    """
    from delayform.model.network import SmoothVariation

    var = SmoothVariation(0.05, 0.0, 2.0)
    plan = link_plan(Network(delays=LinkDelays(TAU1, TAU2), variation=var, seed=3), complete(3), 0.3, 0.2,
                     dt=0.01, duration=4.0)  # fmt: skip
    extra = plan.jitter[0]
    assert np.all(np.abs(extra) <= var.amplitude1 + 1e-12) and np.all(plan.jitter[1] == 0.0)
    assert np.ptp(extra, axis=0).min() > 1.5 * var.amplitude1  # every link swings through most of its range
    sent = np.arange(extra.shape[0])[:, None] * plan.period
    heard = sent + plan.tau1[None, :] + extra
    w = 2.0 * math.pi / var.period
    # the phase of each link from the first packet: a sin(w t + phase) = extra, two candidates, one fits all packets
    for e in range(extra.shape[1]):
        fits = []
        base = math.asin(extra[0, e] / var.amplitude1) - w * heard[0, e]
        for phase in (base, math.pi - 2.0 * w * heard[0, e] - base):
            residual = heard[:, e] - plan.tau1[e] - var.amplitude1 * np.sin(w * heard[:, e] + phase) - sent[:, 0]
            fits.append(np.abs(residual).max())
        assert min(fits) < 1e-9, fits  # the phase recovered through asin carries its rounding


# ------------------------------------------------------------------ a run
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_three_robots_hold_their_links_delays(tmp_path: Path) -> None:
    """Three processes, every link its own delays: each applied within a period, 10x down, the simulator's decay."""
    pytest.importorskip("zenoh")
    pytest.importorskip("mcap_ros2")
    from delayform.deploy import robot_profile
    from delayform.fleet import run_fleet
    from delayform.model import Delays, Start, Team

    h, duration = 0.02, 12.0
    start = np.array([[1.3, 0.0], [-0.5, 0.8], [-0.4, -0.9]])
    run = run_fleet(Team(complete(3), 1.0, 1.5), Delays(0.3, 0.2), "polygon", out=tmp_path, duration=duration,
                    period=h, robot=robot_profile("create3"), start=Start(start, np.zeros(3), speed=0.0),
                    network=Network(delays=LinkDelays(TAU1, TAU2)), endpoint=f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
    links = run.summary["links"]
    assert len(links) == 6
    for link in links:
        i, k = link["receiver"] - 1, link["informer"] - 1
        assert (link["design_tau1_s"], link["design_tau2_s"]) == (TAU1[i, k], TAU2[i, k])
        assert abs(link["measured_tau1_s"] - TAU1[i, k]) <= h, link
        assert abs(link["measured_tau2_s"] - TAU2[i, k]) <= h, link
        assert link["within_one_period"]
    team = run.summary["team"]
    assert team["per_link_delays"] is True
    assert team["error_reduction"] > 10.0
    assert team["measured_decay_rate"] == pytest.approx(team["simulator_decay_rate"], rel=0.3)


def test_the_summary_s_applied_delay_is_the_message_the_controller_used() -> None:
    """The measurement from the logs (stamps, receipts, delays) against the controller fed the same messages live."""
    from delayform.fleet.outcome import _applied

    rng = np.random.default_rng(5)
    h, tau1, tau2 = 0.02, 0.3, 0.2
    m = np.arange(-50, 400)
    stamps = m * h + rng.uniform(0.0, 0.002, m.size)  # sent at the tick, a little late
    receipts = stamps + rng.uniform(0.0005, 0.004, m.size)
    d1 = np.where(m >= 0, tau1 + rng.uniform(-0.05, 0.05, m.size), tau1)  # jitter from t = 0 on
    d2 = np.where(m >= 0, tau2 + rng.uniform(-0.03, 0.03, m.size), tau2)
    d1[(m >= 0) & (rng.random(m.size) < 0.2)] = math.inf  # the network loses a fifth of the positions
    ticks = np.arange(0, 380) * h + rng.uniform(0.0, 0.003, 380)
    ctrl = FormationController(robot=1, P=1.0, D=1.0, tau1=tau1, tau2=tau2, weights={2: 1.0})
    used = []
    j = 0
    for t in ticks:  # live: the messages received by the tick, then the tick
        while j < m.size and receipts[j] <= t:
            ctrl.receive(NeighbourMessage(2, float(stamps[j]), 0.0, 0.0, 0.0, 0.0), (float(d1[j]), float(d2[j])))
            j += 1
        used.append(ctrl.heard(float(t))[2])
    applied1, _ = _applied(ticks, stamps, receipts, d1)
    applied2, _ = _applied(ticks, stamps, receipts, d2)
    assert np.allclose(ticks - applied1, [u[0] for u in used], atol=1e-12)
    assert np.allclose(ticks - applied2, [u[1] for u in used], atol=1e-12)
