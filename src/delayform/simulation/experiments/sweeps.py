"""Monte Carlo runs and parameter sweeps: in this process, on a local Dask cluster, or on a remote one.

A sweep runs :func:`~delayform.simulation.experiments.montecarlo.monte_carlo` at every
point of a grid (delays, gains, topologies, networks). Where the runs go is
chosen by :func:`executor_for`:

* nothing: this process, one run after another;
* ``workers=N``: a local ``dask.distributed.LocalCluster`` of N worker
  processes with one thread each, started for the sweep and closed after it;
* ``scheduler="tcp://host:8786"``: an existing Dask cluster.

Every (point, run) pair is one task whose seeds are fixed up front
(:func:`~delayform.simulation.experiments.montecarlo.run_seeds`), so the three give the
same numbers, whatever the order in which tasks finish. Every point of a
sweep uses the same seed, hence the same initial states and the same network
draws (common random numbers): differences between points come from the
parameter, not from luck. Long sweeps show a Rich progress bar on stderr
with ``progress=True``.

Examples
--------
>>> from delayform.model.network import Jitter, Network
>>> from delayform.topology import ring
>>> setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", duration=4.0, dt=0.05)
>>> nets = [Network(jitter=Jitter(b, b)) for b in (0.0, 0.1)]
>>> result = network_sweep(setup, nets, ["0", "0.1"], runs=2, seed=3)
>>> [r.runs for r in result.results]
[2, 2]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
import logging
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import product
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._extras import require_extra
from delayform._validation import validated
from delayform.errors import ClusterError, SimulationInputError
from delayform.formation import named_formation
from delayform.resources import require
from delayform.simulation.experiments import montecarlo as mc
from delayform.simulation.experiments.montecarlo import (
    Executor,
    MonteCarloResult,
    Progress,
    SerialExecutor,
    Setup,
    collect,
    estimate_cost,
    make_setup,
    run_seeds,
    simulate_run,
)
from delayform.model.network import Network
from delayform.topology import Topology

__all__ = [
    "DaskExecutor",
    "CONNECT_TIMEOUT",
    "check_scheduler",
    "check_sweep",
    "check_workers",
    "parse_scheduler",
    "usable_cores",
    "executor_for",
    "make_setup",
    "SweepResult",
    "sweep",
    "delay_sweep",
    "gain_sweep",
    "topology_sweep",
    "network_sweep",
    "rich_progress",
]


# ---------------------------------------------------------------- executors
class DaskExecutor:
    """Runs tasks on a Dask cluster through a ``distributed.Client``.

    Parameters
    ----------
    client
        A connected ``distributed.Client``.
    """

    def __init__(self, client: Any) -> None:
        self.client = client

    @property
    def workers(self) -> int:
        """Number of worker processes the scheduler knows."""
        return max(1, len(self.client.scheduler_info(n_workers=-1).get("workers", {})))

    def map(self, fn: Callable[[Any], Any], tasks: Sequence[Any], progress: Progress | None = None) -> list[Any]:
        """``[fn(t) for t in tasks]`` on the cluster, results in the order of ``tasks``.

        Parameters
        ----------
        fn
            A module-level function (workers import it by name).
        tasks
            Picklable tasks.
        progress
            Optional callback ``(done, total)``, called as tasks finish.
        """
        from distributed import as_completed

        # pure=False: two equal-looking tasks are still two runs
        futures = self.client.map(fn, list(tasks), pure=False)
        done = 0
        for _ in as_completed(futures):
            done += 1
            if progress is not None:
                progress(done, len(futures))
        return self.client.gather(futures)


#: seconds to wait for a Dask scheduler (TCP connection, then its greeting) before giving up
CONNECT_TIMEOUT = 5.0
#: largest first message a Dask scheduler sends (its handshake is a few hundred bytes)
_MAX_GREETING = 1 << 20


@validated(ClusterError)
def usable_cores() -> int:
    """Number of CPU cores this process may run on (its affinity mask where the OS has one)."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS, Windows: no affinity mask
        return max(1, os.cpu_count() or 1)


