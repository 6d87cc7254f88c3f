"""Benchmark: delayform.simulate against jitcdde on the paper's robots, and scaling to 10,000 robots.

Run with ``.venv/bin/python benchmarks/bench_simulation.py`` after
``pip install -e ".[bench]"`` (jitcdde compiles C code with the system's
compiler). Prints markdown tables for docs/benchmarks.md.

1. The paper's six robots (Fig. topol, P = 1, D = 0.5) at point a
   (tau1, tau2) = (0.3, 0.2), **unicycles** from the seeded random start of
   :func:`delayform.simulate` (initial speed 1e-3, random headings), into a
   hexagon of spacing 2, over 150 s, dt = 0.01. jitcdde integrates the
   unicycle equations themselves (eq. kinem:uni with the inputs of
   eq. transform2; state x, y, theta, v per robot, the neighbours' delayed
   positions and velocities v (cos theta, sin theta)), error-controlled;
   delayform integrates the exact double-integrator path and rebuilds the
   robots' commands. Positions are compared at every second (and at 10, 20,
   30, 60 s); jitcdde's time includes generating and compiling its C code.
   Both run in the same process, alternately, several times: median and best.
2. Ideal unicycle robots on ``random_digraph(n, 3 / n)`` into a grid over 100 s,
   n = 1,000, 3,000, 10,000: wall time, and peak memory traced by
   tracemalloc in a separate run (tracing slows the run down).
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import statistics
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
    """delayform on the paper's six robots; returns (trajectory, seconds)."""
    topo = paper_six()
    desired = named_formation("hexagon", 6, spacing=2.0)
    start = time.perf_counter()
    traj = simulate(topo, P, D, TAU1, TAU2, desired, duration=DURATION, dt=dt, seed=0)
    return traj, time.perf_counter() - start


def jitcdde_run(traj, times, tol: float):
    """jitcdde on the unicycle equations from the same start; returns (positions at ``times``, seconds)."""
    from jitcdde import jitcdde, t, y  # noqa: F401  (t: jitcdde's time symbol)
    from symengine import cos, sin

    topo = paper_six()
    C = np.asarray(topo.C)
    F = formation_forcing(topo, P, traj.desired)
    n = topo.n
    x0 = traj.positions[0]
    th0, v0 = traj.headings[0], traj.speeds[0]
    start = time.perf_counter()
    # state of robot i: x, y, theta, v at 4i .. 4i+3
    f = []
    for i in range(n):
        th, v = y(4 * i + 2), y(4 * i + 3)
        vel = (v * cos(th), v * sin(th))
        u = []
        for k in range(2):
            xd = sum(C[i, j] * y(4 * j + k, t - TAU1) for j in range(n) if C[i, j])
            trig = cos if k == 0 else sin
            vd = sum(C[i, j] * y(4 * j + 3, t - TAU2) * trig(y(4 * j + 2, t - TAU2)) for j in range(n) if C[i, j])
            u.append(P * (xd - y(4 * i + k)) + D * (vd - vel[k]) + F[i, k])
        # eq. kinem:uni and eq. transform2
        f += [vel[0], vel[1], (-sin(th) * u[0] + cos(th) * u[1]) / v, cos(th) * u[0] + sin(th) * u[1]]
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
    # constant past: positions x0, headings, speeds (as in delayform)
    dde.constant_past(np.column_stack([x0, th0, v0]).ravel(), time=0.0)
    dde.set_integration_parameters(atol=tol, rtol=tol, first_step=1e-6, min_step=1e-12)
    dde.step_on_discontinuities()
    # t = 0 is left out: step_on_discontinuities has already moved past it
    out = np.array([dde.integrate(tt) for tt in times[1:]])
    seconds = time.perf_counter() - start
    pos = np.concatenate([x0[None], out.reshape(len(times) - 1, n, 4)[:, :, :2]])
    return pos, seconds, compiled


def scaling_run(n: int, *, trace: bool) -> tuple[float, float]:
    """One ideal-unicycle run on a sparse random digraph; returns (seconds, peak MiB)."""
    topo = random_digraph(n, 3.0 / n, seed=1)
    gc.collect()
    if trace:
        tracemalloc.start()
    start = time.perf_counter()
    traj = simulate(topo, P, D, TAU1, TAU2, "block", duration=100.0, dt=0.05, seed=1, save_every=20)
    seconds = time.perf_counter() - start
    peak = 0.0
    if trace:
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    assert traj.commands is not None and np.all(np.isfinite(traj.positions))
    return seconds, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[1000, 3000, 10000])
    parser.add_argument("--dt", type=float, default=0.01, help="delayform step for the paper run")
    parser.add_argument("--repeat", type=int, default=5, help="alternating runs of each integrator")
    parser.add_argument("--tol", type=float, default=1e-8, help="jitcdde's atol = rtol")
    args = parser.parse_args()

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start")  # fmt: skip
    print()
    print(f"## Paper's six unicycle robots, point a, {DURATION:g} s, dt = {args.dt}")
    print()
    times = np.arange(0.0, DURATION + 1e-9, 1.0)
    stride = int(round(1.0 / args.dt))
    try:
        import jitcdde  # noqa: F401
    except ImportError:
        print("jitcdde is not installed: pip install -e '.[bench]'")
        jitcdde_ok = False
    else:
        jitcdde_ok = True
    ours, theirs, compiles = [], [], []
    traj, ref = None, None
    for _ in range(args.repeat):
        traj, seconds = paper_run(args.dt)
        ours.append(seconds)
        if jitcdde_ok:
            ref, seconds, compiled = jitcdde_run(traj, times, args.tol)
            theirs.append(seconds)
            compiles.append(compiled)
    print("| integrator | settings | best (s) | median (s) |")
    print("|---|---|---|---|")
    print(f"| delayform.simulate (unicycles) | exact double-integrator path + commands, dt = {args.dt} "
          f"| {min(ours):.3f} | {statistics.median(ours):.3f} |")  # fmt: skip
    if jitcdde_ok:
        print(f"| jitcdde, unicycle equations (incl. code generation and compilation, median "
              f"{statistics.median(compiles):.2f} s) | atol = rtol = {args.tol:g} "
              f"| {min(theirs):.3f} | {statistics.median(theirs):.3f} |")  # fmt: skip
        ours_pos = traj.positions[::stride]
        diff = np.abs(ours_pos[1:] - ref[1:]).max()
        at = {T: float(np.abs(ours_pos[int(T)] - ref[int(T)]).max()) for T in (10, 20, 30, 60)}
        print()
        print(f"max |delayform - jitcdde| over positions at t = 1, 2, ..., 150 s: {diff:.2e} m")
        print("at 10, 20, 30, 60 s: " + ", ".join(f"{v:.1e}" for v in at.values()) + " m (goal 1e-3)")
        print(f"settling time: {traj.settling_time:.2f} s (goal 20-40 s)")
        print(f"speed-up: {min(theirs) / min(ours):.1f}x best, "
              f"{statistics.median(theirs) / statistics.median(ours):.1f}x median (goal 10x)")  # fmt: skip
    print()
    print("## Ideal unicycle robots on random_digraph(n, 3/n), point a, 100 s, dt = 0.05")
    print()
    print("| n | time (s) | peak traced memory (MiB) |")
    print("|---|---|---|")
    for n in args.sizes:
        seconds, _ = scaling_run(n, trace=False)
        _, peak = scaling_run(n, trace=True)
        print(f"| {n} | {seconds:.1f} | {peak:.0f} |")
    print()
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
