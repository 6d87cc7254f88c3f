"""Benchmark: guarantees for real networks (issue 20). Prints markdown tables.

Parts
-----
1. Per-link dominant root (``link_dominant_root``): the paper's team (goal 20 ms)
   and random sparse teams of 10, 30 and 100 agents with random per-link delays
   (goal 10 s at 100). The growth with N (up to 200 agents), the split into seeds,
   Newton and the certified count, and the BLAS-thread study: bench_per_link.py.
2. Box certificate (``robust_stability``) at the paper's points a and b: the
   widest certified half-width (bisection on the certificate) next to the widest
   half-width at which 40 random per-link assignments and the corners are all
   stable by the exact per-link check (its conservatism).
3. Jitter margin (``jitter_margin``) at points a and b next to an adversarial
   search in simulation: the smallest amplitude of (i) random per-packet jitter,
   (ii) a sawtooth: packets every 2A s over links of delay tau - A, held, so every
   age sweeps [tau - A, tau + A) and jumps down together, (iii) smooth per-link
   sinusoidal variations at the resonant period (the dominant mode's) and at half
   of it (parametric resonance), that makes the
   formation error grow (bisection over the amplitude, double integrators,
   dt = 0.01 s). The simulator needs every delay >= dt, so amplitudes stop at
   tau - dt; "none" means no destabilization up to there.
   (iv) a greedy switching adversary the simulator cannot play (every link, every
   step, takes tau - A or tau + A, whichever pumps energy into the receiver; own
   semi-implicit Euler integrator, dt = 0.005 s).
4. Mean-square stability under loss (``mean_square_stability``) at point a, 10
   packets/s: rho, the decay rate and the exact E|disagreement|^2 at 4 s next to
   the Monte Carlo mean of the simulator (dt = 0.005 s) with its 95 % interval.

Run: ``OMP_NUM_THREADS=1 python benchmarks/bench_network_guarantees.py [--quick]``.
The machine is shared with other jobs: the load average is printed.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from dataclasses import replace

import numpy as np

from delayform.analysis.ctcr import PAPER_POINTS
from delayform.analysis.network import jitter_margin, link_dominant_root, mean_square_stability, robust_stability
from delayform.analysis.network.links import link_team
from delayform.analysis.network.per_link import dominant_of_team
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.model.network import BernoulliLoss, Jitter, LinkDelays, Network, Sampling, SmoothVariation
from delayform.topology import paper_six, random_digraph

SHAPE = named_formation("hexagon", 6, spacing=2.0)
X0 = np.array([[-4.0, 1.0], [3.0, 4.0], [0.5, -3.0], [4.0, -1.0], [-2.0, -4.0], [1.0, 2.5]])


def per_link(quick: bool) -> None:
    print("\n### 1. Per-link dominant root\n")
    print("| team | links | time (s) | dominant root | certified count right of line |")
    print("|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    T = paper_six()
    t1 = rng.uniform(0.2, 0.4, (6, 6))
    t2 = rng.uniform(0.1, 0.3, (6, 6))
    link_dominant_root(T, 1.0, 0.5, t1, t2)  # warm-up (imports)
    times = []
    for _ in range(5):
        t = time.perf_counter()
        r = link_dominant_root(T, 1.0, 0.5, t1, t2)
        times.append(time.perf_counter() - t)
    print(f"| paper_six near point a (median of 5) | 13 | {np.median(times):.3f} | {r.root:.5f} | {r.count} |")
    for n in (10, 30) if quick else (10, 30, 100):
        Tn = random_digraph(n, 2.0 / n, seed=3)
        a = rng.uniform(0.2, 0.6, (n, n))
        b = rng.uniform(0.2, 0.6, (n, n))
        t = time.perf_counter()
        r = link_dominant_root(Tn, 1.0, 1.0, a, b)
        dt = time.perf_counter() - t
        print(f"| random_digraph({n}, 2/{n}) | {r.team.rows.size} | {dt:.2f} | {r.root:.5f} | {r.count} |")


def _widest(ok, hi: float, steps: int = 7) -> float:
    lo = 0.0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def boxes(quick: bool) -> None:
    print("\n### 2. Box of per-link delays (half-width h around the point, both streams)\n")
    print("| point | certified h | sampled-stable h (40 draws + corners) | time of one certificate (s) |")
    print("|---|---|---|---|")
    T = paper_six()
    rng = np.random.default_rng(1)
    for name in ("a", "b"):
        t1, t2 = PAPER_POINTS[name]
        cap = min(t1, t2)
        cert = _widest(lambda h: robust_stability(T, 1.0, 0.5, (t1 - h, t1 + h), (t2 - h, t2 + h)).certified, cap)
        t = time.perf_counter()
        robust_stability(T, 1.0, 0.5, (t1 - cert, t1 + cert), (t2 - cert, t2 + cert))
        one = time.perf_counter() - t
        base = link_team(T, 1.0, 0.5, t1, t2)

        def sampled(h: float) -> bool:
            draws = [(np.full(base.rows.size, a), np.full(base.rows.size, b)) for a in (-1, 1) for b in (-1, 1)]
            draws += [(rng.uniform(-1, 1, base.rows.size), rng.uniform(-1, 1, base.rows.size))
                      for _ in range(10 if quick else 40)]  # fmt: skip
            for f1, f2 in draws:
                if not dominant_of_team(replace(base, tau1=t1 + h * f1, tau2=t2 + h * f2)).is_stable:
                    return False
            return True

        samp = _widest(sampled, cap)
        print(f"| {name} {PAPER_POINTS[name]} | {cert:.4f} | {samp:.4f} (at most tau = {cap:g}) | {one:.2f} |")


def _grows(point: str, net: Network, duration: float) -> bool:
    t1, t2 = PAPER_POINTS[point]
    traj = simulate(paper_six(), 1.0, 0.5, t1, t2, SHAPE, model="double_integrator", initial_positions=X0,
                    duration=duration, dt=0.01, network=net)  # fmt: skip
    err = traj.formation_error
    return (not np.all(np.isfinite(err))) or err[-1] > 0.5 * err[0] or traj.status == "diverged"


def _greedy_switching_grows(point: str, A: float, duration: float, dt: float = 0.005) -> bool:
    """An adversary the simulator cannot play: every link, every step, picks its delay from
    {tau - A, tau + A} (clipped at dt) to pump energy into the receiver (the choice maximising
    v_i . (P x_k(t - d) + D v_k(t - d))). Own semi-implicit Euler integrator, 2-D double integrators."""
    t1, t2 = PAPER_POINTS[point]
    team = link_team(paper_six(), 1.0, 0.5, t1, t2)
    P, D = team.P, team.D
    rows, cols, w = team.rows, team.cols, team.weights
    lo1, hi1 = max(t1 - A, dt), t1 + A
    lo2, hi2 = max(t2 - A, dt), t2 + A
    lags = [int(round(x / dt)) for x in (lo1, hi1, lo2, hi2)]
    depth = max(lags) + 1
    x = (X0 - SHAPE).astype(float)
    v = np.zeros_like(x)
    hx = np.repeat(x[None], depth, axis=0)  # ring buffers of the history (constant before t = 0)
    hv = np.repeat(v[None], depth, axis=0)
    e0 = float(((x - x.mean(0)) ** 2).sum())
    steps = int(duration / dt)
    for k in range(steps):
        idx = [(k - m) % depth for m in lags]
        xa, xb = hx[idx[0]][cols], hx[idx[1]][cols]
        va, vb = hv[idx[2]][cols], hv[idx[3]][cols]
        vi = v[rows]
        # per link, the delayed value that pushes hardest along the receiver's velocity
        xs = np.where(((xa - xb) * vi).sum(1, keepdims=True) > 0, xa, xb)
        vs = np.where(((va - vb) * vi).sum(1, keepdims=True) > 0, va, vb)
        heard = np.zeros_like(x)
        np.add.at(heard, rows, w[:, None] * (P * xs + D * vs))
        acc = heard - P * x - D * v
        v = v + dt * acc
        x = x + dt * v
        hx[(k + 1) % depth], hv[(k + 1) % depth] = x, v
        if not np.all(np.isfinite(x)):
            return True
    e1 = float(((x - x.mean(0)) ** 2).sum())
    return e1 > 0.5 * e0


def jitter(quick: bool) -> None:
    print("\n### 3. Jitter margin against an adversarial search in simulation\n")
    print("| point | certified delta (s) | greedy switching (own integrator) | random jitter: smallest destabilizing (s) "
          "| sawtooth (sampled and held) | resonant sinusoid | half-period sinusoid |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name in ("a", "b"):
        t1, t2 = PAPER_POINTS[name]
        m = jitter_margin(paper_six(), 1.0, 0.5, t1, t2)
        wd = abs(m.nominal_root.imag)
        cap = min(t1, t2) - 0.01
        duration = 120.0 if name == "a" else 240.0
        out = []
        full = np.ones((6, 6))
        patterns = {
            "jitter": lambda A: Network(jitter=Jitter(A, A), seed=1),
            # packets every 2A s over links of delay tau - A, held: the age is a sawtooth over
            # [tau - A, tau + A), every link switching down by 2A at once (a fast, coherent switch)
            "sawtooth": lambda A: Network(delays=LinkDelays(tau1=(t1 - A) * full, tau2=(t2 - A) * full),
                                          sampling=Sampling(1.0 / (2.0 * A)), seed=1),  # fmt: skip
            "resonant": lambda A: Network(variation=SmoothVariation(A, A, period=max(2 * math.pi / wd, 2 * math.pi * A * 1.05)), seed=1),
            "half": lambda A: Network(variation=SmoothVariation(A, A, period=max(math.pi / wd, 2 * math.pi * A * 1.05)), seed=1),
        }
        # the greedy switching adversary (own integrator): bisection on A between 0 and the cap
        if _greedy_switching_grows(name, cap, duration):
            lo, hi = 0.0, cap
            for _ in range(4 if quick else 6):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if _greedy_switching_grows(name, mid, duration) else (mid, hi)
            greedy = f"{hi:.3f} (ratio {hi / m.delta:.1f})"
        else:
            greedy = f"none up to {cap:.2f}"
        for make in patterns.values():
            if not _grows(name, make(cap), duration):
                out.append(f"none up to {cap:.2f}")
                continue
            lo, hi = m.delta, cap
            for _ in range(3 if quick else 5):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if _grows(name, make(mid), duration) else (mid, hi)
            out.append(f"{hi:.3f} (ratio {hi / m.delta:.1f})")
        print(f"| {name} {PAPER_POINTS[name]} | {m.delta:.4f} | {greedy} | " + " | ".join(out) + " |")


def loss(quick: bool) -> None:
    print("\n### 4. Mean-square stability under packet loss (point a, 10 packets/s)\n")
    print("| loss | rho per period | decay rate (1/s) | time (s) | E|dis|^2 at 4 s: exact | Monte Carlo (runs, 95 % CI) |")
    print("|---|---|---|---|---|---|")
    shape_err = X0 - SHAPE
    runs = 10 if quick else 40
    for p in (0.0, 0.3, 0.6):
        t = time.perf_counter()
        r = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=p)
        dt_exact = time.perf_counter() - t
        exact = r.disagreement(shape_err, steps=40)[40]
        vals = []
        for seed in range(runs if p > 0 else 1):
            tr = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, SHAPE, model="double_integrator", initial_positions=X0,
                          initial_speed=0.0, duration=4.0, dt=0.005, save_every=20,
                          network=Network(sampling=Sampling(10.0), loss=BernoulliLoss(p), seed=seed))  # fmt: skip
            y = tr.positions[-1] - SHAPE
            vals.append(float(((y - y.mean(axis=0)) ** 2).sum()))
        v = np.array(vals)
        half = 1.96 * v.std(ddof=1) / math.sqrt(v.size) if v.size > 1 else 0.0
        print(f"| {p:g} | {r.rho:.5f} | {r.decay_rate:.4f} | {dt_exact:.2f} | {exact:.4f} | "
              f"{v.mean():.4f} +- {half:.4f} ({v.size}) |")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--part", choices=["1", "2", "3", "4"], action="append")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")  # fmt: skip
    parts = args.part or ["1", "2", "3", "4"]
    if "1" in parts:
        per_link(args.quick)
    if "2" in parts:
        boxes(args.quick)
    if "3" in parts:
        jitter(args.quick)
    if "4" in parts:
        loss(args.quick)


if __name__ == "__main__":
    main()
