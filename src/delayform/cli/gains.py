"""Design command: gain design (``delayform gains``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from delayform.cli._common import FloatTuple, _emit, _out_dir, _scenario, cli, scenario_options, without_actuation

#: Largest coarse map accepted: grid^2 gain points, each solved for every factor.
_MAX_GRID = 101


def _box(value: tuple[float, float] | None, option: str) -> tuple[float, float] | None:
    if value is not None and value[0] > value[1]:
        raise click.BadParameter(f"expected lo <= hi, got {value[0]:g},{value[1]:g}", param_hint=option)
    return value


def _gain_bounds(value: tuple[float, float], option: str) -> tuple[float, float]:
    if not 0.0 < value[0] < value[1]:
        raise click.BadParameter(f"expected 0 < lo < hi, got {value[0]:g},{value[1]:g}", param_hint=option)
    return value


@cli.command("gains")
@scenario_options
@click.option("--tau1-box", type=FloatTuple(2, minimum=0.0),
              help="Robust design: tau1 anywhere in LO,HI (s); replaces --tau1.")
@click.option("--tau2-box", type=FloatTuple(2, minimum=0.0),
              help="Robust design: tau2 anywhere in LO,HI (s); replaces --tau2.")
@click.option("--P-bounds", "P_bounds", type=FloatTuple(2), default="0.05,3", show_default=True,
              help="Interval LO,HI searched for P.")
@click.option("--D-bounds", "D_bounds", type=FloatTuple(2), default="0.05,3", show_default=True,
              help="Interval LO,HI searched for D.")
@click.option("--grid", type=click.IntRange(3, _MAX_GRID), default=21, show_default=True,
              help="Points per axis of the coarse gain-plane map.")
def gains_command(scenario: Path | None, tau1_box: tuple[float, float] | None,
                  tau2_box: tuple[float, float] | None, P_bounds: tuple[float, float],
                  D_bounds: tuple[float, float], grid: int, out: Path | None, as_json: bool,
                  **overrides: Any) -> None:  # fmt: skip
    """Gain design: the P, D within bounds that make the team converge fastest at its delays.

    Minimises the real part of the dominant root over the gains at the
    scenario's delays (or --tau1/--tau2); with --tau1-box and/or --tau2-box,
    minimises its worst case over the box and certifies the gains stable on
    the whole box with the exact CTCR map. Writes gain_plane.png/.svg/.npz and
    gains.json; the scenario's own gains are marked for comparison.
    """
    from delayform.report import gains_section

    if tau1_box is not None and overrides.get("tau1") is not None:
        raise click.UsageError("give --tau1 or --tau1-box, not both")
    if tau2_box is not None and overrides.get("tau2") is not None:
        raise click.UsageError("give --tau2 or --tau2-box, not both")
    box1, box2 = _box(tau1_box, "--tau1-box"), _box(tau2_box, "--tau2-box")
    pb, db = _gain_bounds(P_bounds, "--P-bounds"), _gain_bounds(D_bounds, "--D-bounds")
    sc = without_actuation(_scenario(scenario, **overrides), "gain design")
    if box1 is None or box2 is None:  # the design is then at the scenario's own delays
        sc = sc.at_one_delay_pair("the gain design at the scenario's delays", "--tau1-box and --tau2-box for a box of delays")
    directory = _out_dir(out, sc)
    section = gains_section(sc, directory, tau1=box1, tau2=box2, P_bounds=pb, D_bounds=db, grid=grid)
    _emit(section, directory, as_json=as_json)
