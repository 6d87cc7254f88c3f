"""Shared pieces of the command line: the group, option types, scenario overrides, progress bars, output."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

if TYPE_CHECKING:  # the command line imports the library lazily, to start fast
    from delayform.scenario import Scenario
    from delayform.topology import Topology

TOPOLOGY_NAMES = ("paper_six", "ring", "complete", "star", "random_digraph")
#: the keys of delayform.formation.SHAPES, then the old names of SHAPE_ALIASES (kept literal: the CLI starts fast)
FORMATION_NAMES = ("polygon", "hexagon", "line", "block", "v")
OLD_FORMATION_NAMES = ("grid",)

F = TypeVar("F", bound=Callable[..., Any])


def _fail(message: str, *, code: int = 2) -> None:
    click.echo(f"delayform: error: {message}", err=True)
    sys.exit(code)


def _named_topology(name: str, n: int | None, *, p: float | None = None, seed: int | None = None) -> Topology:
    """A named topology from the command-line options, each option checked against the name."""
    from delayform import topology as topo

    if name == "paper_six":
        if n is not None and n != 6:
            raise click.BadParameter(f"the paper's topology has 6 agents, got --n {n}", param_hint="--n")
        if p is not None:
            raise click.UsageError("--p is only used with --topology random_digraph")
        return topo.paper_six()
    if n is None:
        raise click.UsageError(f"--topology {name} needs --n")
    if name == "random_digraph":
        if p is None:
            raise click.UsageError("--topology random_digraph needs --p (probability of each extra edge)")
        return topo.random_digraph(n, p, seed=0 if seed is None else seed)
    if p is not None:
        raise click.UsageError("--p is only used with --topology random_digraph")
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


class DelayValues(click.ParamType):
    """``START:STOP:COUNT`` (evenly spaced, both ends included) or ``T1,T2,...``: delays in seconds."""

    name = "START:STOP:COUNT"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        import math

        if isinstance(value, tuple):
            return value
        text = str(value)
        try:
            if ":" in text:
                start, stop, count = text.split(":")
                a, b, m = float(start), float(stop), int(count)
                if m < 1 or m > 200:
                    self.fail(f"COUNT must be between 1 and 200, got {m}", param, ctx)
                values = tuple(a + (b - a) * i / (m - 1) for i in range(m)) if m > 1 else (a,)
            else:
                values = tuple(float(p) for p in text.split(","))
        except ValueError:
            self.fail(f"expected START:STOP:COUNT or comma-separated delays, got {value!r}", param, ctx)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            self.fail(f"delays must be finite and >= 0, got {value!r}", param, ctx)
        if len(set(values)) != len(values) or list(values) != sorted(values):
            self.fail(f"delays must increase, got {value!r}", param, ctx)
        return values


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


class OutDir(click.Path):
    """An output folder; an empty string (which would mean the current folder) is refused."""

    def __init__(self) -> None:
        super().__init__(file_okay=False, path_type=Path)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str) and not value.strip():
            self.fail("expected a folder, got an empty path", param, ctx)
        return super().convert(value, param, ctx)


POSITIVE = click.FloatRange(min=0.0, min_open=True)
NON_NEGATIVE = click.FloatRange(min=0.0)


# ------------------------------------------------------- shared options
#: command-line option -> field of delayform.simulation.RobotLimits
_LIMIT_OPTIONS = (
    ("max_speed", "--max-speed", "Largest linear speed |v| (m/s)."),
    ("max_turn_rate", "--max-turn-rate", "Largest turn rate |omega| (rad/s)."),
    ("max_acceleration", "--max-acceleration", "Largest linear acceleration |dv/dt| (m/s^2)."),
    ("max_wheel_speed", "--max-wheel-speed", "Largest wheel speed (rad/s)."),
    ("wheel_radius", "--wheel-radius", "Wheel radius (m)."),
    ("axle_length", "--axle-length", "Distance between the wheels (m)."),
)


#: the names of delayform.deploy.PROFILES (kept literal: the CLI starts fast; tests/test_deploy_cli.py checks them)
ROBOT_NAMES = ("create", "create2", "create3", "robotarium", "turtlebot3_burger")


def limit_options(func: F) -> F:
    """``--robot``, ``--limits/--no-limits`` and one option per actuator limit (the scenario's ``[robot]`` table)."""
    for field, flag, text in reversed(_LIMIT_OPTIONS):
        func = click.option(flag, field, type=POSITIVE,
                            help=f"{text} Implies --limits [default: robot.{field} or the iRobot Create's].")(func)  # fmt: skip
    func = click.option("--robot", "robot_profile", metavar="NAME",
                        help=f"A real robot's limits and geometry ({', '.join(ROBOT_NAMES)}; docs/deploy.md). "
                             "Implies --limits; the limit options override single values.")(func)  # fmt: skip
    return click.option("--limits/--no-limits", "use_limits", default=None,
                        help="Robots with actuator limits (the scenario's [robot] table, else the iRobot Create's) "
                             "or ideal robots [default: limits when the scenario has a [robot] table].")(func)  # fmt: skip


def _limits_given(overrides: dict[str, Any]) -> dict[str, Any]:
    """Pop the limit options (and ``--robot``, as ``"profile"``) from a command's keyword arguments; those given."""
    given = {field: overrides.pop(field) for field, _, _ in _LIMIT_OPTIONS}
    given["profile"] = overrides.pop("robot_profile", None)
    return {k: v for k, v in given.items() if v is not None}


def _robot(robot: Any, use_limits: bool | None, given: dict[str, Any], model: str) -> Any:
    """The robots' limits from the scenario's ``[robot]`` table, ``--robot``, ``--limits/--no-limits`` and the limit options."""
    from dataclasses import replace

    from delayform.simulation import IROBOT_CREATE

    given = dict(given)
    name = given.pop("profile", None)
    if use_limits is False:
        if given or name is not None:
            raise click.UsageError("--no-limits cannot be combined with " + ", ".join(
                ["--robot"] * (name is not None) + [flag for field, flag, _ in _LIMIT_OPTIONS if field in given]))  # fmt: skip
        return None
    if name is not None:
        from delayform.deploy import robot_profile

        robot = robot_profile(name).limits
    if use_limits or given:
        robot = replace(robot or IROBOT_CREATE, **given)
    if robot is not None and model == "double_integrator":
        raise click.UsageError("actuator limits apply to robots: use --model unicycle or --no-limits")
    return robot


def _with_robot(scenario: Scenario, use_limits: bool | None, given: dict[str, Any], model: str) -> Scenario:
    """The scenario with the robots of :func:`_robot`; a robot profile's body and arena checked against the formation.

    With a profile (``--robot`` or the scenario's ``[robot] profile``) a
    formation the robots cannot hold is refused here, before anything runs
    (:func:`delayform.deploy.fit.require_formation_fit`).
    """
    from dataclasses import replace

    robot = _robot(scenario.robot, use_limits, given, model)
    profile = given.get("profile", scenario.robot_profile if robot is not None else None)
    if profile is not None:
        from delayform.deploy import robot_profile
        from delayform.deploy.fit import require_formation_fit

        require_formation_fit(scenario.desired_positions(), replace(robot_profile(profile), limits=robot))
    return replace(scenario, robot=robot, robot_profile=profile)
def radius_option(func: F) -> F:
    """``--radius``, ``--safety`` (the scenario's ``[robot]`` table) and ``--assignment`` (``[simulation]``)."""
    func = click.option("--safety", type=click.Choice(("barrier", "none")),
                        help="Filter every command through control barrier functions that keep the bodies apart "
                             "(barrier) or not (none) [default: robot.safety, else none].")(func)  # fmt: skip
    func = click.option("--assignment", type=click.Choice(("given", "optimal")),
                        help="Which robot takes which slot: given (robot i, slot i) or optimal (least total squared "
                             "distance to the predicted final positions) [default: simulation.assignment].")(func)  # fmt: skip
    return click.option("--radius", type=NON_NEGATIVE,
                        help="Body radius of each robot (m), for contacts [default: robot.radius, else 0.17 m "
                             "(the iRobot Create) for robots and 0 (points) for double integrators].")(func)  # fmt: skip


def _finite_delay(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not (math.isfinite(value) and value >= 0.0):
        raise click.BadParameter(f"{value} is not a finite non-negative delay (seconds)")
    return value


def actuation_option(func: F) -> F:
    """``--actuation-delay`` (the scenario's ``[robot] actuation_delay``): each robot applies its command late."""
    return click.option("--actuation-delay", "actuation_delay", type=float, callback=_finite_delay,
                        help="Actuation delay tau_a (s): each robot applies its command tau_a late; every factor "
                             "gains the delayed own-state terms [default: robot.actuation_delay, else 0].")(func)  # fmt: skip


def without_actuation(scenario: Scenario, what: str) -> Scenario:
    """The scenario, refused (exit 2, one line) when it has an actuation delay that ``what`` would ignore."""
    if scenario.actuation_delay > 0.0:
        from delayform.errors import ScenarioError

        raise ScenarioError(
            f"{what} has no actuation delay in its theory, and the scenario has [robot] actuation_delay = "
            f"{scenario.actuation_delay:g} s; set it to 0 here (chart, roots, map, schedule, report and simulate take it)"
        )
    return scenario


def with_actuation(scenario: Scenario, actuation_delay: float | None) -> Scenario:
    """The scenario with ``--actuation-delay`` applied when given."""
    from dataclasses import replace

    return scenario if actuation_delay is None else replace(scenario, actuation_delay=actuation_delay)


def _team_options() -> list[Callable[[F], F]]:
    return [
        click.argument("scenario", required=False, type=click.Path(path_type=Path)),
        click.option("--topology", "topology_name", type=click.Choice(TOPOLOGY_NAMES),
                     help="Replace the scenario's topology by a named one."),
        click.option("--n", type=click.IntRange(min=2, max=100_000),
                     help="Number of agents for --topology (paper_six has 6)."),
        click.option("--p", type=click.FloatRange(0.0, 1.0),
                     help="random_digraph only: probability of each extra edge."),
        click.option("--seed", type=click.IntRange(min=0),
                     help="Seed of random_digraph (and, for simulate, of the random initial state; for montecarlo, of the runs)."),
        click.option("--P", "P", type=POSITIVE, help="Proportional gain P (overrides the scenario)."),
        click.option("--D", "D", type=POSITIVE, help="Derivative gain D (overrides the scenario)."),
    ]  # fmt: skip


def team_options(func: F) -> F:
    """The scenario argument and the topology and gain overrides (commands without delays)."""
    for option in reversed([*_team_options(), click.option("--json", "as_json", is_flag=True,
                                                             help="Print the summary as JSON on stdout.")]):
        func = option(func)
    return func


def scenario_options(func: F) -> F:
    """The scenario argument and the overrides every analysis command shares."""
    options = [
        *_team_options(),
        click.option("--formation", "formation_name", type=click.Choice((*FORMATION_NAMES, *OLD_FORMATION_NAMES)),
                     help="Replace the scenario's formation shape (spacing kept); block = agents in rows "
                          "and columns ('grid' is its old name, still accepted)."),
        click.option("--tau1", type=NON_NEGATIVE, help="Position delay tau1 in seconds (overrides the scenario)."),
        click.option("--tau2", type=NON_NEGATIVE, help="Velocity delay tau2 in seconds (overrides the scenario)."),
        click.option("--out", type=OutDir(),
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
    tau1: float | None = None,
    tau2: float | None = None,
    p: float | None = None,
    seed: int | None = None,
    formation_name: str | None = None,
) -> Scenario:
    """The scenario file (or the paper's example) with the command-line overrides applied.

    The formation is checked only by the commands that need it (simulate,
    report): a chart of twelve robots does not need the paper's hexagon.
    """
    from delayform.scenario import load_scenario, paper_scenario

    if path is not None and path.is_dir():
        raise click.BadParameter(f"{path} is a directory, expected a scenario file (.toml)", param_hint="SCENARIO")
    scenario = paper_scenario() if path is None else load_scenario(path)
    topology = None
    if topology_name is not None:
        topology = _named_topology(topology_name, n, p=p, seed=seed)
    elif n is not None or p is not None:
        raise click.UsageError(f"--{'n' if n is not None else 'p'} is only used with --topology")
    return scenario.with_changes(topology=topology, P=P, D=D, tau1=tau1, tau2=tau2, formation=formation_name)


def _simulation_spec(scenario: Scenario, *, model: str | None, duration: float | None, dt: float | None,
                     assignment: str | None = None) -> Any:  # fmt: skip
    """The scenario's ``[simulation]`` table with ``--model``, ``--duration``, ``--dt`` and ``--assignment`` applied."""
    from delayform.scenario import SimulationSpec

    sim = scenario.simulation
    spec = SimulationSpec(model=model or sim.model, duration=sim.duration if duration is None else duration,
                          dt=sim.dt if dt is None else dt, assignment=assignment or sim.assignment)  # fmt: skip
    if spec.dt >= spec.duration:
        raise click.BadParameter(f"the step must be smaller than the duration {spec.duration:g}", param_hint="--dt")
    if spec.model == "physics":
        from delayform._extras import require_extra

        require_extra("physics")  # the engine comes with an extra: say which, before any work
    return spec


def _safe_name(name: str) -> str:
    """A scenario name as one harmless path component: no separators, no leading dots, not empty."""
    import re

    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._-")
    return safe[:100] or "scenario"


def _out_dir(out: Path | None, scenario: Scenario, *, create: bool = True) -> Path:
    """The output folder, proven writable before anything is computed; created now, or by the first write.

    Only ``--out`` (or ``out/<scenario name>``) is ever written to; the name
    becomes a single path component, so ``name = "../../evil"`` stays inside.
    With ``create=False`` the folder is made by the computation when it
    writes, so input that the computation refuses leaves no folder behind.
    """
    if out is not None and str(out).strip() == "":
        raise click.BadParameter("expected a folder, got an empty path", param_hint="--out")
    path = out if out is not None else Path("out") / _safe_name(scenario.name)
    return writable_folder(path, "the output folder", "--out", create=create)


def refuse_file_in_the_way(path: Path, what: str, hint: str) -> None:
    """Refuse a folder ``path`` that cannot be created because it, or one of its parents, is a file."""
    try:
        blocker = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), None)
    except (OSError, ValueError):  # a NUL byte, a name too long: mkdir says which
        return
    if blocker is not None:
        raise click.BadParameter(f"cannot write into {what} {path}: {blocker} is a file, not a folder", param_hint=hint)


def writable_folder(path: Path, what: str, hint: str, *, create: bool = True) -> Path:
    """``path`` created with its parents (as every output of the command line is) and proven writable.

    One rule for ``--out`` and the folder of ``--mcap``: a missing folder is
    created, a file in its place is named as a file, and an unwritable one is
    refused, all before anything is computed. With ``create=False`` a missing
    folder is left for its first write to create: the nearest folder that
    exists must then take a new entry.
    """
    import tempfile

    refuse_file_in_the_way(path, what, hint)
    try:
        if create:
            path.mkdir(parents=True, exist_ok=True)
            probe = path
        else:
            if "\x00" in str(path):
                raise ValueError("embedded null byte")
            probe = next((p for p in (path.absolute(), *path.absolute().parents) if p.is_dir()))
        with tempfile.TemporaryFile(dir=probe):
            pass
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the name
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise click.BadParameter(f"cannot write into {what} {path}: {reason}", param_hint=hint)
    return path


@contextmanager
def _bar() -> Iterator[Any]:
    """A Rich progress bar on stderr, so ``--json`` output on stdout stays clean.

    Drawn only on a terminal: redirected to a file or a pipe, stderr stays
    empty (not even the blank line a hidden bar would leave).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    with Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=console, disable=not console.is_terminal,
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


