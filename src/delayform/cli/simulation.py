"""The simulate command."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from delayform.cli._common import (
    POSITIVE,
    _emit,
    _out_dir,
    _progress,
    _scenario,
    cli,
    scenario_options,
)

if TYPE_CHECKING:
    pass


@cli.command("simulate")
@scenario_options
@click.option("--model", type=click.Choice(("unicycle", "double_integrator")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@click.option("--gif/--no-gif", default=False, show_default=True, help="Also write an animated GIF.")
def simulate_command(scenario: Path | None, model: str | None, duration: float | None, dt: float | None,
                     seed: int | None, gif: bool, out: Path | None, as_json: bool,
                     **overrides: Any) -> None:  # fmt: skip
    """Simulate the team at the scenario's delays into its formation.

    Writes positions versus time (sim_operating_xy.png/.svg), the traces
    (sim_operating_traces.png/.svg), the trajectory as CSV and NPZ, and with
    --gif an animation; reports settling time, final formation error and the
    closest approach of two agents.
    """
    from delayform.report import simulation_section
    from delayform.scenario import SimulationSpec

    sc = _scenario(scenario, seed=seed, **overrides)
    sim = SimulationSpec(
        model=model or sc.simulation.model,
        duration=sc.simulation.duration if duration is None else duration,
        dt=sc.simulation.dt if dt is None else dt,
    )
    if sim.dt >= sim.duration:
        raise click.BadParameter(f"the step must be smaller than the duration {sim.duration:g}", param_hint="--dt")
    sc = replace(sc, simulation=sim, initial=replace(sc.initial, seed=sc.initial.seed if seed is None else seed))
    directory = _out_dir(out, sc)
    with _progress(1, title="simulate") as step:
        step(f"{sim.model}, {sim.duration:g} s")
        section = simulation_section(sc, directory, gif=gif)
    _emit(section, directory, as_json=as_json)


