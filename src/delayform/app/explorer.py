"""The computations behind the explorer page, one scenario at a time, without any web code.

:class:`Explorer` answers the page's four questions with the library's own
functions, so the page and the library can never disagree:

* the chart: :func:`delayform.analysis.ctcr.stability_map.stability_map` (exact CTCR curves)
  and its ``unstable_count`` on a grid of cell centres for the shading;
* a clicked point: the number of unstable roots NU from the same exact map,
  :func:`delayform.analysis.roots.dominant.dominant_root`, and every root of every
  factor of the paper's eq. 3 in a rectangle around the imaginary axis
  (:func:`delayform.analysis.roots.team_roots.factor_roots_in`, all factors at once, each count
  certified by the argument principle);
* the robots: :func:`delayform.simulation.simulate` with the scenario's model,
  formation and initial state, thinned to animation frames;
* the eigenvalue plane of a clicked point: :func:`delayform.app.plane.region_report`
  (the boundary curve of :func:`delayform.analysis.plane.region.lambda_region`, NU(lam)
  and the team's eigenvalues);
* downloads: the scenario as TOML and the figures of :mod:`delayform.plots`,
  written into the explorer's output folder only.

"Stable" means what it means in the library: NU = 0, the centroid factor's
persistent root s = 0 (paper, eq. 4, Lemma 2) not counted.

Every method takes checked values (see :mod:`delayform.app.params`) and
refuses work beyond :class:`~delayform.app.params.ExplorerLimits` with an
:class:`~delayform.errors.InputError` naming the limit.
"""

from __future__ import annotations

import io
import json
import math
import re
import threading
import zipfile
from collections import OrderedDict
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._files import atomic_path
from delayform._validation import validated
from delayform.analysis.roots.actuated import actuated_roots_in
from delayform.analysis.ctcr.stability_map import StabilityMap, stability_map
from delayform.analysis.network import jitter_margin
from delayform.analysis.roots.team_roots import factor_roots_in
from delayform.analysis.roots.dominant import dominant_root, roots_in
from delayform.analysis.roots.single import delay_reach
from delayform.app.answers import (GUARANTEE_AGENTS, Animation, ChartData, GuaranteeReport, PointReport, RootsReport,
                                   _num, crossing_frequency_bound)  # fmt: skip
from delayform.app.params import ExplorerLimits, Param
from delayform.app.plane import RegionReport, region_report
from delayform.scenario.write import scenario_toml
from delayform.characteristic import factors
from delayform.errors import InputError, NotConvergedError
from delayform.scenario import Scenario
from delayform.simulation import IROBOT_CREATE, Robot, RobotLimits, Trajectory, simulate
from delayform.model.network import BernoulliLoss, Jitter, Network

# the answers live in delayform.app.answers; importable from here as before
__all__ = ["Explorer", "PointReport", "GuaranteeReport", "RootsReport", "ChartData", "Animation", "GUARANTEE_AGENTS",
           "crossing_frequency_bound"]

