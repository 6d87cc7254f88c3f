"""The ``delayform`` command line.

Every subcommand takes an optional scenario file (TOML, see
:mod:`delayform.scenario`; without one, the paper's example) and options that
override it, calls the library, writes figures (PNG and SVG), data (CSV and
NPZ) and summaries (JSON) into ``--out`` and prints a short summary, or the
summary as JSON on stdout with ``--json``. Progress goes to stderr.

Every input error (a bad option, a malformed scenario file, an argument the
library rejects) is one line on stderr naming the problem and exit code 2;
no traceback reaches the user for an input error.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from delayform.errors import DelayformError, InputError

if TYPE_CHECKING:  # the command line imports the library lazily, to start fast
    from delayform.scenario import Scenario
    from delayform.topology import Topology

TOPOLOGY_NAMES = ("paper_six", "ring", "complete", "star")

F = TypeVar("F", bound=Callable[..., Any])


def _fail(message: str, *, code: int = 2) -> None:
    click.echo(f"delayform: error: {message}", err=True)
    sys.exit(code)


def _named_topology(name: str, n: int) -> Topology:
    from delayform import topology as topo

    if name == "paper_six":
        return topo.paper_six()
    return getattr(topo, name)(n)


# ------------------------------------------------------------ option types
class FloatTuple(click.ParamType):
    """``a,b`` (or ``a,b,c,d``): a fixed number of comma-separated numbers."""

    def __init__(self, count: int, *, integer: bool = False, minimum: float | None = None) -> None:
        self.count = count
        self.integer = integer
        self.minimum = minimum
        kind = "INT" if integer else "X"
        self.name = ",".join([kind] * count)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        if len(parts) != self.count:
            self.fail(f"expected {self.count} comma-separated numbers, got {value!r}", param, ctx)
        try:
            numbers = tuple((int if self.integer else float)(p) for p in parts)
        except ValueError:
            self.fail(f"expected {self.count} comma-separated {'integers' if self.integer else 'numbers'}, got {value!r}", param, ctx)
        if self.minimum is not None and min(numbers) < self.minimum:
            self.fail(f"values must be >= {self.minimum:g}, got {value!r}", param, ctx)
        return numbers


class LabelledPoint(click.ParamType):
    """``LABEL=tau1,tau2``: a delay pair to mark on the chart."""

    name = "LABEL=T1,T2"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        label, sep, rest = str(value).partition("=")
        if not sep or not label:
            self.fail(f"expected LABEL=tau1,tau2, got {value!r}", param, ctx)
        t1, t2 = FloatTuple(2, minimum=0.0).convert(rest, param, ctx)
        return (label, t1, t2)


POSITIVE = click.FloatRange(min=0.0, min_open=True)
NON_NEGATIVE = click.FloatRange(min=0.0)


# ------------------------------------------------------- shared options
def scenario_options(func: F) -> F:
    """The scenario argument and the overrides every analysis command shares."""
    options = [
        click.argument("scenario", required=False, type=click.Path(dir_okay=False, path_type=Path)),
        click.option("--topology", "topology_name", type=click.Choice(TOPOLOGY_NAMES),
                     help="Replace the scenario's topology by a named one."),
        click.option("--n", type=click.IntRange(min=2), help="Number of agents for --topology (not paper_six)."),
        click.option("--P", "P", type=POSITIVE, help="Proportional gain P (overrides the scenario)."),
        click.option("--D", "D", type=POSITIVE, help="Derivative gain D (overrides the scenario)."),
        click.option("--tau1", type=NON_NEGATIVE, help="Position delay tau1 in seconds (overrides the scenario)."),
        click.option("--tau2", type=NON_NEGATIVE, help="Velocity delay tau2 in seconds (overrides the scenario)."),
        click.option("--out", type=click.Path(file_okay=False, path_type=Path),
                     help="Output directory [default: out/<scenario name>]."),
        click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout."),
    ]  # fmt: skip
    for option in reversed(options):
        func = option(func)
    return func


def _scenario(
    path: Path | None,
    *,
    topology_name: str | None,
    n: int | None,
    P: float | None,
    D: float | None,
    tau1: float | None,
    tau2: float | None,
) -> Scenario:
    """The scenario file (or the paper's example) with the command-line overrides applied."""
    from delayform.scenario import load_scenario, paper_scenario

    scenario = paper_scenario() if path is None else load_scenario(path)
    topology = None
    if topology_name is not None:
        if topology_name != "paper_six" and n is None:
            raise click.UsageError(f"--topology {topology_name} needs --n")
        topology = _named_topology(topology_name, n or 6)
    elif n is not None:
        raise click.UsageError("--n is only used with --topology")
    return scenario.with_changes(topology=topology, P=P, D=D, tau1=tau1, tau2=tau2)


def _out_dir(out: Path | None, scenario: Scenario) -> Path:
    path = out if out is not None else Path("out") / scenario.name
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise click.BadParameter(f"cannot create output directory {path}: {exc.strerror}", param_hint="--out")
    return path


@contextmanager
def _bar() -> Iterator[Any]:
    """A Rich progress bar on stderr, so ``--json`` output on stdout stays clean."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    with Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=console, transient=not console.is_terminal,
    ) as bar:  # fmt: skip
        yield bar


@contextmanager
def _progress(total: int, *, title: str) -> Iterator[Callable[[str], None]]:
    """A bar over the steps of a command; yields ``step(text)``, called before each step."""
    with _bar() as bar:
        task = bar.add_task(title, total=total)
        started = False

        def step(text: str) -> None:
            nonlocal started
            if started:
                bar.advance(task)
            started = True
            bar.update(task, description=f"{title}: {text}")

        yield step
        bar.update(task, completed=total, description=f"{title}: done")


@contextmanager
def _inner_progress(title: str) -> Iterator[Callable[[int, int], None]]:
    """A bar for a library loop; yields ``callback(done, total)``."""
    with _bar() as bar:
        task = bar.add_task(title, total=None)

        def callback(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield callback


def _emit(section: Any, out: Path, *, as_json: bool) -> None:
    """Print a section's summary: JSON on stdout, or its table and files as text."""
    from delayform.report import jsonable

    files = [str(out / f) for f in section.files]
    if as_json:
        click.echo(json.dumps(jsonable({**section.summary, "files": files}), indent=2))
        return
    click.echo(section.title)
    width = max((len(k) for k, _ in section.table), default=0)
    for key, value in section.table:
        click.echo(f"  {key:<{width}}  {value}")
    if files:
        click.echo("Wrote " + ", ".join(files))


# ------------------------------------------------------------------ group
@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="delayform")
def cli() -> None:
    """delayform: exact stability maps, dominant roots, delay scheduling and
    simulation for robot formations under two communication delays.

    Every command takes an optional SCENARIO file (TOML; see docs/cli.md and
    examples/) and otherwise works on the paper's example: six robots, P = 1,
    D = 0.5, delays (0.3, 0.2). Options override the file. Input errors exit
    with code 2 and one line on stderr.
    """


