"""Eigenvalue-plane commands: region (which eigenvalues of C are stable) and safe-delays (certificates)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from delayform.cli._common import (
    POSITIVE,
    LabelledPoint,
    _emit,
    _out_dir,
    _scenario,
    cli,
    scenario_options,
    without_actuation,
)
from delayform.cli.analysis import PER_LINK


@cli.command("region")
@scenario_options
def region_command(scenario: Path | None, out: Path | None, as_json: bool, **overrides: Any) -> None:
    """Stable region of the eigenvalue plane at one delay pair, with the team's eigenvalues.

    Every factor of the characteristic equation is q(s, lam) = s^2 + D s + P -
    lam (D s e^{-tau2 s} + P e^{-tau1 s}); the region holds the eigenvalues lam
    of C whose factor is stable. Writes lambda_region.png/.svg and
    eigenvalue_region.csv (each eigenvalue with its number of unstable roots)
    and reports whether the delays are safe for every undirected team and for
    every team.
    """
    from delayform.report import region_section

    sc = without_actuation(_scenario(scenario, **overrides), "the eigenvalue plane")
    sc = sc.at_one_delay_pair("region (the eigenvalue plane at one delay pair)", PER_LINK)
    directory = _out_dir(out, sc)
    _emit(region_section(sc, directory), directory, as_json=as_json)


@cli.command("safe-delays")
@scenario_options
@click.option("--spectrum", default="undirected", show_default=True,
              help="Set of eigenvalues of C to certify: undirected (real, [-1, 1]), any (the unit disc), "
                   "interval:A,B, disc:C,R, disc:RE,IM,R, or bound (a certified bound of the scenario's "
                   "topology, sparse for large teams).")  # fmt: skip
@click.option("--tau1-max", type=POSITIVE, help="Right edge of the delay window [default: chart.tau1_max].")
@click.option("--tau2-max", type=POSITIVE, help="Top edge of the delay window [default: chart.tau2_max].")
@click.option("--point", "points", type=LabelledPoint(), multiple=True,
              help="Delay pair to mark and classify, e.g. --point a=0.3,0.2 (repeatable) [default: chart.points].")
def safe_delays_command(scenario: Path | None, spectrum: str, tau1_max: float | None, tau2_max: float | None,
                        points: tuple[tuple[str, float, float], ...], out: Path | None, as_json: bool,
                        **overrides: Any) -> None:  # fmt: skip
    """Delay pairs safe for every team whose eigenvalues of C lie in a set.

    A certified test: at a safe pair every such team is stable, whatever its
    size or graph (for one given team it is sufficient, not necessary). Uses
    the scenario's gains and chart window. Writes safe_delays.png/.svg and
    safe_delays.npz and reports the safe fraction of the window.
    """
    from delayform.analysis.plane.spectrum_sets import parse_spectrum
    from delayform.report import safe_delays_section

    sc = without_actuation(_scenario(scenario, **overrides), "the certificate of safe delays")
    t1max = sc.chart.tau1_max if tau1_max is None else tau1_max
    t2max = sc.chart.tau2_max if tau2_max is None else tau2_max
    # the scenario's points outside a smaller window are left out; points given here must fit
    marks = points or tuple(p for p in sc.chart.points if p[1] <= t1max and p[2] <= t2max)
    for label, a, b in marks:
        if a > t1max or b > t2max:
            raise click.BadParameter(
                f"point {label} ({a:g}, {b:g}) lies outside the window [0, {t1max:g}] x [0, {t2max:g}]",
                param_hint="--point",
            )
    if spectrum.strip().lower() == "bound":
        from delayform.analysis.plane.spectrum_bounds import spectrum_bound

        spec: object = spectrum_bound(sc.topology)
    else:
        spec = parse_spectrum(spectrum)
    directory = _out_dir(out, sc)
    _emit(safe_delays_section(directory, sc.P, sc.D, t1max, t2max, spectrum=spec, points=marks), directory,
          as_json=as_json)
