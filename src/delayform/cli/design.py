"""Design commands: delay scheduling."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from delayform.cli._common import (
    FloatTuple,
    _emit,
    _out_dir,
    _scenario,
    actuation_option,
    cli,
    scenario_options,
    with_actuation,
)
from delayform.cli.analysis import PER_LINK

if TYPE_CHECKING:
    pass


@cli.command("schedule")
@scenario_options
@click.option("--tau-min", type=FloatTuple(2, minimum=0.0),
              help="Hardware delays T1,T2: delays can only be increased from here "
                   "[default: --tau1,--tau2 when given, else schedule.tau_min].")
@click.option("--tau-max", type=FloatTuple(2, minimum=0.0),
              help="Largest acceptable delays T1,T2 [default: schedule.tau_max].")
@actuation_option
def schedule_command(scenario: Path | None, tau_min: tuple[float, float] | None,
                     tau_max: tuple[float, float] | None, actuation_delay: float | None, out: Path | None,
                     as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Delay scheduling: the stable delays, no smaller than the hardware's, that converge fastest.

    Minimises the real part of the dominant root over
    [tau_min, tau_max] and reports the delays, the root and the predicted
    settling time (schedule.json).
    """
    from delayform.report import schedule_section
    from delayform.scenario import ScheduleSpec

    # the hardware delays are one pair on every link: the schedule adds the same delay to every link
    sc = with_actuation(_scenario(scenario, **overrides), actuation_delay)
    sc = sc.at_one_delay_pair("schedule (one delay pair added on every link)", PER_LINK)
    lo = tau_min or sc.schedule.tau_min
    # the default upper bound follows the lower one given (ScheduleSpec.starting_at)
    hi = tau_max or sc.schedule.starting_at(lo).tau_max
    if hi[0] < lo[0] or hi[1] < lo[1]:
        where = "--tau-min" if tau_min is not None else "schedule.tau_min"
        raise click.BadParameter(f"expected bounds >= {where} = {lo[0]:g},{lo[1]:g}", param_hint="--tau-max")
    sc = replace(sc, schedule=ScheduleSpec(tau_min=lo, tau_max=hi))
    directory = _out_dir(out, sc)
    _emit(schedule_section(sc, directory), directory, as_json=as_json)


