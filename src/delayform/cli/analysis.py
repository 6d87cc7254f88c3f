"""Analysis commands: factors, chart, roots, map."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from delayform.cli._common import (
    POSITIVE,
    FloatTuple,
    LabelledPoint,
    _emit,
    _inner_progress,
    _out_dir,
    _scenario,
    actuation_option,
    cli,
    scenario_options,
    team_options,
    with_actuation,
)

if TYPE_CHECKING:
    pass


#: what to use instead when a scenario's per-link delays differ between links
PER_LINK = "links (the certified per-link root), box, or simulate / montecarlo (runs over [network])"

#: above this many agents C is summarised, not printed
_PRINT_C_UP_TO = 12
#: factors listed in the text output (all of them are in --json)
_LIST_FACTORS = 30


@cli.command("factors")
@team_options
def factors_command(scenario: Path | None, as_json: bool, **overrides: Any) -> None:
    """Print C, its eigenvalues and the factors of the characteristic equation (Lemma 1).

    Takes a scenario file like every analysis command (its topology and
    gains; delays do not enter the factors). Large teams get a summary of C
    instead of the matrix.
    """
    import numpy as np

    from delayform.characteristic import factors, format_number
    from delayform.report import jsonable

    sc = _scenario(scenario, **overrides)
    topo, P, D = sc.topology, sc.P, sc.D
    fs = factors(topo, P, D)
    eig = topo.eigenvalues
    if as_json:
        click.echo(json.dumps(jsonable({
            "topology": topo.name, "agents": topo.n, "P": P, "D": D,
            "eigenvalues": [complex(v) for v in eig],
            "factors": [{"lam": complex(f.lam), "order": f.order, "multiplicity": f.multiplicity,
                         "centroid": f.is_centroid, "quasi_polynomial": f.quasi_polynomial.describe()}
                        for f in fs],
        }), indent=2))  # fmt: skip
        return
    click.echo(f"Topology {topo.name}: {topo.n} agents, spanning tree: {topo.has_spanning_tree()}")
    if topo.n <= _PRINT_C_UP_TO:
        dense = topo.C.toarray() if hasattr(topo.C, "toarray") else np.asarray(topo.C)
        with np.printoptions(precision=4, suppress=True, linewidth=120):
            click.echo("C = Delta^-1 A =")
            click.echo(str(dense))
    else:
        nnz = int(topo.C.nnz) if hasattr(topo.C, "nnz") else int(np.count_nonzero(topo.C))
        click.echo(f"C = Delta^-1 A: {topo.n} x {topo.n}, {nnz} non-zero entries, every row sums to 1")
    shown = ", ".join(format_number(v, digits=4) for v in eig[:_LIST_FACTORS])
    click.echo("eigenvalues of C: " + shown + (f" ... ({eig.size} in all)" if eig.size > _LIST_FACTORS else ""))
    click.echo(f"Factors of the characteristic equation (paper, eq. 3), P = {P:g}, D = {D:g}:")
    for i, f in enumerate(fs[:_LIST_FACTORS], start=1):
        click.echo(f"  q{i}: {f.describe()}")
        click.echo(f"      {f.quasi_polynomial.describe()} = 0")
    if len(fs) > _LIST_FACTORS:
        click.echo(f"  ... {len(fs) - _LIST_FACTORS} more factors (all of them with --json)")


@cli.command("chart")
@scenario_options
@click.option("--tau1-max", type=POSITIVE, help="Right edge of the delay window [default: chart.tau1_max].")
@click.option("--tau2-max", type=POSITIVE, help="Top edge of the delay window [default: chart.tau2_max].")
@click.option("--point", "points", type=LabelledPoint(), multiple=True,
              help="Delay pair to mark and classify, e.g. --point a=0.3,0.2 (repeatable) [default: chart.points].")
@actuation_option
@click.option("--jitter-margin", "jitter", is_flag=True,
              help="Draw contour lines of the certified jitter margin over the stable region.")
@click.option("--jitter-grid", type=click.IntRange(2, 200), default=24, show_default=True,
              help="Grid points per axis of the jitter-margin map (with --jitter-margin).")
def chart_command(scenario: Path | None, tau1_max: float | None, tau2_max: float | None,
                  points: tuple[tuple[str, float, float], ...], actuation_delay: float | None,
                  jitter: bool, jitter_grid: int, out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Exact CTCR stability chart in the (tau1, tau2) plane.

    Writes stability_chart.png/.svg (kernel curves red, offspring blue,
    stable region shaded), the curve points as ctcr_curves.csv/.npz, and
    reports the stable fraction of the window and, at each marked point,
    the number of unstable roots NU. With --jitter-margin also the certified
    jitter margin on a --jitter-grid grid, as contour lines on the chart and
    as jitter_margin_map.npz (refused up front beyond the time budget).
    """
    from delayform.report import chart_section

    sc = with_actuation(_scenario(scenario, **overrides), actuation_delay)
    sc = sc.at_one_delay_pair("chart (the plane of equal delays on every link, its operating point marked)", PER_LINK)
    chart = replace(
        sc.chart,
        tau1_max=sc.chart.tau1_max if tau1_max is None else tau1_max,
        tau2_max=sc.chart.tau2_max if tau2_max is None else tau2_max,
    )
    # the scenario's own points outside a smaller window are left out; points asked for must fit
    inside = tuple(p for p in sc.chart.points if p[1] <= chart.tau1_max and p[2] <= chart.tau2_max)
    chart = replace(chart, points=points or inside)
    labels = [label for label, _, _ in points]
    if len(set(labels)) != len(labels):
        twice = next(label for label in labels if labels.count(label) > 1)
        raise click.BadParameter(f"the label {twice!r} is given twice", param_hint="--point")
    for label, a, b in points:
        if a > chart.tau1_max or b > chart.tau2_max:
            raise click.BadParameter(
                f"point {label} ({a:g}, {b:g}) lies outside the window [0, {chart.tau1_max:g}] x [0, {chart.tau2_max:g}]",
                param_hint="--point",
            )
    sc = replace(sc, chart=chart)
    grid = jitter_grid if jitter else 0
    # the folder is made by the chart's first write: a map it refuses (beyond the budget) leaves nothing behind
    directory = _out_dir(out, sc, create=False)
    _emit(chart_section(sc, directory, jitter_grid=grid), directory, as_json=as_json)