@cli.command("factors")
@click.option("--topology", "topology_name", type=click.Choice(TOPOLOGY_NAMES), default="paper_six",
              show_default=True, help="Named topology.")
@click.option("--n", type=int, default=6, show_default=True, help="Number of agents (not for paper_six).")
@click.option("--P", "P", type=float, default=1.0, show_default=True, help="Proportional gain P.")
@click.option("--D", "D", type=float, default=0.5, show_default=True, help="Derivative gain D.")
@click.option("--json", "as_json", is_flag=True, help="Print eigenvalues and factors as JSON on stdout.")
def factors_command(topology_name: str, n: int, P: float, D: float, as_json: bool) -> None:
    """Print C, its eigenvalues and the factors of the characteristic equation (Lemma 1)."""
    import numpy as np

    from delayform.characteristic import factors
    from delayform.report import jsonable

    topo = _named_topology(topology_name, n)
    fs = factors(topo, P, D)
    if as_json:
        click.echo(json.dumps(jsonable({
            "topology": topo.name, "agents": topo.n, "P": P, "D": D,
            "eigenvalues": [complex(v) for v in topo.eigenvalues],
            "factors": [{"lam": complex(f.lam), "order": f.order, "multiplicity": f.multiplicity,
                         "centroid": f.is_centroid, "quasi_polynomial": f.quasi_polynomial.describe()}
                        for f in fs],
        }), indent=2))  # fmt: skip
        return
    with np.printoptions(precision=4, suppress=True, linewidth=120):
        click.echo(f"Topology {topo.name}: {topo.n} agents, spanning tree: {topo.has_spanning_tree()}")
        click.echo("C = Delta^-1 A =")
        click.echo(str(topo.C))
        click.echo("eigenvalues of C: " + ", ".join(f"{v:.4g}" for v in topo.eigenvalues))
    click.echo(f"Factors of the characteristic equation (eq. factorized), P = {P:g}, D = {D:g}:")
    for i, f in enumerate(fs, start=1):
        click.echo(f"  q{i}: {f.describe()}")
        click.echo(f"      {f.quasi_polynomial.describe()} = 0")


@cli.command("chart")
@scenario_options
@click.option("--tau1-max", type=POSITIVE, help="Right edge of the delay window [default: chart.tau1_max].")
@click.option("--tau2-max", type=POSITIVE, help="Top edge of the delay window [default: chart.tau2_max].")
@click.option("--point", "points", type=LabelledPoint(), multiple=True,
              help="Delay pair to mark and classify, e.g. --point a=0.3,0.2 (repeatable) [default: chart.points].")
