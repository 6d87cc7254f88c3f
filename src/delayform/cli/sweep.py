"""The sweep command: Monte Carlo on a grid of delays, here or on Dask."""

from __future__ import annotations

from dataclasses import replace
from itertools import product
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    POSITIVE,
    DelayValues,
    _emit,
    _inner_progress,
    _limits_given,
    _out_dir,
    _with_robot,
    _scenario,
    _simulation_spec,
    cli,
    limit_options,
    scenario_options,
)


@cli.command("sweep")
@scenario_options
@click.option("--tau1-values", type=DelayValues(), required=True,
              help="Position delays (s): START:STOP:COUNT, both ends included, or T1,T2,...")
@click.option("--tau2-values", type=DelayValues(), required=True,
              help="Velocity delays (s): START:STOP:COUNT, both ends included, or T1,T2,...")
@click.option("--runs", type=click.IntRange(min=1), default=10, show_default=True, help="Seeded runs per delay pair.")
@click.option("--workers", type=click.IntRange(min=1), help="Run on a local Dask cluster of this many processes.")
@click.option("--scheduler", metavar="ADDRESS", help="Run on an existing Dask cluster, e.g. tcp://10.0.0.5:8786.")
@click.option("--model", type=click.Choice(("unicycle", "double_integrator", "physics")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time per run in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@limit_options
def sweep_command(scenario: Path | None, tau1_values: tuple[float, ...], tau2_values: tuple[float, ...], runs: int,
                  seed: int | None, workers: int | None, scheduler: str | None, model: str | None,
                  duration: float | None, dt: float | None, use_limits: bool | None, out: Path | None,
                  as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Monte Carlo of the scenario at every delay pair of a grid: settling time over (tau1, tau2).

    Every pair runs --runs seeded runs over the scenario's [network] (ideal
    without it), with the robots of its [robot] table or --limits. Writes the
    median settling time over the grid (sweep_settling.png/.svg), one CSV
    row per pair (settled fraction, settling median and 5-95 %, final
    error) and an NPZ of the grids. The same seed gives the same numbers in
    this process, with --workers and with --scheduler; every pair uses the
    same seeds (common random numbers).
    """
    from delayform.report import scenario_setup, sweep_section
    from delayform.simulation.experiments.sweeps import check_sweep

    if workers is not None and scheduler is not None:
        raise click.UsageError("give either --workers (a local cluster) or --scheduler (an existing one), not both")
    for name in ("tau1", "tau2"):
        if overrides.get(name) is not None:
            raise click.UsageError(f"--{name} sets one delay; the sweep takes --{name}-values")
    given = _limits_given(overrides)
    # every point of the grid is one delay pair on every link (a delay_spread follows it): a matrix cannot be swept
    sc = _scenario(scenario, seed=seed, **overrides).at_one_delay_pair(
        "sweep (one delay pair on every link at each point of its grid)", "montecarlo for runs at the per-link delays",
        spread=False)  # fmt: skip
    sim = _simulation_spec(sc, model=model, duration=duration, dt=dt)
    sc = replace(_with_robot(sc, use_limits, given, sim.model), simulation=sim)
    # every input, the budget and the cluster are checked before anything is started or written
    grid = [{"tau1": a, "tau2": b} for a, b in product(tau1_values, tau2_values)]
    check_sweep(scenario_setup(sc), grid, runs=runs, workers=workers, scheduler=scheduler)
    directory = _out_dir(out, sc)
    points = len(tau1_values) * len(tau2_values)
    with _inner_progress(f"sweep ({points} delay pairs x {runs} runs)") as bar:
        section = sweep_section(sc, directory, tau1_values=tau1_values, tau2_values=tau2_values, runs=runs,
                                seed=0 if seed is None else seed, workers=workers, scheduler=scheduler,
                                progress=bar)  # fmt: skip
    _emit(section, directory, as_json=as_json)