#: maps kept per explorer (each a few hundred kB): the chart's and the clicks' windows
_MAP_CACHE = 8
#: trajectories kept for the figures download
_TRAJECTORY_CACHE = 4
#: simulated seconds of the robots' default run (the paper's team settles in about 26 s at point a)
_DEFAULT_DURATION = 40.0
#: half-width of the default root window around the imaginary axis (1/s)
_ROOT_WINDOW_RE = 0.5
_ROOT_WINDOW_IM = 3.0
#: largest ``height x delay`` of the root window (rad): about six roots per chain
_ROOT_WINDOW_PHASE = 20.0
#: largest packet-loss probability of the network switch (beyond it the team hears almost nothing)
_MAX_LOSS = 0.95
#: largest jitter bound of the network switch (s); a delay minus its jitter must stay >= dt anyway
_MAX_JITTER = 5.0
#: the network switch's fields when the scenario has no ``[network]`` table
_DEFAULT_LOSS = 0.2
_DEFAULT_JITTER = 0.05
# ==================================================================== explorer
@validated()
class Explorer:
    """The explorer's computations for one scenario, with caches and work limits.

    Parameters
    ----------
    scenario
        The team, gains, delays and settings the page starts from.
    out_dir
        The only folder the explorer writes to (created when a download is asked for).
    limits
        The most work one request may cause.

    Raises
    ------
    InputError
        When the team is larger than ``limits.max_agents``.
    ScenarioError
        When the scenario's per-link ``[network]`` delays differ between links.
    """

    def __init__(self, scenario: Scenario, *, out_dir: str | Path, limits: ExplorerLimits | None = None) -> None:
        # the page is the plane of one delay pair on every link: a click runs the robots at that pair,
        # so per-link delays that differ are refused (a delay_spread follows the click)
        self.scenario = scenario.at_one_delay_pair(
            "the explorer (a click runs the robots there)",
            "delayform links / box, or simulate / montecarlo", spread=False)  # fmt: skip
        self.limits = limits or ExplorerLimits()
        self.out_dir = Path(out_dir).resolve()
        n = scenario.topology.n
        if n > self.limits.max_agents:
            raise InputError(
                f"the explorer opens teams of up to {self.limits.max_agents} agents "
                f"(explorer limit max_agents), this scenario has {n}"
            )
        self._lock = threading.Lock()
        self._maps: OrderedDict[tuple[float, ...], StabilityMap] = OrderedDict()
        self._runs: OrderedDict[tuple[float, ...], tuple[Trajectory, int]] = OrderedDict()

    # ------------------------------------------------------------ parameters
    @property
    def toggles(self) -> dict[str, bool]:
        """The switches of the robots' run this team offers, each with its default.

        ``limits``: actuator limits (the scenario's ``[robot]`` table, else
        :data:`~delayform.simulation.IROBOT_CREATE`), for unicycle teams; on by
        default when the scenario has the table.
        ``network``: an imperfect network (see :meth:`network`), for every team;
        on by default when the scenario has a ``[network]`` table and no ``[robot]`` table.
        Both on: robots with actuator limits over the imperfect network.
        """
        out: dict[str, bool] = {}
        if self.scenario.simulation.model == "unicycle":
            out["limits"] = self.scenario.robot is not None
        out["network"] = self.scenario.network is not None and not out.get("limits", False)
        return out

    def network(self, loss: float, jitter: float) -> Network:
        """The network of the network switch: the scenario's, with the page's loss and jitter.

        The scenario's other parts (per-link delays, variation, sampling, noise,
        seed) are kept; its loss becomes independent (Bernoulli) loss with
        probability ``loss`` (a bursty Gilbert-Elliott loss is replaced: the
        page sets one number) and its jitter ``+-jitter`` s on both streams.

        Parameters
        ----------
        loss
            Packet-loss probability in [0, 0.95].
        jitter
            Jitter bound (s), both streams.
        """
        base = self.scenario.network or Network(seed=self.scenario.initial.seed)
        return replace(base, loss=BernoulliLoss(loss) if loss > 0 else None,
                       jitter=Jitter(jitter, jitter) if jitter > 0 else None)  # fmt: skip

    def _network_defaults(self) -> tuple[float, float]:
        net = self.scenario.network
        if net is None:
            return _DEFAULT_LOSS, _DEFAULT_JITTER
        rate = 0.0 if net.loss is None else net.loss.loss_rate
        if isinstance(net.loss, BernoulliLoss):  # a matrix: its mean over the team's links only
            rate = net.loss.link_loss_rate(self.scenario.topology.adjacency)
        loss = min(rate, _MAX_LOSS)
        jitter = 0.0 if net.jitter is None else min(max(net.jitter.bound1, net.jitter.bound2), _MAX_JITTER)
        return loss, jitter

    def _switches(self, limits: bool, network: bool, loss: float, jitter: float) -> tuple[RobotLimits | None, Network | None]:
        """The run's actuator limits and network (both at once: robots with limits over the network).

        With the network off, a loss or jitter other than 0 or the defaults is
        refused rather than ignored (simulation, scenario and figure downloads alike).
        """
        if not network and (loss, jitter) not in ((0.0, 0.0), self._network_defaults()):
            raise InputError(f"loss, jitter: they set the network imperfections, which are off (network=0); "
                             f"add network=1 to run over a network with loss {loss:g} and jitter {jitter:g} s")  # fmt: skip
        return self._limits(limits), (self.network(loss, jitter) if network else None)

    def _limits(self, limits: bool) -> RobotLimits | None:
        if not limits:
            return None
        if "limits" not in self.toggles:
            raise InputError("limits: actuator limits apply to unicycle robots, not to double integrators")
        return self.scenario.robot or IROBOT_CREATE

    def _gain(self, name: str, default: float) -> Param:
        return Param(name, "float", 0.0, self.limits.max_gain, default=default, open_low=True, limit="max_gain")

    def _delay(self, name: str, default: float | None = None) -> Param:
        return Param(name, "float", 0.0, self.limits.max_delay, default=default, limit="max_delay")

    def _window(self, name: str, default: float) -> Param:
        return Param(name, "float", 0.0, self.limits.max_delay, default=default, open_low=True, limit="max_delay")

    def point_params(self) -> tuple[Param, ...]:
        """Parameters of :meth:`point`: tau1 and tau2 required, P and D default to the scenario's."""
        s = self.scenario
        return (self._delay("tau1"), self._delay("tau2"), self._gain("P", s.P), self._gain("D", s.D))

    def chart_params(self) -> tuple[Param, ...]:
        """Parameters of :meth:`chart`: P, D, the window (the scenario's, within the limits) and the grid."""
        s = self.scenario
        side = self.limits.max_delay_bandwidth / crossing_frequency_bound(s.P, s.D)
        w1, w2 = min(s.chart.tau1_max, side, self.limits.max_delay), min(s.chart.tau2_max, side, self.limits.max_delay)
        return (
            self._gain("P", s.P), self._gain("D", s.D),
            self._window("tau1_max", w1), self._window("tau2_max", w2),
            Param("grid", "int", 10, self.limits.max_grid, default=min(160, self.limits.max_grid), limit="max_grid"),
        )  # fmt: skip

    def animation_params(self) -> tuple[Param, ...]:
        """Parameters of :meth:`animation`: the point, gains, duration and frame count."""
        s = self.scenario
        duration = min(s.simulation.duration, _DEFAULT_DURATION, self.limits.max_steps * s.simulation.dt)
        return self.point_params() + (
            Param("duration", "float", 0.0, math.inf, default=duration, open_low=True),
            Param("frames", "int", 2, self.limits.max_frames, default=min(300, self.limits.max_frames),
                  limit="max_frames"),
        ) + self._toggle_params()  # fmt: skip

    def _toggle_params(self) -> tuple[Param, ...]:
        loss, jitter = self._network_defaults()
        return tuple(Param(name, "bool", default=on) for name, on in self.toggles.items()) + (
            Param("loss", "float", 0.0, _MAX_LOSS, default=loss),
            Param("jitter", "float", 0.0, _MAX_JITTER, default=jitter),
        )

    def download_params(self) -> tuple[Param, ...]:
        """Parameters of the downloads: the point, gains, duration, chart window and switches."""
        chart = self.chart_params()
        return self.animation_params()[:5] + chart[2:4] + self._toggle_params()

    # ------------------------------------------------------------ caches
    def _cached(self, cache: OrderedDict[Any, Any], key: Any, size: int, make: Any) -> Any:
        with self._lock:
            if key in cache:
                cache.move_to_end(key)
                return cache[key]
        value = make()  # outside the lock: two different requests may compute at once
        with self._lock:
            cache[key] = value
            while len(cache) > size:
                cache.popitem(last=False)
        return value

    def stability_map(self, P: float, D: float, tau1_max: float, tau2_max: float) -> StabilityMap:
        """The exact CTCR map of the scenario's team (cached).

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1_max, tau2_max
            The window.
        """
        key = (P, D, tau1_max, tau2_max)
        topology = self.scenario.topology
        ta = self.scenario.actuation_delay  # [robot] actuation_delay: the exact map at that tau_a
        return self._cached(self._maps, key, _MAP_CACHE,
                            lambda: stability_map(topology, P, D, tau1_max, tau2_max, actuation_delay=ta))  # fmt: skip

    def _map_covering(self, P: float, D: float, tau1: float, tau2: float) -> StabilityMap:
        with self._lock:
            for (p, d, w1, w2), smap in reversed(self._maps.items()):
                if p == P and d == D and tau1 <= w1 and tau2 <= w2:
                    return smap
        chart = self.scenario.chart
        return self.stability_map(P, D, max(chart.tau1_max, math.ceil(tau1)), max(chart.tau2_max, math.ceil(tau2)))

    # ------------------------------------------------------------ answers
    def chart(self, P: float, D: float, tau1_max: float, tau2_max: float, grid: int) -> ChartData:
        """The stability chart: exact curves and NU on a ``grid x grid`` shading.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1_max, tau2_max
            The window.
        grid
            Cells per axis of the shading (<= ``limits.max_grid``).
        """
        self._check_bandwidth(P, D, max(tau1_max, tau2_max), "tau1_max, tau2_max")
        smap = self.stability_map(P, D, tau1_max, tau2_max)
        t1 = (np.arange(grid) + 0.5) * tau1_max / grid
        t2 = (np.arange(grid) + 0.5) * tau2_max / grid
        counts = smap.unstable_count(t1[None, :], t2[:, None])
        points = tuple((k, a, b) for k, a, b in self.scenario.chart.points if a <= tau1_max and b <= tau2_max)
        return ChartData(smap, t1, t2, counts, points)

    def point(self, P: float, D: float, tau1: float, tau2: float) -> PointReport:
        """Stability, NU and the dominant root at one delay pair.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The delays.
        """
        self._check_bandwidth(P, D, max(tau1, tau2), "tau1, tau2", roots=True)
        count = int(self._map_covering(P, D, tau1, tau2).unstable_count(tau1, tau2))
        dom = dominant_root(self.scenario.topology, P, D, tau1, tau2, actuation_delay=self.scenario.actuation_delay)
        return PointReport(P, D, tau1, tau2, count, dom)

    def guarantee(self, P: float, D: float, tau1: float, tau2: float) -> GuaranteeReport:
        """The certified jitter margin at one delay pair, for teams up to :data:`GUARANTEE_AGENTS`.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The nominal delays.
        """
        self._check_bandwidth(P, D, max(tau1, tau2), "tau1, tau2")
        team = self.scenario.topology
        margin = jitter_margin(team, P, D, tau1, tau2) if team.n <= GUARANTEE_AGENTS else None
        return GuaranteeReport(P, D, tau1, tau2, margin)

    def roots(self, P: float, D: float, tau1: float, tau2: float) -> RootsReport:
        """The roots of every factor in a window around the imaginary axis and the dominant root.

        The window reaches :data:`_ROOT_WINDOW_RE` left and right of the axis and
        of the dominant root s*, and ``|Im s| < max(min(3, 20 / max(tau1, tau2)), |Im s*| + 0.5)``:
        a chain of roots of a quasi-polynomial with delay h has about one root per
        ``2 pi / h`` of height, so the window holds about six roots per chain
        however long the delays (the certified count's cost grows with the roots in it).

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The delays.
        """
        self._check_bandwidth(P, D, max(tau1, tau2), "tau1, tau2", roots=True)
        topology = self.scenario.topology
        ta = self.scenario.actuation_delay
        dom = dominant_root(topology, P, D, tau1, tau2, actuation_delay=ta).root
        height = max(min(_ROOT_WINDOW_IM, _ROOT_WINDOW_PHASE / max(tau1, tau2, 1e-12)), abs(dom.imag) + 0.5)
        # irrational nudges keep the edges off roots exactly on the real axis or at s = 0
        region = (
            min(-_ROOT_WINDOW_RE, dom.real - _ROOT_WINDOW_RE) - 1.37e-3,
            max(_ROOT_WINDOW_RE, dom.real + _ROOT_WINDOW_RE) + 1.13e-3,
            -(height + 1.21e-3),
            height + 1.21e-3,
        )
        found: list[NDArray[np.complex128]] = []
        owners: list[int] = []
        certified = True
        fs = factors(topology, P, D)
        try:  # all factors as one family; factor by factor only to keep what a failing one found
            per_factor = [roots for _, roots in factor_roots_in(topology, P, D, tau1, tau2, region,
                                                                actuation_delay=ta)]  # fmt: skip
        except NotConvergedError:
            per_factor = []
            for f in fs:
                try:
                    per_factor.append(actuated_roots_in(f, tau1, tau2, ta, region) if ta > 0.0
                                      else roots_in(f, tau1, tau2, region))  # fmt: skip
                except NotConvergedError as exc:
                    certified = False
                    per_factor.append(np.asarray(exc.partial if exc.partial is not None else [], dtype=np.complex128))
        for idx, (f, roots) in enumerate(zip(fs, per_factor, strict=True)):
            if f.is_centroid and roots.size:
                # Lemma 2: the persistent root s = 0 is the centroid's motion, not a mode
                roots = np.delete(roots, np.argmin(np.abs(roots)))
            found.append(roots)
            owners += [idx] * roots.size
        allroots = np.concatenate(found) if found else np.zeros(0, dtype=np.complex128)
        names = tuple(f.describe() for f in fs)
        return RootsReport(P, D, tau1, tau2, dom, allroots, tuple(owners), names, region, certified)

    def region(self, P: float, D: float, tau1: float, tau2: float) -> RegionReport:
        """The eigenvalue plane at one point: boundary curve, NU(lam) and the team's eigenvalues.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The delays (bounded like :meth:`point`: the boundary curve's samples
            grow with delay x crossing frequency).
        """
        self._check_bandwidth(P, D, max(tau1, tau2), "tau1, tau2")
        return region_report(self.scenario.topology, P, D, tau1, tau2)

    def delay_limits(self, P: float, D: float) -> dict[str, float]:
        """The longest delays the explorer takes at gains (P, D), per kind of request.

        ``"chart"`` and ``"region"``: ``max_delay_bandwidth`` over the
        crossing-frequency bound; ``"roots"`` (point, roots: the dominant-root
        finder) also the finder's own reach,
        :func:`~delayform.analysis.roots.single.delay_reach`, the rule the
        finder refuses by, so this table never allows a delay the finder then
        refuses, and follows the finder when its reach changes.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        """
        bandwidth = self.limits.max_delay_bandwidth / crossing_frequency_bound(P, D)
        work = min(self.limits.max_delay, bandwidth)
        return {"chart": work, "region": work,
                "roots": min(work, delay_reach(tuple(factors(self.scenario.topology, P, D))))}  # fmt: skip

    def _check_bandwidth(self, P: float, D: float, delay: float, what: str, *, roots: bool = False) -> None:
        """Refuse delays beyond :meth:`delay_limits` (the root finder's reach too with ``roots``)."""
        omega = crossing_frequency_bound(P, D)
        if delay * omega > self.limits.max_delay_bandwidth:
            raise InputError(
                f"{what}: {delay:g} s x crossing-frequency bound {omega:.3g} rad/s exceeds the explorer "
                f"limit max_delay_bandwidth = {self.limits.max_delay_bandwidth:g} "
                f"(at P = {P:g}, D = {D:g}: delays up to {self.limits.max_delay_bandwidth / omega:.3g} s)"
            )
        reach = self.delay_limits(P, D)["roots"] if roots else math.inf
        if delay > reach:
            raise InputError(
                f"{what}: {delay:g} s is beyond the dominant-root finder's reach at P = {P:g}, D = {D:g} "
                f"(delays up to {reach:.3g} s); the chart has no such limit"
            )

    def _step(self, tau1: float, tau2: float) -> float:
        """The scenario's step, shortened when a non-zero delay is smaller (simulate needs tau >= dt)."""
        dt = self.scenario.simulation.dt
        for tau in (tau1, tau2, self.scenario.actuation_delay):
            if 0.0 < tau < dt:
                dt = tau
        return dt

    def _run_step(self, tau1: float, tau2: float, duration: float) -> float:
        """The step of a run, after checking the run against the work limits."""
        dt = self._step(tau1, tau2)
        steps = math.ceil(duration / dt - 1e-9)
        n = self.scenario.topology.n
        if steps > self.limits.max_steps:
            raise InputError(
                f"duration: {duration:g} s at dt = {dt:g} s is {steps} steps; "
                f"explorer limit max_steps = {self.limits.max_steps}"
            )
        if steps * n > self.limits.max_agent_steps:
            raise InputError(
                f"duration: {steps} steps x {n} agents exceeds the explorer limit "
                f"max_agent_steps = {self.limits.max_agent_steps}"
            )
        return dt

    def animation(self, P: float, D: float, tau1: float, tau2: float, duration: float, frames: int,
                  limits: bool = False, network: bool = False, loss: float = 0.0, jitter: float = 0.0,
                  ) -> Animation:  # fmt: skip
        """Simulate the team at one point and thin the run to ``frames`` animation frames.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The delays.
        duration
            Simulated time (s); ``duration / dt`` steps must stay within the explorer's limits.
        frames
            Number of frames to send.
        limits
            Integrate the robots with actuator limits (see :attr:`toggles`).
        network
            Send positions and velocities over :meth:`network` (not with ``limits``).
        loss, jitter
            The network's packet-loss probability and jitter bound (s).

        Raises
        ------
        InputError
            When the run would exceed ``limits.max_steps`` or ``limits.max_agent_steps``,
            when both switches are on, or when the network does not fit the delays
            (:class:`~delayform.errors.NetworkError`: a delay minus its jitter must stay >= dt).
        """
        s = self.scenario
        dt = self._run_step(tau1, tau2, duration)
        robot, net = self._switches(limits, network, loss, jitter)
        spec = s.robot_spec
        if s.simulation.model == "physics":  # robots with mass: always the profile's limits and chassis
            robot = spec.limits

        def run() -> tuple[Trajectory, int]:
            with np.errstate(over="ignore", invalid="ignore"):  # an unstable run may overflow; cut below
                tr = simulate(
                    s.topology, P, D, tau1, tau2, s.desired_positions(),
                    robot=Robot(model=s.simulation.model, limits=robot, radius=s.radius, safety=s.safety,
                                actuation_delay=s.actuation_delay, chassis=spec.chassis),
                    assignment=s.simulation.assignment,
                    network=net,
                    initial_positions=s.initial_positions(), initial_headings=s.initial_headings(),
                    initial_speed=s.initial.speed, seed=s.initial.seed, duration=duration, dt=dt,
                )  # fmt: skip
            finite = np.all(np.isfinite(tr.positions), axis=(1, 2)) & np.isfinite(tr.formation_error)
            return tr, (tr.times.size if finite.all() else int(np.argmin(finite)))

        # the page's run and the figures download share one simulation
        key = (P, D, tau1, tau2, duration, limits, network, loss if network else 0.0, jitter if network else 0.0)
        tr, last = self._cached(self._runs, key, _TRAJECTORY_CACHE, run)
        # the first non-finite sample, else where integration stopped on overflow (the warnings' time)
        diverged = float(tr.times[last]) if last < tr.times.size else tr.stopped_at
        idx = np.unique(np.linspace(0, max(last - 1, 0), frames).round().astype(np.int64))
        return Animation(tr, idx, diverged, net if net is None or not net.is_ideal else None)

    # ------------------------------------------------------------ downloads
    def _scenario_at(self, P: float, D: float, tau1: float, tau2: float, duration: float,
                     tau1_max: float, tau2_max: float, limits: bool, network: bool, loss: float,
                     jitter: float) -> Scenario:  # fmt: skip
        s = self.scenario.with_changes(P=P, D=D, tau1=tau1, tau2=tau2)
        robot, net = self._switches(limits, network, loss, jitter)
        return replace(
            s,
            robot=robot,
            network=net,
            chart=replace(s.chart, tau1_max=tau1_max, tau2_max=tau2_max),
            simulation=replace(s.simulation, duration=duration, dt=self._step(tau1, tau2)),
            source="<explorer>",
        )

    def _write(self, name: str, data: bytes) -> Path:
        """Write one file into the output folder, and nowhere else."""
        path = (self.out_dir / name).resolve()
        if path.parent != self.out_dir:
            raise InputError(f"refusing to write {name!r} outside {self.out_dir}")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
        return path

    def _stem(self, P: float, D: float, tau1: float, tau2: float, duration: float, tau1_max: float,
              tau2_max: float, limits: bool, network: bool, loss: float, jitter: float) -> str:  # fmt: skip
        """A file name carrying every setting that changes a download, letters, digits and ``._-`` only.

        ``<scenario name>_P.._D.._tau<tau1>_<tau2>_T<duration>_win<tau1_max>x<tau2_max>``, then
        ``_limits`` with actuator limits and ``_net-loss<p>-jitter<s>`` over the network (loss
        and jitter only there: without the network they change nothing). Numbers in their
        shortest exact form, so two settings never share a name (and a second download with
        other switches never overwrites the first).
        """
        name = re.sub(r"[^A-Za-z0-9_.-]", "_", self.scenario.name)[:40].strip(".") or "scenario"
        stem = (f"{name}_P{_num(P)}_D{_num(D)}_tau{_num(tau1)}_{_num(tau2)}_T{_num(duration)}"
                f"_win{_num(tau1_max)}x{_num(tau2_max)}")  # fmt: skip
        if limits:
            stem += "_limits"
        if network:
            stem += f"_net-loss{_num(loss)}-jitter{_num(jitter)}"
        return stem

    def scenario_file(self, P: float, D: float, tau1: float, tau2: float, duration: float,
                      tau1_max: float, tau2_max: float, limits: bool = False, network: bool = False,
                      loss: float = 0.0, jitter: float = 0.0) -> Path:  # fmt: skip
        """Write the scenario at the current settings as TOML into the output folder.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The operating delays (the clicked point).
        duration
            Simulated time of the file's ``[simulation]`` table.
        tau1_max, tau2_max
            The chart window of the file's ``[chart]`` table.
        limits
            Write the actuator limits as the ``[robot]`` table (see :attr:`toggles`).
        network
            Write :meth:`network` as the ``[network]`` table (not with ``limits``).
        loss, jitter
            The network's packet-loss probability and jitter bound (s).

        Returns
        -------
        Path
            ``<out>/<stem>.toml``, the stem naming every setting (:meth:`_stem`).
        """
        s = self._scenario_at(P, D, tau1, tau2, duration, tau1_max, tau2_max, limits, network, loss, jitter)
        stem = self._stem(P, D, tau1, tau2, duration, tau1_max, tau2_max, limits, network, loss, jitter)
        return self._write(f"{stem}.toml", scenario_toml(s).encode("utf-8"))

    def figures_file(self, P: float, D: float, tau1: float, tau2: float, duration: float,
                     tau1_max: float, tau2_max: float, limits: bool = False, network: bool = False,
                     loss: float = 0.0, jitter: float = 0.0) -> Path:  # fmt: skip
        """Write a ZIP with the chart, the robots' figures, the point's numbers and the scenario.

        Parameters
        ----------
        P, D
            Gains of the paper's eq. 1.
        tau1, tau2
            The clicked point.
        duration
            Simulated time of the robots' run.
        tau1_max, tau2_max
            The chart window.
        limits
            Run the robots with actuator limits (see :attr:`toggles`).
        network
            Run them over :meth:`network` instead (not with ``limits``).
        loss, jitter
            The network's packet-loss probability and jitter bound (s).

        Returns
        -------
        Path
            ``<out>/<stem>_figures.zip`` (the stem of :meth:`scenario_file`) holding ``stability_chart``,
            ``traces`` and ``xy`` as PNG and SVG, ``point.json`` and ``scenario.toml``.
        """
        self._run_step(tau1, tau2, duration)  # refuse an oversized run before any drawing
        from matplotlib.figure import Figure  # only downloads draw with matplotlib

        from delayform.plots import plot_trajectory_traces, plot_trajectory_xy, savefig_noting_glyphs, stability_chart

        chart = self.chart(P, D, tau1_max, tau2_max, 10)
        run = self.animation(P, D, tau1, tau2, duration, 2, limits, network, loss, jitter)
        point = self.point(P, D, tau1, tau2)
        roots = self.roots(P, D, tau1, tau2)
        s = self._scenario_at(P, D, tau1, tau2, duration, tau1_max, tau2_max, limits, network, loss, jitter)
        tr = run.trajectory
        if run.diverged_at is not None:  # draw the finite part of an overflowing run
            keep = int(np.searchsorted(tr.times, run.diverged_at))
            tr = replace(tr, times=tr.times[:keep], positions=tr.positions[:keep], headings=tr.headings[:keep])
        marks = {k: (a, b) for k, a, b in chart.points} | {"here": (tau1, tau2)}
        figures: dict[str, Figure] = {}
        fig = Figure(figsize=(6, 5))
        stability_chart(chart.smap, ax=fig.add_subplot(), points=marks)
        figures["stability_chart"] = fig
        fig = Figure(figsize=(6, 5))
        plot_trajectory_traces(tr, ax=fig.add_subplot())
        figures["traces"] = fig
        fig = Figure(figsize=(7, 5))
        axes = fig.subplots(2, 1, sharex=True)
        plot_trajectory_xy(tr, ax=(axes[0], axes[1]))
        figures["xy"] = fig
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for name, fig in figures.items():
                for fmt in ("png", "svg"):
                    data = io.BytesIO()
                    savefig_noting_glyphs(fig, data, where=f"{name}.{fmt}", format=fmt, dpi=150, bbox_inches="tight")
                    zf.writestr(f"{name}.{fmt}", data.getvalue())
            zf.writestr("point.json", json.dumps(point.as_json() | roots.as_json(), indent=2))
            zf.writestr("scenario.toml", scenario_toml(s))
        stem = self._stem(P, D, tau1, tau2, duration, tau1_max, tau2_max, limits, network, loss, jitter)
        return self._write(f"{stem}_figures.zip", buffer.getvalue())
