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
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.certificates.intervals import IntervalDelays
from delayform.analysis.certificates.margin import DelayCertificate, _Attempt
from delayform.analysis.certificates.several import Functional, attempt
from delayform._validation import check_delay, validated
from delayform.characteristic import CharacteristicFactor, factors
from delayform.errors import InputError
from delayform.topology import Topology

__all__ = ["COVERS", "LEVELS", "ModeMargin", "TeamDelayMargin", "team_delay_margin"]

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
        The functional whose certificate holds (the cheapest of :data:`LEVELS` that does).
    certificate
        Its certificate (re-checked exactly), on intervals at least as wide as the team's
        delta (a certificate for wider intervals covers the narrower ones); None when delta is 0.
    """

    lam: complex
    centroid: bool
    functional: str
    certificate: DelayCertificate | None = field(repr=False)


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
        Bound on the gap to the first uncertified delta (the search's relative width times delta).
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


class _Modes:
    """The team's distinct modes, hardest first, searched one at a time below the smallest margin so far.

    The team margin is the smallest mode margin, so a mode only needs a search when it fails at
    the current smallest margin U: the hardest mode (rightmost root nearest the axis) is searched
    first, every other one is then usually a single cheap solve at U. Per mode the functionals of
    ``levels`` are tried cheapest first and a mode never returns to a cheaper one (a functional
    that fails at delta fails at every larger one: the intervals are nested). Between a certified
    and an uncertified delta the next one is interpolated on the solver's optimum margin t(delta)
    (regula falsi, kept inside the middle 80 % of the bracket), which takes fewer solves than halving.
    """

    def __init__(self, fs: tuple[CharacteristicFactor, ...], t1: float, t2: float, right: list[complex],
                 levels: tuple[Functional, ...]) -> None:  # fmt: skip
        self.levels = levels
        order = sorted(range(len(fs)), key=lambda i: -right[i].real)
        self.fs = [fs[i] for i in order]
        self.systems = [mode_system(f) for f in self.fs]
        self.t = (t1, t2)
        self.level = [0 for _ in self.fs]  # the cheapest functional not yet failed, per mode
        self.tried: list[tuple[float, str]] = []

    def check(self, i: int, delta: float) -> tuple[_Attempt | None, float]:
        """(the attempt that holds or None, the solver margin of the last functional tried) for mode i at delta."""
        A0, ak, e = self.systems[i]
        data = IntervalDelays(A0, ak, tuple(max(t - delta, 0.0) for t in self.t), tuple(t + delta for t in self.t), None, e)
        t = -math.inf
        while self.level[i] < len(self.levels):
            att = attempt(data, self.levels[self.level[i]], exact=False)
            t = att.cert.solver_margin if math.isfinite(att.cert.solver_margin) else -math.inf
            if att.cert.holds:
                self.tried.append((delta, f"mode {i}: holds"))
                return att, t
            if self.level[i] == len(self.levels) - 1:
                break
            self.level[i] += 1
        self.tried.append((delta, f"mode {i}: not certified"))
        return None, t

    def margin(self, i: int, lo: float, hi: float, t_lo: float | None, t_hi: float, rtol: float,
               floor: float) -> tuple[float, _Attempt | None]:  # fmt: skip
        """Largest certified delta of mode i in [lo, hi): hi failed (margin t_hi), lo held (t_lo) or is 0."""
        best: _Attempt | None = None
        level = self.level[i]
        while hi - lo > rtol * max(lo, floor):
            width = hi - lo
            mid = 0.5 * (lo + hi)
            if t_lo is not None and t_lo > 0.0 > t_hi and self.level[i] == level:
                mid = lo + width * min(max(t_lo / (t_lo - t_hi), 0.2), 0.8)
            if lo == 0.0 and best is None and mid < floor:
                break
            att, t = self.check(i, mid)
            if att is not None:
                lo, t_lo, best = mid, t, att
            else:
                hi, t_hi = mid, t
            level = self.level[i]
        return lo, best

    def search(self, start: float, cap: float, rtol: float) -> tuple[float, list[_Attempt | None], int]:
        """The team margin: (delta, each mode's attempt at delta or beyond, the limiting mode)."""
        found: list[_Attempt | None] = [None for _ in self.fs]
        limiting, upper = 0, cap
        # the hardest mode: grow from ``start`` until a failure (or the cap), then narrow down
        d, t_lo, lo = min(start, cap), None, 0.0
        while True:
            att, t = self.check(0, d)
            if att is None:
                upper, found[0] = self.margin(0, lo, d, t_lo, t, rtol, 1e-3 * start)
                if found[0] is None:
                    return 0.0, found, 0
                break
            lo, t_lo, found[0] = d, t, att
            if d >= cap:
                upper = d
                break
            d = min(2.0 * d, cap)
        for i in range(1, len(self.fs)):  # every other mode: certified at the current margin, or searched below it
            att, t = self.check(i, upper)
            if att is not None:
                found[i] = att
                continue
            upper, found[i] = self.margin(i, 0.0, upper, None, t, rtol, 1e-3 * start)
            limiting = i
            if found[i] is None:
                return 0.0, found, i
        return upper, found, limiting


@validated()
def team_delay_margin(topology: Topology, P: float, D: float, tau1: float, tau2: float, *,
                      rtol: float = 0.02, max_order: int = 3) -> TeamDelayMargin:  # fmt: skip
    """The certified margin of the team for delays varying together on every link (module docstring).

    Parameters
    ----------
    topology, P, D
        The team and the gains of the paper's eq. 1.
    tau1, tau2
        The nominal delays, the same on every link.
    rtol
        Relative width at which the search on delta stops (0.005 to 0.1).
    max_order
        The highest Bessel-Legendre order of :data:`LEVELS` tried (1 to 3): lower is
        faster and more conservative.

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
    from delayform.analysis.roots.single import rightmost_root  # roots import the network layer: not at the top

    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    if not (isinstance(rtol, (int, float)) and 0.005 <= rtol <= 0.1):
        raise InputError(f"rtol must be a number from 0.005 to 0.1, got {rtol!r}")
    if isinstance(max_order, bool) or max_order not in (1, 2, 3):
        raise InputError(f"max_order must be 1, 2 or 3, got {max_order!r}")
    levels = tuple(f for f in LEVELS if f.order <= max_order)
    fs = factors(topology, P, D)
    if t1 == 0.0:
        return TeamDelayMargin(0.0, None, (), reason=(
            "tau1 = 0: the centroid's zero is double (the team drifts) and no variation of the delays is certified"))
    right = [complex(rightmost_root(f, t1, t2)) for f in fs]
    worst = max(right, key=lambda z: z.real)
    if not worst.real < 0.0:
        return TeamDelayMargin(0.0, None, (), reason=(
            f"the nominal delays are unstable (rightmost root {worst.real:.4g} {worst.imag:+.4g}j)"))
    modes = _Modes(fs, t1, t2, right, levels)
    start = 0.05 * max(t1, t2, 0.2)
    # beyond tau1 the position delay may be 0, where the centroid's zero is double: nothing to certify
    delta, found, limiting = modes.search(start, t1 * (1.0 - 1e-9), rtol)
    gap = rtol * delta
    while delta > 0.0:
        certs = [att.confirmed() for att in found if att is not None]
        if len(certs) == len(found) and all(c.holds for c in certs):
            out = tuple(ModeMargin(f.lam, f.is_centroid, att.cert.method, c)
                        for f, att, c in zip(modes.fs, found, certs, strict=True))  # fmt: skip
            return TeamDelayMargin(delta, modes.fs[limiting].lam, out, tried=tuple(modes.tried), tolerance=gap)
        modes.tried.append((delta, "failed the exact re-check"))
        delta *= 0.5  # rare: step back and certify every mode again there
        found = [modes.check(i, delta)[0] for i in range(len(modes.fs))] if delta > 1e-3 * start else []
        if not found or any(att is None for att in found):
            break
    return TeamDelayMargin(0.0, modes.fs[limiting].lam, (), tried=tuple(modes.tried), tolerance=gap,
                           reason="no deviation of the delays could be certified")  # fmt: skip
