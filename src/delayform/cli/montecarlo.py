"""The montecarlo command: N seeded runs over an imperfect network, here or on Dask."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    NON_NEGATIVE,
    POSITIVE,
    FloatTuple,
    _emit,
    _inner_progress,
    _limits_given,
    _out_dir,
    _with_robot,
    _scenario,
    _simulation_spec,
    cli,
    limit_options,
    radius_option,
    scenario_options,
)


def _network(base: Any, *, loss: float | None, burst: tuple[float, float] | None, jitter: tuple[float, float] | None,
             rate: float | None, noise: tuple[float, float] | None, spread: float | None) -> Any:  # fmt: skip
    """The scenario's ``[network]`` with the command-line parts replacing its own."""
    from delayform.model.network import (
        BernoulliLoss,
        GilbertElliott,
        Jitter,
        LinkDelays,
        MeasurementNoise,
        Network,
        Sampling,
    )

    if loss is not None and burst is not None:
        raise click.UsageError("give either --loss (independent) or --burst (Gilbert-Elliott), not both")
    net = base if base is not None else Network()
    changes: dict[str, Any] = {}
    if loss is not None:
        changes["loss"] = BernoulliLoss(loss)
    if burst is not None:
        changes["loss"] = GilbertElliott(*burst)
    if jitter is not None:
        changes["jitter"] = Jitter(*jitter)
    if rate is not None:
        changes["sampling"] = Sampling(rate)
    if noise is not None:
        changes["noise"] = MeasurementNoise(*noise)
    if spread is not None:
        changes["delays"] = LinkDelays(spread=spread)
    return replace(net, **changes)


@cli.command("montecarlo")
@scenario_options
@click.option("--runs", type=click.IntRange(min=1), default=40, show_default=True, help="Number of seeded runs.")
@click.option("--workers", type=click.IntRange(min=1), help="Run on a local Dask cluster of this many processes.")
@click.option("--scheduler", metavar="ADDRESS", help="Run on an existing Dask cluster, e.g. tcp://10.0.0.5:8786.")
@click.option("--model", type=click.Choice(("unicycle", "double_integrator", "physics")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time per run in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@click.option("--loss", type=click.FloatRange(0.0, 1.0), help="Independent packet-loss probability (network.loss).")
@click.option("--burst", type=FloatTuple(2, minimum=0.0), metavar="P_GB,P_BG",
              help="Bursty loss: Gilbert-Elliott good->bad and bad->good probabilities per packet.")
@click.option("--jitter", type=FloatTuple(2, minimum=0.0), metavar="B1,B2",
              help="Jitter bounds (s) on position and velocity delays (network.jitter); every delay minus "
                   "its jitter must be >= --dt.")
@click.option("--rate", type=POSITIVE, help="Sampled transmission: packets per second (network.rate).")
@click.option("--noise", type=FloatTuple(2, minimum=0.0), metavar="SX,SV",
              help="Measurement noise: std of positions (m) and velocities (m/s) (network.noise).")
@click.option("--delay-spread", "spread", type=NON_NEGATIVE,
              help="Per-link delays drawn in tau (1 +- SPREAD), SPREAD < 1 (network.delay_spread).")
@limit_options
@radius_option
def montecarlo_command(scenario: Path | None, runs: int, seed: int | None, workers: int | None, scheduler: str | None,
                       model: str | None, duration: float | None, dt: float | None, loss: float | None,
                       burst: tuple[float, float] | None, jitter: tuple[float, float] | None, rate: float | None,
                       noise: tuple[float, float] | None, spread: float | None, use_limits: bool | None,
                       radius: float | None, assignment: str | None, safety: str | None, out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Monte Carlo of the scenario over an imperfect network: N seeded runs.

    The network comes from the scenario's [network] table and the options
    --loss, --burst, --jitter, --rate, --noise, --delay-spread. Every value
    heard is at least one step old: with any of these on, every delay minus
    its jitter (and variation) must be >= dt (so tau1, tau2 >= dt). Robots with
    actuator limits (the scenario's [robot] table, --limits and the limit
    options) are the saturated unicycle driven by what each robot hears.
    Writes the quantile bands of the formation error
    (montecarlo_bands.png/.svg), histograms of settling time, final error,
    peak command and closest approach (montecarlo_histograms.png/.svg), the
    probability of contact between bodies (--radius), one CSV row per run
    and an NPZ; reports median and 5-95 % of each. The same seed gives the
    same numbers in this process, with --workers and with --scheduler.
    --seed seeds the runs (per-run seeds from numpy SeedSequence.spawn;
    default 0) and a random_digraph topology.
    """
    from delayform.report import montecarlo_section, scenario_setup
    from delayform.simulation.experiments.montecarlo import guard
    from delayform.simulation.experiments.sweeps import check_workers, executor_for, parse_scheduler

    if workers is not None and scheduler is not None:
        raise click.UsageError("give either --workers (a local cluster) or --scheduler (an existing one), not both")
    if workers is not None:  # against this machine's cores, before any budget or process
        check_workers(workers)
    if scheduler is not None:  # parsed now; executor_for proves a scheduler answers before --out is made
        parse_scheduler(scheduler)
    given = _limits_given(overrides)
    sc = _scenario(scenario, seed=seed, **overrides)
    seed = 0 if seed is None else seed
    sim = _simulation_spec(sc, model=model, duration=duration, dt=dt, assignment=assignment)
    network = _network(sc.network, loss=loss, burst=burst, jitter=jitter, rate=rate, noise=noise, spread=spread)
    sc = replace(_with_robot(sc, use_limits, given, sim.model), simulation=sim, network=network,
                 radius=sc.radius if radius is None else radius,
                 safety=sc.safety if safety is None else (None if safety == "none" else safety))
    # every input and the budget are checked before anything is started or written
    setup = scenario_setup(sc)
    guard(setup, runs, workers or 1)
    with executor_for(workers=workers, scheduler=scheduler) as ex:
        directory = _out_dir(out, sc)
        with _inner_progress(f"montecarlo ({runs} runs)") as bar:
            section = montecarlo_section(sc, directory, runs=runs, seed=seed, executor=ex, progress=bar)
    _emit(section, directory, as_json=as_json)
    shout_bugs(section.summary)


def shout_bugs(summary: dict[str, Any]) -> None:
    """A run that diverged where a certificate holds is a bug: say so on stderr and exit with code 1.

    The files are written (they are the evidence); the exit code makes scripts and CI notice.
    """
    bugs = summary.get("contradictions") or []
    if bugs:
        for bug in bugs:
            click.echo(f"delayform: BUG: {bug}", err=True)
        raise SystemExit(1)