@validated(ClusterError)
def check_workers(workers: object) -> int:
    """A local cluster's worker count, checked against this machine before any process starts.

    Each worker is one process with one thread running GIL-bound NumPy loops,
    so more workers than cores only compete for the same cores (and every
    process costs memory and semaphores): the count must be at most
    :func:`usable_cores`.

    Parameters
    ----------
    workers
        A positive integer.

    Raises
    ------
    ClusterError
        Not a positive integer, or more than the cores of this machine.
    MissingExtraError
        Without Dask (the ``cluster`` extra).
    """
    require_extra("cluster")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ClusterError(f"workers must be a positive integer, got {workers!r}")
    cores = usable_cores()
    if workers > cores:
        raise ClusterError(f"workers: {workers} worker processes asked for, but this machine has {cores} "
                           f"core{'s' if cores > 1 else ''}; use at most {cores} (one process per core)")  # fmt: skip
    return workers


@validated(ClusterError)
def parse_scheduler(address: object) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of a Dask scheduler address, checked before anything connects.

    Accepted: ``tcp://host:port`` or ``tls://host:port`` (``host:port`` means
    tcp), the host a name, an IPv4 address or a bracketed IPv6 address
    (``tcp://[::1]:8786``), the port 1-65535; nothing after the port.

    Parameters
    ----------
    address
        The address as a string.

    Raises
    ------
    ClusterError
        Anything else, in one line naming the address.
    MissingExtraError
        Without Dask (the ``cluster`` extra): no address is of use then.

    >>> parse_scheduler("tcp://[::1]:8786")
    ('tcp', '::1', 8786)
    """
    from urllib.parse import urlsplit

    require_extra("cluster")

    def bad(reason: str) -> ClusterError:
        return ClusterError(f"scheduler: {address!r} is not an address like tcp://host:8786 ({reason})")

    if not isinstance(address, str):
        raise ClusterError(f"scheduler must be an address like tcp://host:8786, got {type(address).__name__}")
    text = address.strip()
    if not text or any(c.isspace() for c in text):
        raise bad("empty or with spaces")
    try:
        parts = urlsplit(text if "://" in text else f"tcp://{text}")
        port = parts.port
    except ValueError as exc:  # an unclosed IPv6 bracket, a port that is no number
        raise bad(str(exc).lower()) from None
    if parts.scheme not in ("tcp", "tls"):
        raise bad(f"the protocol must be tcp or tls, not {parts.scheme or 'empty'}")
    if not parts.hostname:
        raise bad("no host")
    if port is None or port == 0:
        raise bad("no port")
    if parts.path not in ("", "/") or parts.query or parts.fragment or parts.username is not None:
        raise bad("nothing may follow the port")
    return parts.scheme, parts.hostname, port


@validated(ClusterError)
def check_scheduler(address: object, timeout: float = CONNECT_TIMEOUT) -> str:
    """Prove, within ``timeout`` seconds, that a Dask scheduler answers at ``address``; return the address.

    The address is parsed first (:func:`parse_scheduler`). For ``tcp`` the
    check opens a connection and waits for the scheduler's greeting: a Dask
    server speaks first, a handshake framed as an 8-byte length, a frame
    count and frame lengths that add up. A closed port, a host that does not
    answer, a server that stays silent (a web server waits for a request) or
    one that sends anything else (its first bytes read as a length of
    exabytes) is refused here, instead of hanging the Client or making it
    allocate that length. ``tls`` is left to the Client (with the same timeout).

    Parameters
    ----------
    address
        The scheduler's address.
    timeout
        Seconds for the connection and for the greeting, each.

    Raises
    ------
    ClusterError
        A malformed address, or no Dask scheduler there, in one line.
    """
    import socket
    import struct

    scheme, host, port = parse_scheduler(address)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout < math.inf:
        raise ClusterError(f"timeout must be a positive number of seconds, got {timeout!r}")
    if scheme != "tcp":
        return str(address)
    where = f"a Dask scheduler at {address!r}"
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except TimeoutError:
        raise ClusterError(f"cannot reach {where}: no answer within {timeout:g} s") from None
    except OSError as exc:
        raise ClusterError(f"cannot reach {where} ({exc.strerror or type(exc).__name__})") from None
    with sock:
        try:  # Dask's framing (distributed.comm.tcp): native-order uint64 counts
            head = _receive(sock, 8)
            (size,) = struct.unpack("=Q", head) if len(head) == 8 else (0,)
            if not 16 <= size <= _MAX_GREETING:
                raise ClusterError(f"{address!r} is not a Dask scheduler (it answered {head!r})")
            body = _receive(sock, size)
        except TimeoutError:
            raise ClusterError(f"{address!r} is not a Dask scheduler: nothing came back within {timeout:g} s "
                               "(a Dask scheduler greets first; a web server waits)") from None  # fmt: skip
        except OSError as exc:
            raise ClusterError(f"cannot reach {where} ({exc.strerror or type(exc).__name__})") from None
    # the message: a frame count, the frame lengths, the frames; they must add up to the length sent
    count = struct.unpack("=Q", body[:8])[0] if len(body) >= 8 else 0
    framed = 0 < count <= 64 and len(body) >= 8 + 8 * count
    lengths = struct.unpack(f"={count}Q", body[8 : 8 + 8 * count]) if framed else ()
    if not lengths or 8 + 8 * count + sum(lengths) != size:
        raise ClusterError(f"{address!r} is not a Dask scheduler (its first message is not a Dask handshake)")
    return str(address)


def _receive(sock: Any, n: int) -> bytes:
    """Exactly ``n`` bytes, or fewer if the peer closed the connection (timeouts raise)."""
    chunks, got = [], 0
    while got < n:
        chunk = sock.recv(min(n - got, 65536))
        if not chunk:
            break
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


@validated()
@contextmanager
def executor_for(*, workers: int | None = None, scheduler: str | None = None,
                 timeout: float = CONNECT_TIMEOUT) -> Iterator[Executor]:  # fmt: skip
    """Where runs go: this process, a local Dask cluster, or an existing one (module doc).

    Parameters
    ----------
    workers
        Start a local cluster of this many worker processes (one thread
        each), at most the cores of this machine (:func:`check_workers`).
    scheduler
        Address of an existing Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``
        (:func:`check_scheduler`).
    timeout
        Seconds to wait for the scheduler (and for its first worker) before giving up.

    Yields
    ------
    Executor
        :class:`~delayform.simulation.experiments.montecarlo.SerialExecutor` or :class:`DaskExecutor`.

    Raises
    ------
    ClusterError
        Both ``workers`` and ``scheduler`` given, a bad worker count, a
        malformed address, no Dask scheduler at it, or a scheduler without workers.
    """
    if workers is not None and scheduler is not None:
        raise ClusterError("give either workers (a local cluster) or scheduler (an existing one), not both")
    if workers is not None:
        check_workers(workers)
    if scheduler is not None:
        check_scheduler(scheduler, timeout)
    if workers is None and scheduler is None:
        yield SerialExecutor()
        return
    # the scheduler and client log every connection at INFO on stderr; a sweep reports through its result
    import distributed  # noqa: F401  (sets up its loggers, which are quieted below)

    names = ["distributed"] + [n for n in logging.root.manager.loggerDict if n.startswith("distributed.")]
    levels = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.ERROR)
    try:
        if workers is not None:
            with _local(workers) as ex:
                yield ex
        else:
            with _remote(str(scheduler), timeout) as ex:
                yield ex
    finally:
        for n, level in levels.items():
            logging.getLogger(n).setLevel(level)


@contextmanager
def _local(workers: int) -> Iterator[DaskExecutor]:
    from distributed import Client, LocalCluster

    # processes with one thread each: the runs are pure Python/NumPy loops that hold the GIL
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, worker_dashboard_address=None, silence_logs=logging.ERROR)  # fmt: skip
    except (RuntimeError, OSError, TimeoutError) as exc:  # e.g. "Nanny failed to start": no traceback of Dask's
        raise ClusterError(f"could not start a local Dask cluster of {workers} worker process"
                           f"{'es' if workers > 1 else ''} ({exc}); run without workers") from None  # fmt: skip
    try:
        with Client(cluster) as client:
            yield DaskExecutor(client)
    finally:
        cluster.close()


@contextmanager
def _remote(scheduler: str, timeout: float) -> Iterator[DaskExecutor]:
    from distributed import Client

    try:
        client = Client(scheduler, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {scheduler!r} ({type(exc).__name__})") from None
    try:
        try:  # a scheduler without workers would take the tasks and never run them
            client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError):
            raise ClusterError(f"the Dask scheduler at {scheduler!r} has no workers (none joined within "
                               f"{timeout:g} s); start some with `dask worker {scheduler}`") from None  # fmt: skip
        yield DaskExecutor(client)
    finally:
        client.close()


@contextmanager
def rich_progress(title: str) -> Iterator[Progress]:
    """A Rich progress bar on stderr; yields the ``(done, total)`` callback.

    Parameters
    ----------
    title
        Text in front of the bar.
    """
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    console = Console(stderr=True)
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                  console=console, transient=not console.is_terminal) as bar:  # fmt: skip
        task = bar.add_task(title, total=None)

        def callback(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield callback


# ------------------------------------------------------------------ result
@validated()
@dataclass(frozen=True, eq=False)
class SweepResult:
    """Monte Carlo results at every point of a sweep.

    Attributes
    ----------
    parameter
        What was swept (``"delays"``, ``"gains"``, ``"topology"``, ``"network"``).
    labels
        One label per point.
    values
        The swept value(s) of each point, e.g. ``(tau1, tau2)``.
    results
        One :class:`~delayform.simulation.experiments.montecarlo.MonteCarloResult` per point.
    """

    parameter: str
    labels: tuple[str, ...]
    values: tuple[Any, ...]
    results: tuple[MonteCarloResult, ...]

    def statistic(self, metric: str = "settling_time", q: float = 0.5) -> NDArray[np.float64]:
        """One quantile of a metric at every point.

        Parameters
        ----------
        metric
            ``settling_time``, ``final_error``, ``peak_command_1``, ``peak_command_2`` or
            ``min_distance`` (closest approach of two robots).
        q
            Probability of the quantile (:func:`~delayform.simulation.experiments.montecarlo.quantile`:
            the ordinary median at 0.5; runs that did not settle count as infinite).
        """
        return np.array([float(mc.run_quantile(r.metric(metric), q)) for r in self.results])

    def table(self) -> tuple[tuple[str, str], ...]:
        """Rows ``(point, settling median [5 %, 95 %], settled fraction, closest approach, contacts)``."""
        rows = []
        for label, r in zip(self.labels, self.results, strict=True):
            s = r.summary()["settling_time"]
            close = r.summary()["min_distance"]["median"]
            bodies = f", contacts in {100 * r.contact_probability:.0f} %" if r.setup.robot.body_radius > 0 else ""
            rows.append((label, f"{_fmt(s['median'])} s [{_fmt(s['q05'])}, {_fmt(s['q95'])}], "
                                f"{100 * r.settled_fraction:.0f} % settled, closest {_fmt(close)} m{bodies}"))  # fmt: skip
        return tuple(rows)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the parameter and each point's label, values and Monte Carlo summary."""
        return {
            "parameter": self.parameter,
            "points": [
                {"label": lab, "value": val, **r.summary()}
                for lab, val, r in zip(self.labels, self.values, self.results, strict=True)
            ],
        }

    def plot(self, ax: Any = None, *, x: ArrayLike | None = None, metric: str = "settling_time",
             label: str = "", xlabel: str = "") -> Any:  # fmt: skip
        """Median of a metric against the points (or ``x``), with the 5-95 % band; returns the axes.

        Parameters
        ----------
        ax
            Axes to draw on; None makes a figure.
        x
            Abscissa of each point; default 0, 1, 2, ...
        metric
            The metric (see :meth:`statistic`).
        label, xlabel
            Legend entry and x-axis label.
        """
        from delayform.plots import plot_metric_against

        xs = np.arange(len(self.results)) if x is None else np.asarray(x, dtype=np.float64)
        return plot_metric_against(
            xs, self.statistic(metric, 0.5), self.statistic(metric, 0.05), self.statistic(metric, 0.95), ax=ax,
            label=label, xlabel=xlabel or self.parameter, ylabel=metric.replace("_", " "),
        )  # fmt: skip


def _fmt(value: float) -> str:
    return f"{value:.4g}" if math.isfinite(value) else "inf"


# ------------------------------------------------------------------ sweeps
@validated()
def sweep(
    setup: Setup,
    changes: Sequence[Mapping[str, Any]],
    *,
    labels: Sequence[str] | None = None,
    parameter: str = "points",
    values: Sequence[Any] | None = None,
    runs: int,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | Progress = False,
) -> SweepResult:
    """Monte Carlo at ``setup`` changed by each entry of ``changes`` (fields of :class:`Setup`).

    All (point, run) tasks go to one executor at once, so the workers stay
    busy across points.

    Parameters
    ----------
    setup
        The base point (:func:`make_setup`).
    changes
        One mapping of field -> value per point, e.g. ``{"tau1": 1.0, "tau2": 0.5}``.
    labels
        One label per point; default ``"0"``, ``"1"``, ...
    parameter
        Name of what is swept, for tables and figures.
    values
        The swept value of each point, kept in the result; default the changes.
    runs
        Runs per point.
    seed
        Seed of every point (common random numbers).
    workers, scheduler
        Where the runs go (:func:`executor_for`).
    progress
        True for a Rich bar on stderr, or a callback ``(done, total)``.

    Raises
    ------
    SimulationInputError, NetworkError, ClusterError
        Bad inputs at some point (checked before any run), or a bad cluster setting.
    ResourceLimitError
        A sweep beyond this machine's memory or time budget (:mod:`delayform.resources`).
    """
    runs, seed = mc._check_runs(runs, seed)
    labels = [str(i) for i in range(len(changes))] if labels is None else list(labels)
    if len(labels) != len(changes):
        raise SimulationInputError(f"{len(labels)} labels for {len(changes)} points")
    points = check_sweep(setup, changes, runs=runs, workers=workers)
    seeds = run_seeds(seed, runs)
    tasks = [(p, r, s) for p in points for r, s in enumerate(seeds)]
    with executor_for(workers=workers, scheduler=scheduler) as ex:
        if progress is True:
            with rich_progress(f"{parameter} sweep") as callback:
                outcomes = ex.map(simulate_run, tasks, callback)
        else:
            outcomes = ex.map(simulate_run, tasks, progress or None)
    results = tuple(collect(p, runs, seed, outcomes[i * runs : (i + 1) * runs]) for i, p in enumerate(points))
    return SweepResult(parameter=parameter, labels=tuple(labels),
                       values=tuple(changes if values is None else values), results=results)  # fmt: skip


def check_sweep(
    setup: Setup, changes: Sequence[Mapping[str, Any]], *, runs: int, workers: int | None = None,
    scheduler: str | None = None,
) -> list[Setup]:  # fmt: skip
    """The points of a sweep, every input checked and the budget guarded before any run starts.

    Parameters
    ----------
    setup
        The base point.
    changes
        One mapping of field -> value per point.
    runs
        Runs per point.
    workers
        Runs in parallel (memory for that many at once, time shared among them).
    scheduler
        Address of an existing Dask cluster, checked to be reachable; None: not used.

    Raises
    ------
    SimulationInputError, NetworkError, ClusterError, ResourceLimitError
        As :func:`sweep`.
    """
    if workers is not None and scheduler is not None:
        raise ClusterError("give either workers (a local cluster) or scheduler (an existing one), not both")
    if workers is not None:
        check_workers(workers)
    if scheduler is not None:
        parse_scheduler(scheduler)
    if not changes:
        raise SimulationInputError("a sweep needs at least one point")
    for change in changes:
        unknown = set(change) - set(Setup.__dataclass_fields__)
        if unknown:
            raise SimulationInputError(f"unknown sweep field(s) {', '.join(sorted(unknown))}")
    # the budget first: a huge grid is refused before its points are tried
    costs = [estimate_cost(setup.with_changes(**change), runs) for change in changes]
    _guard_total(max(c[0] for c in costs), sum(c[1] for c in costs), len(changes) * runs, 1 if workers is None else workers)
    points = [mc.checked(setup.with_changes(**change)) for change in changes]
    if scheduler is not None:
        check_scheduler(scheduler)
    return points


def _guard_total(nbytes: float, seconds: float, tasks: int, workers: int) -> None:
    require(what=f"a sweep of {tasks} runs", setting="the points, runs, duration or dt (or add workers)",
            nbytes=nbytes * max(1, min(workers, tasks)), seconds=seconds / max(workers, 1))  # fmt: skip


@validated()
def delay_sweep(
    setup: Setup, tau1_values: Sequence[float], tau2_values: Sequence[float], *, runs: int, seed: int = 0,
    workers: int | None = None, scheduler: str | None = None, progress: bool | Progress = False,
) -> SweepResult:  # fmt: skip
    """Monte Carlo on the grid ``tau1_values x tau2_values`` of nominal delays.

    Parameters
    ----------
    setup
        The base point.
    tau1_values, tau2_values
        Delays (s) to combine.
    runs, seed, workers, scheduler, progress
        As for :func:`sweep`.
    """
    return _grid(setup, ("tau1", "tau2"), tau1_values, tau2_values, "({:g}, {:g})", "delays",
                 runs=runs, seed=seed, workers=workers, scheduler=scheduler, progress=progress)  # fmt: skip


@validated()
def gain_sweep(
    setup: Setup, P_values: Sequence[float], D_values: Sequence[float], *, runs: int, seed: int = 0,
    workers: int | None = None, scheduler: str | None = None, progress: bool | Progress = False,
) -> SweepResult:  # fmt: skip
    """Monte Carlo on the grid ``P_values x D_values`` of gains (paper, eq. 1).

    Parameters
    ----------
    setup
        The base point.
    P_values, D_values
        Gains to combine.
    runs, seed, workers, scheduler, progress
        As for :func:`sweep`.
    """
    return _grid(setup, ("P", "D"), P_values, D_values, "P={:g}, D={:g}", "gains",
                 runs=runs, seed=seed, workers=workers, scheduler=scheduler, progress=progress)  # fmt: skip


#: bytes of one grid point while the points are listed (pair, change, label, setup)
_BYTES_PER_POINT = 2_000.0


def _guard_grid(setup: Setup, rows: int, cols: int, options: Mapping[str, Any]) -> None:
    """Refuse a grid beyond the budget before its points are listed (each base point's cost, times the count).

    :func:`check_sweep` estimates every point once they are listed; a 10^5 x 10^5
    grid would fill the memory listing them, so the base point stands for all first.
    """
    runs, workers = options.get("runs"), options.get("workers")
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        return  # check_sweep names the problem
    count = float(rows) * float(cols)
    nbytes, seconds = estimate_cost(setup, runs)
    w = 1 if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1 else workers
    require(what=f"a {rows:,} x {cols:,} grid of sweeps ({count * runs:.3g} runs)",
            setting="the points of the grid, runs, duration or dt (or add workers)",
            nbytes=_BYTES_PER_POINT * count + nbytes * min(w, count * runs), seconds=seconds * count / w)  # fmt: skip


def _grid(setup: Setup, fields: tuple[str, str], first: Sequence[float], second: Sequence[float],
          label: str, parameter: str, **options: Any) -> SweepResult:  # fmt: skip
    _guard_grid(setup, len(first), len(second), options)
    pairs = [(float(a), float(b)) for a, b in product(first, second)]
    changes = [dict(zip(fields, pair, strict=True)) for pair in pairs]
    return sweep(setup, changes, labels=[label.format(*p) for p in pairs], parameter=parameter, values=pairs, **options)


@validated()
def topology_sweep(
    setup: Setup, topologies: Sequence[Topology], *, shape: str, spacing: float = 1.0, runs: int, seed: int = 0,
    workers: int | None = None, scheduler: str | None = None, progress: bool | Progress = False,
) -> SweepResult:  # fmt: skip
    """Monte Carlo for each topology, in the named shape built for its size.

    Parameters
    ----------
    setup
        The base point; its initial state must be drawn per run (None), as sizes differ.
    topologies
        The teams.
    shape, spacing
        Named formation (:data:`delayform.formation.SHAPES`) and its spacing.
    runs, seed, workers, scheduler, progress
        As for :func:`sweep`.
    """
    if setup.initial_positions is not None or setup.initial_headings is not None:
        raise SimulationInputError("a topology sweep draws initial states per run: leave initial positions and headings unset")
    changes = [{"topology": t, "formation": named_formation(shape, t.n, spacing=spacing)} for t in topologies]
    labels = [f"{t.name} ({t.n} agents)" for t in topologies]
    return sweep(setup, changes, labels=labels, parameter="topology", values=labels, runs=runs, seed=seed,
                 workers=workers, scheduler=scheduler, progress=progress)  # fmt: skip


@validated()
def network_sweep(
    setup: Setup, networks: Sequence[Network | None], labels: Sequence[str], *, runs: int, seed: int = 0,
    workers: int | None = None, scheduler: str | None = None, progress: bool | Progress = False,
) -> SweepResult:  # fmt: skip
    """Monte Carlo for each network (e.g. growing jitter or loss).

    Parameters
    ----------
    setup
        The base point.
    networks
        The networks (None: ideal).
    labels
        One label per network.
    runs, seed, workers, scheduler, progress
        As for :func:`sweep`.
    """
    return sweep(setup, [{"network": net} for net in networks], labels=labels, parameter="network",
                 values=list(labels), runs=runs, seed=seed, workers=workers, scheduler=scheduler,
                 progress=progress)  # fmt: skip