def chart_command(scenario: Path | None, tau1_max: float | None, tau2_max: float | None,
                  points: tuple[tuple[str, float, float], ...], out: Path | None, as_json: bool,
                  **overrides: Any) -> None:  # fmt: skip
    """Exact CTCR stability chart in the (tau1, tau2) plane.

    Writes stability_chart.png/.svg (kernel curves red, offspring blue,
    stable region shaded), the curve points as ctcr_curves.csv/.npz, and
    reports the stable fraction of the window and, at each marked point,
    the number of unstable roots NU.
    """
    from delayform.report import chart_section

    sc = _scenario(scenario, **overrides)
    chart = replace(
        sc.chart,
        tau1_max=sc.chart.tau1_max if tau1_max is None else tau1_max,
        tau2_max=sc.chart.tau2_max if tau2_max is None else tau2_max,
        points=points or sc.chart.points,
    )
    for label, a, b in chart.points:
        if a > chart.tau1_max or b > chart.tau2_max:
            raise click.BadParameter(
                f"point {label} ({a:g}, {b:g}) lies outside the window [0, {chart.tau1_max:g}] x [0, {chart.tau2_max:g}]",
                param_hint="--point",
            )
    sc = replace(sc, chart=chart)
    directory = _out_dir(out, sc)
    _emit(chart_section(sc, directory), directory, as_json=as_json)


@cli.command("roots")
@scenario_options
@click.option("--region", type=FloatTuple(4),
              help="Rectangle RE_MIN,RE_MAX,IM_MIN,IM_MAX of the s-plane in which to list every root "
                   "[default: Re from min(-2, 2 Re(dominant)) to 1, Im from -0.01 to 10].")  # fmt: skip
