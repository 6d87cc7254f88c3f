"""Benchmark: delayform.simulate against jitcdde, and scaling to 10,000 robots (issue 5).

Run with ``.venv/bin/python benchmarks/bench_simulation.py`` after
``pip install -e ".[bench]"`` (jitcdde compiles C code with the system's
compiler). Prints markdown tables for docs/benchmarks.md.

1. The paper's six agents (Fig. topol, P = 1, D = 0.5) at point a
   (tau1, tau2) = (0.3, 0.2), **double-integrator agents** (the linear
   eq. formation, which jitcdde integrates as written), into a hexagon of
   spacing 2 from the seeded random start of :func:`delayform.simulate`
   (initial speed 1e-3), over 150 s. Both trajectories are compared at every
   second; jitcdde's time includes generating and compiling its C code.
2. Unicycle robots on ``random_digraph(n, 3 / n)`` into a grid over 100 s,
   n = 1,000, 3,000, 10,000: wall time, and peak memory traced by
   tracemalloc in a separate run (tracing slows the run down).
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import tempfile
import time
import tracemalloc

import numpy as np

from delayform.formation import formation_forcing, named_formation
from delayform.simulation import simulate
from delayform.topology import paper_six, random_digraph

P, D = 1.0, 0.5
TAU1, TAU2 = 0.3, 0.2
DURATION = 150.0


def paper_run(dt: float):
    """delayform on the paper's six agents; returns (trajectory, seconds)."""
    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    start = time.perf_counter()
    traj = simulate(topo, P, D, TAU1, TAU2, desired, model="double_integrator",
                    duration=DURATION, dt=dt, seed=0)
    return traj, time.perf_counter() - start


def jitcdde_run(traj, times):
    """jitcdde on the same problem and start; returns (positions at ``times``, seconds)."""
    from jitcdde import jitcdde, t, y  # noqa: F401  (t: jitcdde's time symbol)

    topo = paper_six()
    C = np.asarray(topo.C)
    F = formation_forcing(topo, P, traj.desired)
    n = topo.n
    x0 = traj.positions[0]
    v0 = traj.speeds[0][:, None] * np.column_stack([np.cos(traj.headings[0]), np.sin(traj.headings[0])])
    start = time.perf_counter()
    # state of agent i: x, y, xdot, ydot at 4i .. 4i+3 (eq. formation, coordinates decoupled)
    f = []
    for i in range(n):
        f += [y(4 * i + 2), y(4 * i + 3)]
        for k in range(2):
            xd = sum(C[i, j] * y(4 * j + k, t - TAU1) for j in range(n) if C[i, j])
            vd = sum(C[i, j] * y(4 * j + 2 + k, t - TAU2) for j in range(n) if C[i, j])
            f.append(P * (xd - y(4 * i + k)) + D * (vd - y(4 * i + 2 + k)) + F[i, k])
    # giving the delays spares jitcdde finding them symbolically (which needs sympy)
    dde = jitcdde(f, delays=[TAU1, TAU2], max_delay=max(TAU1, TAU2), verbose=False)
    # jitcdde builds its module with setuptools in the working directory, which would
    # read the project's pyproject.toml: compile from an empty directory instead.
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        try:
            dde.compile_C(simplify=False)
        finally:
            os.chdir(here)
    compiled = time.perf_counter() - start
    # constant past: positions x0 and velocities v0, zero derivatives (as in delayform)
    dde.constant_past(np.column_stack([x0, v0]).ravel(), time=0.0)
    dde.set_integration_parameters(atol=1e-10, rtol=1e-10)
    dde.step_on_discontinuities()
    # t = 0 is left out: step_on_discontinuities has already moved past it
    out = np.array([dde.integrate(tt) for tt in times[1:]])
    seconds = time.perf_counter() - start
    print(f"(jitcdde: {compiled:.2f} s to generate and compile, {seconds - compiled:.2f} s to integrate)")
    pos = np.concatenate([x0[None], out.reshape(len(times) - 1, n, 4)[:, :, :2]])
    return pos, seconds


def scaling_run(n: int, *, trace: bool) -> tuple[float, float, int]:
    """One unicycle run on a sparse random digraph; returns (seconds, peak MiB, regularised)."""
    topo = random_digraph(n, 3.0 / n, seed=1)
    gc.collect()
    if trace:
        tracemalloc.start()
    start = time.perf_counter()
    traj = simulate(topo, P, D, TAU1, TAU2, "grid", duration=100.0, dt=0.05, seed=1, save_every=20)
    seconds = time.perf_counter() - start
    peak = 0.0
    if trace:
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return seconds, peak, traj.regularisation_count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[1000, 3000, 10000])
    parser.add_argument("--dt", type=float, default=0.1,
                        help="delayform step for the paper run (tau1, tau2 multiples of it: order 4)")
    args = parser.parse_args()

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print()
    print("## Paper's six double-integrator agents, point a, 150 s")
    print()
    traj, ours = paper_run(args.dt)
    ours = min(ours, *(paper_run(args.dt)[1] for _ in range(2)))  # best of three
    times = np.arange(0.0, DURATION + 1e-9, 1.0)
    stride = int(round(1.0 / args.dt))
    try:
        import jitcdde  # noqa: F401
    except ImportError:
        print("jitcdde is not installed: pip install -e '.[bench]'")
        ref, theirs = None, float("nan")
    else:
        ref, theirs = jitcdde_run(traj, times)
    print("| integrator | settings | time (s) |")
    print("|---|---|---|")
    print(f"| delayform.simulate | RK4 + Hermite history, dt = {args.dt} | {ours:.3f} |")
    print(f"| jitcdde (incl. code generation and compilation) | atol = rtol = 1e-10 | {theirs:.3f} |")
    if ref is not None:
        diff = np.abs(traj.positions[::stride][1:] - ref[1:]).max()
        print()
        print(f"max |delayform - jitcdde| over positions at t = 1, 2, ..., 150 s: {diff:.2e} (goal 1e-4)")
        print(f"speed-up: {theirs / ours:.1f}x (goal 10x)")
    print()
    print("## Unicycle robots on random_digraph(n, 3/n), point a, 100 s, dt = 0.05")
    print()
    print("| n | time (s) | peak traced memory (MiB) | regularised (agent, step) |")
    print("|---|---|---|---|")
    for n in args.sizes:
        seconds, _, reg = scaling_run(n, trace=False)
        _, peak, _ = scaling_run(n, trace=True)
        print(f"| {n} | {seconds:.1f} | {peak:.0f} | {reg} |")


if __name__ == "__main__":
    main()
