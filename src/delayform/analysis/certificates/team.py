"""A certified margin for the team's delays varying together: one Lyapunov-Krasovskii certificate per mode.

When every link has the same delays h1(t), h2(t), varying in time, the team
still factorizes (eq. factorized): with C = U T U^H (Schur, U unitary, T upper
triangular, its diagonal the eigenvalues lam of C) the coordinates y = U^H x
obey, mode by mode,

    y_j'' = -P y_j - D y_j' + lam_j (P y_j(t - h1(t)) + D y_j'(t - h2(t))) + (terms in y_k, k > j),

the eq. subsystems with time-varying delays (a real 4-state system for a
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
from delayform.analysis.certificates.several import Functional, attempt, search_delta
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
        Gap to the first uncertified delta.
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
    """The team's distinct modes, hardest first, with the cheapest functional that held or failed per deviation."""

    def __init__(self, fs: tuple[CharacteristicFactor, ...], t1: float, t2: float, right: list[complex],
                 levels: tuple[Functional, ...]) -> None:  # fmt: skip
        self.levels = levels
        order = sorted(range(len(fs)), key=lambda i: -right[i].real)
        self.fs = [fs[i] for i in order]
        self.systems = [mode_system(f) for f in self.fs]
        self.t = (t1, t2)
        self.failed: list[dict[int, float]] = [{} for _ in self.fs]  # level -> smallest delta it failed at
        # the widest deviation certified per mode: its certificate covers every smaller one (the intervals are nested)
        self.held: list[tuple[float, _Attempt, int] | None] = [None for _ in self.fs]
        self.limiting = 0

    def check(self, i: int, delta: float) -> tuple[_Attempt, int] | None:
        held = self.held[i]
        if held is not None and held[0] >= delta:
            return held[1], held[2]
        A0, ak, e = self.systems[i]
        data = IntervalDelays(A0, ak, tuple(max(t - delta, 0.0) for t in self.t), tuple(t + delta for t in self.t), None, e)
        for level, fun in enumerate(self.levels):
            if delta >= self.failed[i].get(level, math.inf):  # it failed at a smaller deviation already
                continue
            att = attempt(data, fun, exact=False)
            if att.cert.holds:
                self.held[i] = (delta, att, level)
                return att, level
            self.failed[i][level] = min(delta, self.failed[i].get(level, math.inf))
        return None

    def all_hold(self, delta: float) -> list[tuple[_Attempt, int]] | None:
        """Every mode certified at delta (the last limiting mode first: a failure ends the check early)."""
        order = [self.limiting] + [i for i in range(len(self.fs)) if i != self.limiting]
        out: dict[int, tuple[_Attempt, int]] = {}
        for i in order:
            got = self.check(i, delta)
            if got is None:
                self.limiting = i
                return None
            out[i] = got
        return [out[i] for i in range(len(self.fs))]


@validated()
def team_delay_margin(topology: Topology, P: float, D: float, tau1: float, tau2: float, *,
                      rtol: float = 0.02, max_order: int = 3) -> TeamDelayMargin:  # fmt: skip
    """The certified margin of the team for delays varying together on every link (module docstring).

    Parameters
    ----------
    topology, P, D
        The team and the gains of eq. protocol.
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
    delta, found, tried, gap = search_delta(modes.all_hold, start, t1 * (1.0 - 1e-9), rtol)
    while found is not None:
        certs = [att.confirmed() for att, _ in found]
        if all(c.holds for c in certs):
            out = tuple(ModeMargin(f.lam, f.is_centroid, levels[lv].describe(), c)
                        for f, (_, lv), c in zip(modes.fs, found, certs, strict=True))  # fmt: skip
            return TeamDelayMargin(delta, modes.fs[modes.limiting].lam, out, tried=tuple(tried), tolerance=gap)
        tried.append((delta, "failed the exact re-check"))
        delta *= 0.5
        found = modes.all_hold(delta) if delta > 1e-3 * start else None
    return TeamDelayMargin(0.0, modes.fs[modes.limiting].lam, (), tried=tuple(tried), tolerance=gap,
                           reason="no deviation of the delays could be certified")  # fmt: skip