def roots_command(scenario: Path | None, region: tuple[float, float, float, float] | None,
                  out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Dominant root and characteristic roots at one delay pair.

    The dominant root is the rightmost root over all factors, the centroid
    factor's root s = 0 excluded; its time constant is 1/|Re|. Also lists
    every root of every factor in --region (roots.csv) and the dominant root
    at each of the scenario's chart points.
    """
    from delayform.report import roots_section

    if region is not None and (region[0] >= region[1] or region[2] >= region[3]):
        raise click.BadParameter("expected RE_MIN < RE_MAX and IM_MIN < IM_MAX", param_hint="--region")
    sc = _scenario(scenario, **overrides)
    directory = _out_dir(out, sc)
    _emit(roots_section(sc, directory, region=region), directory, as_json=as_json)


@cli.command("map")
@scenario_options
@click.option("--tau1-range", type=FloatTuple(2, minimum=0.0), help="FIRST,LAST along tau1 [default: map.tau1].")
@click.option("--tau2-range", type=FloatTuple(2, minimum=0.0), help="FIRST,LAST along tau2 [default: map.tau2].")
@click.option("--size", type=FloatTuple(2, integer=True, minimum=2), help="Grid points N1,N2 [default: map.size].")
def map_command(scenario: Path | None, tau1_range: tuple[float, float] | None,
                tau2_range: tuple[float, float] | None, size: tuple[int, int] | None,
                out: Path | None, as_json: bool, **overrides: Any) -> None:  # fmt: skip
    """Dominant-root map over a grid of delays: surface and contour.

    Writes dominant_surface.png/.svg (Re of the dominant root with the
    plane Re = 0), dominant_contour.png/.svg, and the grid as
    dominant_map.npz and dominant_map.csv. Shows a progress bar.
    """
    from delayform.report import map_section

    for name, rng in (("--tau1-range", tau1_range), ("--tau2-range", tau2_range)):
        if rng is not None and rng[0] >= rng[1]:
            raise click.BadParameter("expected FIRST < LAST", param_hint=name)
    sc = _scenario(scenario, **overrides)
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


@cli.command("schedule")
@scenario_options
@click.option("--tau-min", type=FloatTuple(2, minimum=0.0),
              help="Hardware delays T1,T2: delays can only be increased from here [default: schedule.tau_min].")
@click.option("--tau-max", type=FloatTuple(2, minimum=0.0),
              help="Largest acceptable delays T1,T2 [default: schedule.tau_max].")
def schedule_command(scenario: Path | None, tau_min: tuple[float, float] | None,
                     tau_max: tuple[float, float] | None, out: Path | None, as_json: bool,
                     **overrides: Any) -> None:  # fmt: skip
    """Delay scheduling: the stable delays, no smaller than the hardware's, that converge fastest.

    Minimises the real part of the dominant root over
    [tau_min, tau_max] and reports the delays, the root and the predicted
    settling time (schedule.json).
    """
    from delayform.report import schedule_section
    from delayform.scenario import ScheduleSpec

    sc = _scenario(scenario, **overrides)
    lo = tau_min or sc.schedule.tau_min
    hi = tau_max or sc.schedule.tau_max
    if hi[0] < lo[0] or hi[1] < lo[1]:
        raise click.BadParameter(f"expected bounds >= tau_min = {lo[0]:g},{lo[1]:g}", param_hint="--tau-max")
    sc = replace(sc, schedule=ScheduleSpec(tau_min=lo, tau_max=hi))
    directory = _out_dir(out, sc)
    _emit(schedule_section(sc, directory), directory, as_json=as_json)


@cli.command("simulate")
@scenario_options
@click.option("--model", type=click.Choice(("unicycle", "double_integrator")),
              help="Agent model [default: simulation.model].")
@click.option("--duration", type=POSITIVE, help="Simulated time in seconds [default: simulation.duration].")
@click.option("--dt", type=POSITIVE, help="Time step in seconds [default: simulation.dt].")
@click.option("--seed", type=click.IntRange(min=0), help="Seed of the random initial state [default: initial.seed].")
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

    sc = _scenario(scenario, **overrides)
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


def _write_full_report(sc: Scenario, directory: Path, *, paper: bool, as_json: bool) -> None:
    from delayform.report import jsonable, paper_sections, scenario_sections, write_report

    build = paper_sections if paper else scenario_sections
    steps = 9 if paper else 7
    start = time.perf_counter()
    with _progress(steps, title="paper" if paper else "report") as step:
        sections = build(sc, directory, progress=step)
        step("writing index.html")
        seconds = time.perf_counter() - start
        if paper:
            title = "Formation control under two delays: the paper's example reproduced"
            intro = ("Cepeda-Gomez and Perico, Formation Control of Non-holonomic Vehicles under Time Delayed "
                     "Communications, Section 'Simulation Examples': six robots (Fig. topol), P = 1, D = 0.5, "
                     "computed by delayform from scratch.")  # fmt: skip
        else:
            title = f"delayform report: {sc.name}"
            intro = sc.description or f"Scenario {sc.source}."
        index = write_report(sections, directory, title=title, intro=intro, scenario=sc, seconds=seconds)
    if as_json:
        click.echo(json.dumps(jsonable({s.key: s.summary for s in sections} | {"index": str(index)}), indent=2))
        return
    for section in sections:
        _emit(section, directory, as_json=False)
    click.echo(f"Report: {index} ({seconds:.1f} s)")


@cli.command("report")
@scenario_options
def report_command(scenario: Path | None, out: Path | None, as_json: bool, **overrides: Any) -> None:
    """All analyses of one scenario as one self-contained HTML page.

    Runs factors, chart, roots, map, schedule and simulate and writes their
    files plus index.html (figures embedded, a table of numbers and a short
    text per figure) and summary.json into --out.
    """
    sc = _scenario(scenario, **overrides)
    _write_full_report(sc, _out_dir(out, sc), paper=False, as_json=as_json)


@cli.command("paper")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=Path("out/paper"),
              show_default=True, help="Output directory.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
def paper_command(out: Path, as_json: bool) -> None:
    """Reproduce the paper's example end to end (what `make demo` runs).

    Eigenvalues and factors of the six-robot team, the stability chart with
    points a..e, x/y versus time at a and b, traces at a, the dominant-root
    surface and contour, the best delays by scheduling and the settling
    times; all into --out with index.html and summary.json.
    """
    from delayform.scenario import paper_scenario

    sc = paper_scenario()
    _write_full_report(sc, _out_dir(out, sc), paper=True, as_json=as_json)


# ------------------------------------------------------------------- entry
#: click >= 8.2 raises this for a group called without a command; older click prints help itself
_NO_ARGS_IS_HELP: Any = getattr(click.exceptions, "NoArgsIsHelpError", ())


def main(argv: list[str] | None = None) -> None:
    """Entry point of the console script: one line and exit code 2 for every input error."""
    try:
        code = cli.main(args=argv, prog_name="delayform", standalone_mode=False)
    except _NO_ARGS_IS_HELP as exc:  # plain `delayform`: show the help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else str(exc))
        sys.exit(0)
    except click.UsageError as exc:  # bad option, missing value, bad parameter
        hint = f" (see: delayform {exc.ctx.info_name} --help)" if exc.ctx is not None and exc.ctx.parent else ""
        _fail(exc.format_message().replace("\n", " ") + hint)
    except click.ClickException as exc:
        _fail(exc.format_message().replace("\n", " "))
    except click.Abort:
        click.echo("delayform: aborted", err=True)
        sys.exit(130)
    except InputError as exc:
        _fail(str(exc).replace("\n", " "))
    except DelayformError as exc:  # a computation that did not succeed: not the user's input
        _fail(str(exc).replace("\n", " "), code=1)
    sys.exit(code if isinstance(code, int) else 0)
