"""Benchmark: per-link delays against jitcdde, and Monte Carlo throughput serially and on Dask (issue 14).

Run with ``.venv/bin/python benchmarks/bench_network.py`` after
``pip install -e ".[bench]"``. Prints markdown tables for docs/benchmarks.md.

1. The paper's six double-integrator agents (Fig. topol, P = 1, D = 0.5) into
   a hexagon with a different constant delay on every link (drawn with a
   seed from {0.2, 0.3, 0.45, 0.6} s for positions and {0.2, 0.25, 0.4} s for
   velocities), 60 s: ``simulate(..., network=Network(delays=LinkDelays(...)))``
   against jitcdde on the same equations; jitcdde's time includes generating
   and compiling its C code. Best and median of repeats.
2. ``monte_carlo`` of 40 runs (point a, 30 % loss, jitter +-0.05 s, 60 s,
   dt = 0.05) in this process and on a local Dask cluster of 2 workers
   (cluster start included and separately), median of repeats.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time

import numpy as np

from delayform.formation import formation_forcing, named_formation
from delayform.simulation import simulate
from delayform.simulation.experiments.montecarlo import monte_carlo
from delayform.model.network import BernoulliLoss, Jitter, LinkDelays, Network
from delayform.simulation.experiments.sweeps import executor_for
from delayform.topology import paper_six

P, D = 1.0, 0.5
DURATION = 60.0
SHAPE = named_formation("hexagon", 6, spacing=2.0)


def link_delays() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    return rng.choice([0.2, 0.3, 0.45, 0.6], size=(6, 6)), rng.choice([0.2, 0.25, 0.4], size=(6, 6))


def ours(dt: float):
    d1, d2 = link_delays()
    start = time.perf_counter()
    traj = simulate(paper_six(), P, D, 0.3, 0.2, SHAPE, model="double_integrator", duration=DURATION, dt=dt,
                    seed=0, network=Network(delays=LinkDelays(tau1=d1, tau2=d2)))  # fmt: skip
    return traj, time.perf_counter() - start


def theirs(traj, times):
    from jitcdde import jitcdde, t, y

    topo = paper_six()
    C = np.asarray(topo.C)
    F = formation_forcing(topo, P, SHAPE)
    d1, d2 = link_delays()
    n = topo.n
    x0 = traj.positions[0]
    v0 = traj.speeds[0][:, None] * np.column_stack([np.cos(traj.headings[0]), np.sin(traj.headings[0])])
    start = time.perf_counter()
    f = []
    for i in range(n):
        f += [y(4 * i + 2), y(4 * i + 3)]
        for k in range(2):
            xd = sum(C[i, j] * y(4 * j + k, t - d1[i, j]) for j in range(n) if C[i, j])
            vd = sum(C[i, j] * y(4 * j + 2 + k, t - d2[i, j]) for j in range(n) if C[i, j])
            f.append(P * (xd - y(4 * i + k)) + D * (vd - y(4 * i + 2 + k)) + F[i, k])
    delays = sorted({float(d1[i, j]) for i, j in zip(*np.nonzero(C))} | {float(d2[i, j]) for i, j in zip(*np.nonzero(C))})
    dde = jitcdde(f, delays=delays, max_delay=max(delays), verbose=False)
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:  # jitcdde would read the project's pyproject.toml
        os.chdir(tmp)
        try:
            dde.compile_C(simplify=False)
        finally:
            os.chdir(here)
    dde.constant_past(np.column_stack([x0, v0]).ravel(), time=0.0)
    dde.set_integration_parameters(atol=1e-10, rtol=1e-10)
    dde.step_on_discontinuities()
    # with several delays it steps past t = 1 s: compare from where it stands, not by extrapolating back
    later = times[times >= dde.t]
    out = np.array([dde.integrate(tt) for tt in later])
    seconds = time.perf_counter() - start
    return later, out.reshape(len(later), n, 4)[:, :, :2], seconds


def mc_kwargs() -> dict:
    return dict(network=Network(loss=BernoulliLoss(0.3), jitter=Jitter(0.05, 0.05)), runs=40, seed=1,
                duration=DURATION, dt=0.05)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--dt", type=float, default=0.01)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f}")  # fmt: skip
    print("\n## Six agents, per-link delays, 60 s\n")
    runs = [ours(args.dt) for _ in range(args.repeats)]
    traj = runs[0][0]
    ours_t = [r[1] for r in runs]
    times = np.arange(0.0, DURATION + 1e-9, 1.0)
    later, ref, theirs_t = theirs(traj, times)
    rows = np.rint(later / args.dt).astype(int)
    diff = float(np.abs(traj.positions[rows] - ref).max())
    print("| integrator | best (s) | median (s) |\n|---|---|---|")
    print(f"| delayform, network of per-link delays, dt = {args.dt} | {min(ours_t):.3f} | {statistics.median(ours_t):.3f} |")
    print(f"| jitcdde (incl. code generation and compilation), atol = rtol = 1e-10 | {theirs_t:.3f} | {theirs_t:.3f} |")
    print(f"\nmax |delayform - jitcdde| over positions at t = {later[0]:g}, ..., 60 s: {diff:.2e} (goal 1e-4)")

    print("\n## monte_carlo, 40 runs, point a, loss 0.3, jitter +-0.05 s, 60 s, dt = 0.05\n")
    serial = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        a = monte_carlo(paper_six(), P, D, 0.3, 0.2, SHAPE, **mc_kwargs())
        serial.append(time.perf_counter() - start)
    start = time.perf_counter()
    with executor_for(workers=2) as ex:
        started = time.perf_counter() - start
        dask = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            b = monte_carlo(paper_six(), P, D, 0.3, 0.2, SHAPE, executor=ex, **mc_kwargs())
            dask.append(time.perf_counter() - t0)
    same = np.array_equal(a.errors, b.errors) and np.array_equal(a.settling_times, b.settling_times)
    print("| where | best (s) | median (s) |\n|---|---|---|")
    print(f"| this process | {min(serial):.2f} | {statistics.median(serial):.2f} |")
    print(f"| LocalCluster, 2 workers (start {started:.1f} s, not included) | {min(dask):.2f} | {statistics.median(dask):.2f} |")
    print(f"\nidentical numbers serially and on Dask: {same}")


if __name__ == "__main__":
    main()
