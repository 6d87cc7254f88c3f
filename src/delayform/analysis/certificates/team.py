"""A certified margin for the team's delays varying together: one Lyapunov-Krasovskii certificate per mode.

When every link has the same delays h1(t), h2(t), varying in time, the team
still factorizes (paper, eq. 3): with C = U T U^H (Schur, U unitary, T upper
triangular, its diagonal the eigenvalues lam of C) the coordinates y = U^H x
obey, mode by mode,

    y_j'' = -P y_j - D y_j' + lam_j (P y_j(t - h1(t)) + D y_j'(t - h2(t))) + (terms in y_k, k > j),

the paper's eq. 8 with time-varying delays (a real 4-state system for a
conjugate pair). The last mode is autonomous and each one above it is driven
by the modes below it, so if every mode's own dynamics is uniformly
exponentially stable the whole cascade is: the team margin is the smallest
mode margin. A repeated eigenvalue gives the same mode again (the same
certificate).

The centroid mode (lam = 1) has a solution y = constant for any delays (the
team may sit anywhere: q1(0) = 0 at every delay). Its certificate projects
that direction out (``invariant=(1, 0)``,
:mod:`~delayform.analysis.certificates.intervals`): it proves that the
centroid's velocity dies out and its position converges, for any variation
of the delays in the intervals.

Coverage: *the same* h1(t) and h2(t) on every link. Independent per-link
variations do not factorize; :func:`~delayform.analysis.network.jitter.jitter_margin`'s
small-gain margin covers those.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.certificates.intervals import IntervalDelays
from delayform.analysis.certificates.lmi import margin_slope
from delayform.analysis.certificates.margin import DelayCertificate, _Attempt
from delayform.analysis.certificates.several import Functional, attempt
from delayform._validation import check_delay, validated
from delayform.characteristic import CharacteristicFactor, factors
from delayform.errors import InputError
from delayform.topology import Topology

__all__ = ["COVERS", "LEVELS", "ModeMargin", "TeamDelayMargin", "team_delay_margin", "certify_team_delays"]

#: What the per-mode margin covers, in words.
COVERS = "the same time-varying delays h1(t), h2(t) on every link (all links varying together), arbitrarily fast"
#: The functionals tried per mode and deviation, cheapest first (the first that holds is kept).
LEVELS = (Functional(1, 1, False), Functional(2, 1, False), Functional(2, 1, True), Functional(3, 1, True))


@dataclass(frozen=True)
class ModeMargin:
    """One mode's certificate at the team's margin.

    Attributes
    ----------
    lam
        The eigenvalue of C (of a pair, the member with Im > 0).
    centroid
        True for lam = 1 (certified with its constant solutions projected out).
    functional
        The functional whose certificate holds: for the mode that limits the search the richest one
        tried, for the others the cheapest of :data:`LEVELS` that does.
    certificate
        Its certificate (re-checked exactly), on intervals at least as wide as the team's
        delta (a certificate for wider intervals covers the narrower ones); None when delta is 0.
    options
        The functional's options, to rebuild its LMIs from ``certificate`` (an independent re-check).
    solved_at
        The deviation delta its certificate was solved at (at least the team's).
    """

    lam: complex
    centroid: bool
    functional: str
    certificate: DelayCertificate | None = field(repr=False)
    options: Functional | None = field(default=None, repr=False)
    solved_at: float = 0.0


@dataclass(frozen=True)
class TeamDelayMargin:
    """The certified margin for delays varying together on every link, and the proof per mode.

    Attributes
    ----------
    delta
        Every h1(t) in [tau1 - delta, tau1 + delta] and h2(t) in [tau2 - delta, tau2 + delta]
        (clipped at 0), the same on every link and varying arbitrarily fast, keeps the team
        stable; 0 where nothing is certified (``reason``).
    limiting
        The eigenvalue of the mode that stopped the search (None when delta is 0 by ``reason``).
    modes
        Each mode's certificate at ``delta``.
    covers
        :data:`COVERS`: which variations the margin is about.
    method
        The certificate, in words.
    tried
        Every (delta, verdict) of the search.
    tolerance
        The search's resolution, rtol times delta: within it above delta lies a failure of the
        richest functional, or the zero of its optimum margin predicted from its slope (a guess,
        not a bound).
    reason
        Why delta is 0 without a search (unstable nominal delays, tau1 = 0); empty otherwise.
    """

    delta: float
    limiting: complex | None
    modes: tuple[ModeMargin, ...] = field(repr=False)
    covers: str = COVERS
    method: str = "Lyapunov-Krasovskii per mode (Bessel-Legendre, reciprocal convexity), re-checked exactly"
    tried: tuple[tuple[float, str], ...] = field(default=(), repr=False)
    tolerance: float = 0.0
    reason: str = ""


Mode = tuple[NDArray[np.float64], tuple[NDArray[np.float64], ...], NDArray[np.float64] | None]


def mode_system(f: CharacteristicFactor) -> Mode:
    """(A0, (A1, A2), invariant) of a factor's subsystem; lam = 1 exactly for the centroid (its zero is exact)."""
    if f.is_centroid:
        P, D = f.P, f.D
        A0 = np.array([[0.0, 1.0], [-P, -D]])
        return A0, (np.array([[0.0, 0.0], [P, 0.0]]), np.array([[0.0, 0.0], [0.0, D]])), np.array([1.0, 0.0])
    A0, B1, B2 = f.state_matrices()
    return A0, (B1, B2), None


#: Clarabel's tolerances in the search (its defaults are 1e-8): a quarter fewer iterations, and
#: every certificate is re-checked the same way (lmi.recheck), so only t near the boundary suffers.
SEARCH_TOLERANCE = 1e-6
#: The first solve of every step is ``quick`` (lmi.solve: no iterative refinement or equilibration)
#: at this looser tolerance, about half the CPU; an answer with t > 0 that fails the re-check, or a
#: solver that stalled, is solved again the careful way at SEARCH_TOLERANCE (the margin does not suffer).
QUICK_TOLERANCE = 1e-5
#: The tolerance of a balanced quick solve (lmi.solve's ``balance``: its margin t is about 300 times
#: smaller on the order-3 LMIs, so the same relative accuracy needs a tighter one).
BALANCED_TOLERANCE = 1e-7


class _Modes:
    """The team's distinct modes, hardest first, searched one at a time below the smallest margin so far.

    The team margin is the smallest mode margin, so a mode only needs a search when it fails at
    the current smallest margin U: the hardest mode (rightmost root nearest the axis) is searched
    first, every other one is then usually a single cheap solve at U (its functionals cheapest
    first). A mode that needs a search gets it in two phases (:meth:`margin`): the cheapest
    functional alone brackets the margin from below for a few hundredths of a second per solve,
    then only the richest one moves up from there. Each of its certified points gives the optimum
    margin t(delta) and its slope (from the solver's dual matrices); near the boundary t behaves
    like c (delta* - delta)^p, so two points predict delta* (:meth:`_zero`) and the next delta is
    a little below it (:meth:`_next`), which usually holds and ends the search. A functional that
    failed at some delta is not tried again at a larger one (there it would fail too: it is a
    heuristic that costs only solves).
    """

    def __init__(self, fs: tuple[CharacteristicFactor, ...], t1: float, t2: float, right: list[complex],
                 levels: tuple[Functional, ...], rtol: float, start: float) -> None:  # fmt: skip
        self.levels = levels
        order = sorted(range(len(fs)), key=lambda i: -right[i].real)
        self.fs = [fs[i] for i in order]
        self.systems = [mode_system(f) for f in self.fs]
        # per mode: a conjugate pair (4 states) never gets the windows over the intervals, whose
        # order-3 LMIs for it take minutes and gigabytes per SDP (the cut windows instead)
        self.mode_levels = [tuple(replace(f, cover=False) if A0.shape[0] > 2 else f for f in levels)
                            for A0, _, _ in self.systems]  # fmt: skip
        self.t = (t1, t2)
        self.rtol, self.start, self.floor = rtol, start, 1e-3 * start
        # per mode and functional: the smallest delta at which it failed
        self.failed = [[math.inf for _ in levels] for _ in self.fs]
        self.tried: list[tuple[float, str]] = []
        # per mode: every (delta, attempt) that held, for a step back when an answer fails the exact re-check
        self.history: list[list[tuple[float, _Attempt]]] = [[] for _ in self.fs]
        # (mode, functional) whose balanced solve needed the plain one after it: not balanced again
        self.unbalanced: set[tuple[int, int]] = set()

    def solve(self, i: int, delta: float, level: int, slope: bool = False,
              balance: bool = False) -> tuple[_Attempt | None, float, float]:  # fmt: skip
        """(the attempt if it holds, else None; the solver's optimum margin t; dt/d delta or nan) of one functional.

        ``slope``: when it holds, also the derivative of the optimum t in delta from the solver's dual
        matrices (:func:`~delayform.analysis.certificates.lmi.margin_slope`): a guess for the search.
        ``balance``: first a quick solve of the LMIs balanced (``lmi.solve``), at :data:`BALANCED_TOLERANCE`;
        when its answer holds, t and its slope are those of the balanced LMIs. When it fails the re-check
        (its LMIs' smallest eigenvalues need not be balanced relative to their norms), stalls or finds t
        within the tolerance of 0, the plain quick solve follows (and the careful one if needed), as without,
        and that mode's functional is not balanced again (measured: with the windows cut at the upper
        ends the balanced answers miss by -4e-11 relative, where the plain ones hold).
        """
        if delta >= self.failed[i][level]:  # failed at a smaller delta already: not solved again
            return None, -math.inf, math.nan
        fun = self.mode_levels[i][level]
        data = self._data(i, delta)
        att = None
        if balance and (i, level) not in self.unbalanced:  # a shortcut to a certificate only
            att = attempt(data, fun, exact=False, tolerance=BALANCED_TOLERANCE, quick=True, balance=True)
            solved = att.cert.solver_status in ("Solved", "AlmostSolved")
            if not att.cert.holds and (att.cert.solver_margin > -BALANCED_TOLERANCE or not solved):
                att = None  # whatever else it answers, the plain solves follow; and this mode's
                self.unbalanced.add((i, level))  # functional is not balanced again (it did not pay)
        if att is None:
            att = attempt(data, fun, exact=False, tolerance=QUICK_TOLERANCE, quick=True)
            rough = att.cert.solver_margin > 0.0 or att.cert.solver_status not in ("Solved", "AlmostSolved")
            if not att.cert.holds and rough:  # failed the re-check, or the solver stalled: the careful solve
                att = attempt(data, fun, exact=False, tolerance=SEARCH_TOLERANCE)
        t = att.cert.solver_margin if math.isfinite(att.cert.solver_margin) else -math.inf
        if att.cert.holds:
            self.tried.append((delta, f"mode {i}, {fun.describe()}: holds"))
            self.history[i].append((delta, att))
            ds = math.nan
            if slope and att.solution is not None:
                step = 1e-4 * delta
                ds = margin_slope(att.solution, fun.problem(self._data(i, delta - step)),
                                  fun.problem(self._data(i, delta + step)), step)  # fmt: skip
            return att, t, ds
        self.failed[i][level] = min(self.failed[i][level], delta)
        self.tried.append((delta, f"mode {i}, {fun.describe()}: not certified"))
        return None, t, math.nan

    def _data(self, i: int, delta: float) -> IntervalDelays:
        A0, ak, e = self.systems[i]
        lo, hi = tuple(max(t - delta, 0.0) for t in self.t), tuple(t + delta for t in self.t)
        return IntervalDelays(A0, ak, lo, hi, None, e)

    def check(self, i: int, delta: float) -> _Attempt | None:
        """The first functional, cheapest first, that holds for mode i at delta (None: none does)."""
        for level in range(len(self.levels)):
            if delta < self.failed[i][level]:
                att, _, _ = self.solve(i, delta, level)
                if att is not None:
                    return att
        return None

    def done(self, lo: float, hi: float, rtol: float | None = None) -> bool:
        return hi - lo <= (self.rtol if rtol is None else rtol) * max(lo, self.floor) * (1.0 + 1e-9)

    def margin(self, i: int, hi: float, capped: bool) -> tuple[float, _Attempt | None]:
        """Largest certified delta of mode i below ``hi``.

        Every functional failed at ``hi``, or (``capped``) ``hi`` is the search's cap.
        """
        # phase 1: the cheapest functional, doubling from the start then halving, to the resolution
        # (to 5 % when a richer one follows: phase 2 starts from its bracket, a finer one gains nothing)
        lo, best, d, top = 0.0, None, min(self.start, hi), len(self.levels) - 1
        fail, res = hi, self.rtol if top == 0 else max(self.rtol, 0.05)
        while not self.done(lo, fail, res) and d > self.floor:
            att, _, _ = self.solve(i, d, 0)
            if att is not None:
                lo, best = d, att
                d = min(2.0 * d, fail) if fail == hi and d < hi else 0.5 * (lo + fail)
                if d == lo:
                    break
            else:
                fail = d
                d = 0.5 * (lo + fail)
        if top == 0 or lo >= hi:
            return lo, best
        # phase 2: the richest functional only, from the cheap bracket up
        held: list[tuple[float, float, float]] = []  # (delta, t, dt/d delta) where it holds
        d = fail if fail < hi else min(2.0 * max(lo, self.floor), hi)
        misses = 0  # failures in a row
        zeros: list[float] = []  # the predicted zeros of t, one per certified point
        while True:
            # balanced after the first: fewer iterations next to the boundary; the first stays plain, its
            # Newton step sets where the search lands (the balanced margin's lands lower; docs/theory.md)
            att, t, ds = self.solve(i, d, top, slope=True, balance=bool(held))
            if att is not None:
                lo, best, misses = d, att, 0
                held.append((d, t, ds))
            else:
                hi, capped, misses = d, False, misses + 1
            if self.done(lo, hi) or lo >= hi:
                return lo, best
            if lo < self.floor:  # nothing held yet above the floor: halve
                if d <= self.floor:
                    return lo, best
                d = 0.5 * d
                continue
            zero = self._zero(held)
            if att is not None and zero - lo <= self.rtol * lo:  # the predicted boundary is within rtol
                return lo, best
            spread = abs(zero - zeros[-1]) / zero if att is not None and zeros else 1.0
            if att is not None:
                zeros.append(zero)
            d = self._next(lo, hi, zero, capped, misses, spread)

    @staticmethod
    def _zero(held: list[tuple[float, float, float]]) -> float:
        """Where the optimum margin t(delta) is predicted to reach 0, from the certified points' t and slope.

        Near the boundary t behaves like c (delta* - delta)^p with p about 1.4 (t then convex, and a Newton
        step from a certified point stays below delta*); with r = t / |dt/d delta| = (delta* - delta) / p at
        two points, p is their difference in delta over their difference in r (kept in [1, 3]). One point:
        Newton (p = 1). Without slopes (nan): the zero of the line through the last two t's, or 1.5 lo.
        """
        slopes = [(d, t / -s) for d, t, s in held if math.isfinite(s) and s < 0.0 and t > 0.0]
        if slopes and slopes[-1][0] == held[-1][0]:
            d1, r1 = slopes[-1]
            p = 1.0
            if len(slopes) >= 2 and slopes[-2][1] > r1:
                d0, r0 = slopes[-2]
                p = min(max((d1 - d0) / (r0 - r1), 1.0), 3.0)
            return d1 + p * r1
        lo = held[-1][0] if held else 0.0
        if len(held) >= 2:
            (d0, t0, _), (d1, t1, _) = held[-2], held[-1]
            if t1 < t0:
                return d1 + t1 * (d1 - d0) / (t0 - t1)
        return 1.5 * lo

    def _next(self, lo: float, hi: float, zero: float, capped: bool, misses: int, spread: float = 1.0) -> float:
        """The next delta of phase 2 in (lo, hi): rtol (at least 2 %) below the predicted zero of t, inside the bracket.

        That step usually holds and ends the search (:meth:`margin`: its next prediction then lies
        within rtol, or a failure does). Once two certified points predict zeros that agree (their
        relative ``spread`` below 1 %), the step is only twice that spread (at least rtol) below
        the prediction: a fine rtol is then reached in a step or two instead of creeping up. When the prediction
        lies beyond a failure (t bends down far from the boundary) the step is as far below that
        failure, and after a second failure in a row the bracket is halved. ``capped``: hi is the
        search's cap, not a failure: at most a doubling.
        """
        # the prediction's own accuracy (a smaller rtol does not make it sharper), unless two agree
        below = max(self.rtol, min(0.02, 2.0 * spread))
        aim = zero * (1.0 - below)
        if capped:
            return min(max(aim, lo * (1.0 + self.rtol)), 2.0 * lo, hi)
        width = hi - lo
        if misses >= 2:
            return lo + 0.5 * width
        if zero >= hi:
            return max(hi * (1.0 - below), lo + 0.5 * width)
        return min(max(aim, lo * (1.0 + 0.25 * self.rtol)), lo + 0.9 * width)

    def search(self, cap: float) -> tuple[float, list[_Attempt | None], list[float], int]:
        """The team margin: (delta, each mode's attempt, the delta it was solved at (>= delta), the limiting mode)."""
        found: list[_Attempt | None] = [None for _ in self.fs]
        at = [0.0 for _ in self.fs]
        upper, found[0] = self.margin(0, cap, True)
        at[0] = upper
        if found[0] is None:
            return 0.0, found, at, 0
        limiting = 0
        for i in range(1, len(self.fs)):  # every other mode: certified at the current margin, or searched below it
            att = self.check(i, upper)
            if att is None:
                upper, att = self.margin(i, upper, False)
                limiting = i
            found[i], at[i] = att, upper
            if att is None:
                return 0.0, found, at, i
        return upper, found, at, limiting


def _setup(topology: Topology, P: float, D: float, tau1: float, tau2: float, max_order: object, upper_cuts: object,
           cover_intervals: object) -> tuple[float, float, tuple[Functional, ...], tuple[CharacteristicFactor, ...], list[complex]] | TeamDelayMargin:  # fmt: skip
    """The delays, the functionals, the factors and their rightmost roots; or the answer without a search (its reason)."""
    from delayform.analysis.roots.single import rightmost_root  # roots import the network layer: not at the top

    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    if isinstance(max_order, bool) or max_order not in (1, 2, 3, 4):
        raise InputError(f"max_order must be 1, 2, 3 or 4, got {max_order!r}")
    if not isinstance(upper_cuts, bool):
        raise InputError(f"upper_cuts must be True or False, got {upper_cuts!r}")
    if not isinstance(cover_intervals, bool):
        raise InputError(f"cover_intervals must be True or False, got {cover_intervals!r}")
    levels = tuple(f for f in LEVELS if f.order <= max_order) + ((Functional(4, 1, True),) if max_order == 4 else ())
    if upper_cuts or cover_intervals:
        levels = levels[:-1] + (replace(levels[-1], upper=True, cover=cover_intervals),)
    fs = tuple(factors(topology, P, D))
    if t1 == 0.0:
        return TeamDelayMargin(0.0, None, (), reason=(
            "tau1 = 0: the centroid's zero is double (the team drifts) and no variation of the delays is certified"))
    right = [complex(rightmost_root(f, t1, t2)) for f in fs]
    worst = max(right, key=lambda z: z.real)
    if not worst.real < 0.0:
        return TeamDelayMargin(0.0, None, (), reason=(
            f"the nominal delays are unstable (rightmost root {worst.real:.4g} {worst.imag:+.4g}j)"))
    return t1, t2, levels, fs, right


@validated()
def team_delay_margin(topology: Topology, P: float, D: float, tau1: float, tau2: float, *,
                      rtol: float = 0.02, max_order: int = 3, upper_cuts: bool = False,
                      cover_intervals: bool = False) -> TeamDelayMargin:  # fmt: skip
    """The certified margin of the team for delays varying together on every link (module docstring).

    Parameters
    ----------
    topology, P, D
        The team and the gains of the paper's eq. 1.
    tau1, tau2
        The nominal delays, the same on every link.
    rtol
        Relative width at which the search on delta stops (0.001 to 0.1).
    max_order
        The highest Bessel-Legendre order of :data:`LEVELS` tried (1 to 4; 4 adds an order-4
        functional after them): lower is faster and more conservative.
    upper_cuts
        The richest functional also cuts its constant windows at the delays' upper ends
        (docs/theory.md): a little tighter, its LMIs larger (about three times the CPU time).
    cover_intervals
        The richest functional's constant windows also cover the delays' intervals, the integral
        over each tied to its two parts' (docs/theory.md; includes ``upper_cuts``): the tightest,
        each of its SDPs about four times the CPU time of an uncut one. Worth it with a fine
        ``rtol`` (0.001: 0.0999 s at b) or through :func:`certify_team_delays` at a given delta.
        Real modes only: a conjugate pair keeps the windows cut at the upper ends.

    Returns
    -------
    TeamDelayMargin
        The smallest mode margin, each mode's certificate re-checked exactly.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, rtol=0.1, max_order=1)  # point b, Wirtinger only
    >>> 0.035 < m.delta < 0.2622, m.covers.startswith("the same")  # above small gain, below constant offsets
    (True, True)
    """
    if not (isinstance(rtol, (int, float)) and 0.001 <= rtol <= 0.1):
        raise InputError(f"rtol must be a number from 0.001 to 0.1, got {rtol!r}")
    setup = _setup(topology, P, D, tau1, tau2, max_order, upper_cuts, cover_intervals)
    if isinstance(setup, TeamDelayMargin):
        return setup
    t1, t2, levels, fs, right = setup
    start = 0.05 * max(t1, t2, 0.2)
    modes = _Modes(fs, t1, t2, right, levels, rtol, start)
    # beyond tau1 the position delay may be 0, where the centroid's zero is double: nothing to certify
    delta, found, at, limiting = modes.search(t1 * (1.0 - 1e-9))
    options = {f.describe(): f for fl in modes.mode_levels for f in fl}
    gap = rtol * delta
    confirmed: dict[int, DelayCertificate] = {}
    while delta > 0.0:
        for att in found:  # the exact re-check once per attempt, not again after a step back
            if att is not None and id(att) not in confirmed:
                confirmed[id(att)] = att.confirmed()
        certs = [confirmed[id(att)] for att in found if att is not None]
        if len(certs) == len(found) and all(c.holds for c in certs):
            out = tuple(ModeMargin(f.lam, f.is_centroid, att.cert.method, c, options[att.cert.method], d)
                        for f, att, c, d in zip(modes.fs, found, certs, at, strict=True))  # fmt: skip
            return TeamDelayMargin(delta, modes.fs[limiting].lam, out, tried=tuple(modes.tried), tolerance=gap)
        modes.tried.append((delta, "failed the exact re-check"))
        lower = [(d, att) for d, att in modes.history[limiting] if d < delta]
        if len(certs) == len(found) and [k for k, c in enumerate(certs) if not c.holds] == [limiting] and lower:
            # the limiting mode's largest certified delta below: every other mode holds there too (wider intervals)
            delta, found[limiting] = max(lower, key=lambda pair: pair[0])
            at[limiting] = delta
            gap = rtol * delta
            continue
        delta *= 0.5  # rare: step back and certify every mode again there
        found = [modes.check(i, delta) for i in range(len(modes.fs))] if delta > 1e-3 * start else []
        at = [delta for _ in found]
        if not found or any(att is None for att in found):
            break
    return TeamDelayMargin(0.0, modes.fs[limiting].lam, (), tried=tuple(modes.tried), tolerance=gap,
                           reason="no deviation of the delays could be certified")  # fmt: skip


#: Clarabel's own tolerances (1e-8): the last solve of a certificate asked for at a given delta.
CAREFUL_TOLERANCE = 1e-8


@validated()
def certify_team_delays(topology: Topology, P: float, D: float, tau1: float, tau2: float, delta: float, *,
                        max_order: int = 3, upper_cuts: bool = False,
                        cover_intervals: bool = False) -> TeamDelayMargin:  # fmt: skip
    """Certify the team for every h1(t) in [tau1 - delta, tau1 + delta], h2(t) in [tau2 - delta, tau2 + delta].

    The question a known jitter bound asks (is +-delta safe?), answered without a search: every mode
    is certified at ``delta`` by the cheapest functional of :data:`LEVELS` that holds, the richest one
    last, solved again at Clarabel's own tolerances when the search's looser ones do not suffice;
    every certificate is re-checked exactly. Coverage as :func:`team_delay_margin` (the same delays
    on every link, varying arbitrarily fast).

    Parameters
    ----------
    topology, P, D, tau1, tau2
        As for :func:`team_delay_margin`.
    delta
        The deviation to certify, positive and below tau1.
    max_order, upper_cuts, cover_intervals
        As for :func:`team_delay_margin`.

    Returns
    -------
    TeamDelayMargin
        ``delta`` itself when every mode holds; otherwise 0, with ``limiting`` the first mode that
        was not certified and ``reason`` saying so.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> certify_team_delays(paper_six(), 1.0, 0.5, 2.0, 1.0, 0.05, max_order=1).delta  # point b, Wirtinger
    0.05
    """
    d, t1 = check_delay("delta", delta), check_delay("tau1", tau1)
    if not 0.0 < d < t1:  # refused before any root or SDP, whatever the nominal delays
        raise InputError(f"delta must be positive and below tau1 = {t1:g} (the position delay may not reach 0), got {d:g}")
    setup = _setup(topology, P, D, tau1, tau2, max_order, upper_cuts, cover_intervals)
    if isinstance(setup, TeamDelayMargin):
        return setup
    t1, t2, levels, fs, right = setup
    modes = _Modes(fs, t1, t2, right, levels, 0.02, 0.05 * max(t1, t2, 0.2))
    options = {f.describe(): f for fl in modes.mode_levels for f in fl}
    out: list[ModeMargin] = []
    for i, f in enumerate(modes.fs):
        att = modes.check(i, d)
        if att is None:  # the richest functional once more, at the solver's own tolerances
            richest = modes.mode_levels[i][-1]
            att = attempt(modes._data(i, d), richest, exact=False, tolerance=CAREFUL_TOLERANCE)
            modes.tried.append((d, f"mode {i}, {richest.describe()}, tolerance {CAREFUL_TOLERANCE:g}: "
                                   + ("holds" if att.cert.holds else "not certified")))  # fmt: skip
            if not att.cert.holds:
                return TeamDelayMargin(0.0, f.lam, (), tried=tuple(modes.tried),
                                       reason=f"mode lam = {f.lam:.4g} is not certified at delta = {d:g}")  # fmt: skip
        cert = att.confirmed()
        if not cert.holds:
            modes.tried.append((d, f"mode {i}: failed the exact re-check"))
            return TeamDelayMargin(0.0, f.lam, (), tried=tuple(modes.tried),
                                   reason=f"mode lam = {f.lam:.4g}: its certificate failed the exact re-check")  # fmt: skip
        out.append(ModeMargin(f.lam, f.is_centroid, att.cert.method, cert, options[att.cert.method], d))
    limiting = modes.fs[0].lam  # the hardest mode (rightmost constant-delay root nearest the axis)
    return TeamDelayMargin(d, limiting, tuple(out), tried=tuple(modes.tried))