@cli.command("roots")
@scenario_options
@click.option("--region", type=FloatTuple(4),
              help="Rectangle RE_MIN,RE_MAX,IM_MIN,IM_MAX of the s-plane in which to list every root "
                   "[default: Re from min(-2, 2 Re(dominant)) to 1, Im from -0.01 to 10].")  # fmt: skip
@actuation_option
def roots_command(scenario: Path | None, region: tuple[float, float, float, float] | None,
                  actuation_delay: float | None, out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Dominant root and characteristic roots at one delay pair.

    The dominant root is the rightmost root over all factors, the centroid
    factor's roots at s = 0 excluded; its time constant is 1/|Re| (for an
    unstable root: its growth rate; when it is the centroid's, the
    formation's own time constant too). Also lists every root of every
    factor in --region (roots.csv; a root on its edge is included) and the
    dominant root at the operating delays and the scenario's chart points.
    """
    from delayform.report import roots_section

    if region is not None and (region[0] >= region[1] or region[2] >= region[3]):
        raise click.BadParameter("expected RE_MIN < RE_MAX and IM_MIN < IM_MAX", param_hint="--region")
    sc = with_actuation(_scenario(scenario, **overrides), actuation_delay)
    sc = sc.at_one_delay_pair("roots (every factor's roots at the operating delays)", PER_LINK)
    directory = _out_dir(out, sc)
    with _inner_progress("roots of every factor") as callback:
        section = roots_section(sc, directory, region=region, progress=callback)
    _emit(section, directory, as_json=as_json)


@cli.command("map")
@scenario_options
@click.option("--tau1-range", type=FloatTuple(2, minimum=0.0), help="FIRST,LAST along tau1 [default: map.tau1].")
@click.option("--tau2-range", type=FloatTuple(2, minimum=0.0), help="FIRST,LAST along tau2 [default: map.tau2].")
@click.option("--size", type=FloatTuple(2, integer=True, minimum=2), help="Grid points N1,N2 [default: map.size].")
@actuation_option
def map_command(scenario: Path | None, tau1_range: tuple[float, float] | None,
                tau2_range: tuple[float, float] | None, size: tuple[int, int] | None,
                actuation_delay: float | None, out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Dominant-root map over a grid of delays: surface and contour.

    Writes dominant_surface.png/.svg (Re of the dominant root with the
    plane Re = 0), dominant_contour.png/.svg, and the grid as
    dominant_map.npz and dominant_map.csv. Shows a progress bar.
    """
    from delayform.report import map_section

    for name, rng in (("--tau1-range", tau1_range), ("--tau2-range", tau2_range)):
        if rng is not None and rng[0] >= rng[1]:
            raise click.BadParameter("expected FIRST < LAST", param_hint=name)
    sc = with_actuation(_scenario(scenario, **overrides), actuation_delay)
    grid = replace(
        sc.map,
        tau1=tau1_range or sc.map.tau1,
        tau2=tau2_range or sc.map.tau2,
        size=size or sc.map.size,
    )
    sc = replace(sc, map=grid)
    directory = _out_dir(out, sc)
    with _inner_progress("dominant-root map") as callback:
        section = map_section(sc, directory, progress=callback)
    _emit(section, directory, as_json=as_json)


