"""The certified dominant root of a team with a constant delay per link.

Method
------
1. Seeds: eigenvalues of the Chebyshev-collocated generator of the 2N-state DDE
   (:mod:`delayform.analysis.network.discretization`), coarse first (a few nodes
   place the dominant roots to 1e-9 already). Small generators are solved densely;
   large ones by shift-and-invert Arnoldi along the imaginary axis, then, once the
   rightmost roots are known, by a band search over the line's window whose shifts
   advance by the coverage each one proves (``band_seeds``).
2. Polish: Newton's method on det M(s) itself (:mod:`delayform.analysis.network.links`),
   the step ``1 / tr(M(s)^{-1} M'(s))`` (d log det M / ds), so no determinant is
   ever formed; a root where M has an m-dimensional kernel (symmetric teams give
   repeated roots) takes the step times m, which keeps Newton quadratic there.
   The rightmost seeds are polished first; they fix the top and so the line, and
   only seeds near or right of the line are polished after (an N x N solve a step).
3. Certify: a line Re s = c is placed in a gap left of the dominant root (within
   0.1 (1 + |top|) of it on the first attempt, 0.3 (1 + |top|) on retries), the
   roots of det M right of it are counted by the argument principle
   (:mod:`delayform.analysis.network.count`), and the count must equal the sum
   of the *geometric* multiplicities (kernel dimensions of M) of the polished
   roots found there, the persistent zero included. Geometric multiplicity never
   exceeds algebraic, so equality leaves no room for a missed root right of c:
   the seeds are heuristics (a missed root makes the count larger and the attempt
   is retried with finer seeds and a wider window), the count is the certificate.

All of it runs with one BLAS thread (:mod:`delayform.analysis.network.blas`).
Cost grows with N as the sparse eigen-solves of 2N (M + 1) states for the seeds,
O(N^3) per Newton step, and, for the certificate, O(N^3) per sample (an N x N
inverse) times a number of samples that grows slowly with N (the piece rule's
threshold is N-free; the samples crowd near the roots close to the line, which
are denser in large teams): measured about N^2.3 from 30 to 200 agents
(docs/benchmarks.md, "per-link dominant root").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.network.blas import single_threaded_blas
from delayform.analysis.network.count import count_right_of, root_radius
from delayform.analysis.network.discretization import DENSE_STATES, SHIFT_SPACING, band_seeds, generator_seeds
from delayform.analysis.network.links import LinkTeam, link_team
from delayform._validation import validated
from delayform.errors import NotConvergedError
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["LinkDominantRoot", "link_dominant_root", "polish_roots", "link_roots_right_of", "dominant_cost",
           "require_dominant"]

#: Newton stops when the step is below this times (1 + |s|).
_STEP_TOL = 1e-13
#: Singular values of M(s) below this times the largest count towards the kernel.
_KERNEL_TOL = 1e-7
#: The rightmost seeds polished first (they fix the top and so the line).
_FIRST = 8
#: Seeds this far left of the line are still polished (a seed may sit a little off its root).
_SEED_MARGIN = 0.1
#: A seed whose last Newton step is below this times (1 + |s|) is near a (repeated) root.
_SLOW_TOL = 1e-5


@validated()
@dataclass(frozen=True, eq=False)
class LinkDominantRoot:
    """The certified dominant root of a team with per-link delays.

    Attributes
    ----------
    root
        The rightmost root of det M(s), the centroid's persistent s = 0 excluded
        (both zeros on the drift, see ``drift``); Im >= 0.
    team
        The team and its per-link delays.
    line
        The certifying line Re s = line, left of ``root``.
    count
        The certified number of roots of det M right of ``line`` (multiplicity, s = 0 included).
    roots
        The polished roots right of ``line`` with Im >= 0 (s = 0 included), rightmost first.
    multiplicities
        Kernel dimension of M at each of ``roots``.
    drift
        True when s = 0 is a double root (every position delay the centroid weighs is zero).
    """

    root: complex
    team: LinkTeam
    line: float
    count: int
    roots: NDArray[np.complex128]
    multiplicities: NDArray[np.int64]
    drift: bool

    @property
    def is_stable(self) -> bool:
        """True when every root but the centroid's persistent zero(s) has Re s < 0."""
        return self.root.real < 0.0

    @property
    def growth_rate(self) -> float:
        """Re root when it grows, else 0.0 (1/s)."""
        return max(self.root.real, 0.0)

    @property
    def time_constant(self) -> float:
        """1 / |Re root| for a decaying root; ``math.inf`` otherwise."""
        return 1.0 / -self.root.real if self.root.real < 0.0 else math.inf

    def plot(self, ax: Axes | None = None) -> Axes:
        """The roots found right of the certifying line, the line, and the dominant root."""
        import matplotlib.pyplot as plt

        if ax is None:
            ax = plt.figure().add_subplot()
        r = np.concatenate([self.roots, self.roots[self.roots.imag > 0].conj()])
        ax.plot(r.real, r.imag, "o", ms=4, label="roots right of the line")
        ax.plot([self.root.real], [self.root.imag], "r*", ms=10, label="dominant root")
        ax.axvline(self.line, color="grey", ls="--", label=f"certified: {self.count} roots right")
        ax.axvline(0.0, color="k", lw=0.5)
        ax.set_xlabel("Re s")
        ax.set_ylabel("Im s")
        ax.legend(loc="best", fontsize="small")
        return ax


def _newton(team: LinkTeam, s: NDArray[np.complex128], mult: NDArray[np.float64], steps: int) -> tuple[
    NDArray[np.complex128], NDArray[np.bool_], NDArray[np.float64]
]:  # fmt: skip
    """Newton on det M at every point together; the points, which ones converged, and each last step."""
    done = np.zeros(s.shape, dtype=bool)
    last = np.full(s.shape, np.inf)
    s = s.copy()
    for _ in range(steps):
        act = np.flatnonzero(~done)
        if act.size == 0:
            break
        sa = s[act]
        M = team.matrix(sa)
        Md = team.derivative(sa)
        with np.errstate(all="ignore"):
            try:
                tr = np.trace(np.linalg.solve(M, Md), axis1=1, axis2=2)
            except np.linalg.LinAlgError:
                tr = np.array([_safe_trace(M[k], Md[k]) for k in range(act.size)])
            step = mult[act] / tr
        step = np.where(np.isfinite(step), step, 0.0)
        s[act] = sa - step
        last[act] = np.abs(step)
        done[act] = np.abs(step) <= _STEP_TOL * (1.0 + np.abs(sa))
    return s, done, last


def _safe_trace(M: NDArray[np.complex128], Md: NDArray[np.complex128]) -> complex:
    try:
        return complex(np.trace(np.linalg.solve(M, Md)))
    except np.linalg.LinAlgError:
        return complex(np.inf)  # exactly singular: s is a root, the step is 0


def _kernel_dimension(team: LinkTeam, s: NDArray[np.complex128]) -> NDArray[np.int64]:
    sv = np.linalg.svd(team.matrix(s), compute_uv=False)
    return np.sum(sv <= _KERNEL_TOL * sv[:, :1], axis=1).astype(np.int64)


def _tidy(s: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Real roots made real, the persistent zero snapped to 0, Im >= 0 kept, duplicates merged."""
    s = np.where(np.abs(s.imag) < 1e-10 * (1.0 + np.abs(s)), s.real + 0j, s)
    # s = 0 is an exact root (M(0) = P (I - C)); as a double root (the drift) Newton reaches it only to ~1e-8
    s = np.where(np.abs(s) < 1e-6, 0j, s)
    return _distinct(s[s.imag >= 0.0])


def polish_roots(team: LinkTeam, seeds: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Polish seeds on det M (Newton, multiplicity-aware); distinct roots with Im >= 0 and kernel dimensions.

    Parameters
    ----------
    team
        The team and its per-link delays.
    seeds
        Approximate roots (any, e.g. eigenvalues of a discretization).

    Returns
    -------
    roots, kernel
        Converged distinct roots (Im >= 0, rightmost first; the persistent zero
        snapped to 0) and the kernel dimension of M at each.
    """
    s0 = np.asarray(seeds, dtype=np.complex128).ravel()
    s0 = np.where(s0.imag < 0, s0.conj(), s0)
    with single_threaded_blas():
        s, ok, last = _newton(team, s0, np.ones(s0.size), 40)
        # a repeated root (symmetric teams) draws Newton in only linearly: kept while its steps are small,
        # then Newton times the kernel dimension finishes it quadratically
        slow = ~ok & (last < _SLOW_TOL * (1.0 + np.abs(s)))
        roots = _tidy(s[ok | slow])
        if not roots.size:
            return roots, np.zeros(0, np.int64)
        m = np.maximum(_kernel_dimension(team, roots), 1)
        if np.any(m > 1) or slow.any():
            again = (m > 1) | np.isin(roots, s[slow])
            r2, ok2, _ = _newton(team, roots[again], m[again].astype(np.float64), 20)
            roots = _tidy(np.concatenate([roots[~again], r2[ok2]]))
            if not roots.size:
                return roots, np.zeros(0, np.int64)
            m = _kernel_dimension(team, roots)
        return roots, m


def _distinct(s: NDArray[np.complex128]) -> NDArray[np.complex128]:
    out: list[complex] = []
    for z in s[np.argsort(-s.real, kind="stable")]:
        if not any(abs(z - w) <= 1e-8 * (1.0 + abs(z)) for w in out):
            out.append(complex(z))
    return np.array(out, dtype=np.complex128)


def _choose_line(reals: NDArray[np.float64], top: float, width: float) -> float:
    """A line Re s = c left of ``top``, as far as possible from every known real part (0 among them).

    The line is sought in (top - width, top): the widest gap there, or the window's
    left end when that is farther from every root; far from roots the certificate
    needs fewer samples, and a narrow window leaves fewer roots to find right of it.
    """
    lo = top - width
    near = np.sort(np.unique(np.concatenate([reals[(reals > lo) & (reals < top)], [top]])))
    cands = np.concatenate([0.5 * (near[1:] + near[:-1]), [lo]])
    dist = np.min(np.abs(cands[:, None] - reals[None, :]), axis=1)
    return float(cands[int(np.argmax(dist))])


def link_roots_right_of(team: LinkTeam, c: float, *, degree: int | None = None) -> NDArray[np.complex128]:
    """Polished roots of det M of ``team`` with Re s > c from the discretization (Im >= 0), not certified.

    ``degree`` is the number of Chebyshev intervals (default: from the delays and the root radius).
    """
    require_seed_search(team, c)
    R = root_radius(team, c)
    M = degree or _degree(team, R)
    with single_threaded_blas():
        seeds = generator_seeds(team, M, 1.5 * R)
        roots, _ = polish_roots(team, seeds[seeds.real > c - 0.5])
    return roots[roots.real > c]


def _degree(team: LinkTeam, radius: float, attempt: int = 1) -> int:
    """Chebyshev intervals of the seeds' collocation: coarse first, finer on each retry.

    The collocation resolves e^{-tau s} for |s| tau up to about M, and seeds need only
    reach Newton's basin (at 100 agents, M = 6 already places the dominant roots to 1e-9),
    so the first attempt is coarse; a root it misses shows in the certified count.
    """
    if attempt == 0:
        return int(np.clip(math.ceil(0.5 * team.max_delay * radius) + 5, 6, 160))
    return int(np.clip(math.ceil((0.8 + 0.7 * attempt) * team.max_delay * radius) + 8, 8, 160))


@validated()
def link_dominant_root(topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike) -> LinkDominantRoot:
    """The certified dominant root of the team with per-link delays (det of the N x N matrix).

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its per-link delays, as for
        :func:`~delayform.analysis.network.links.link_team` (scalars or N x N arrays).

    Returns
    -------
    LinkDominantRoot

    Raises
    ------
    DelayError
        Wrong shape, negative or non-finite delays on a link.
    NotConvergedError
        When no line could be certified (the partial result attached).

    Examples
    --------
    >>> import numpy as np
    >>> from delayform.topology import paper_six
    >>> t1 = np.full((6, 6), 1.0); t1[0, 5] = 0.8
    >>> r = link_dominant_root(paper_six(), 1.0, 0.5, t1, 0.5)
    >>> r.is_stable
    True
    """
    team = link_team(topology, P, D, tau1, tau2)
    return dominant_of_team(team)


#: seconds of one certified per-link root per N^2.5 (random digraphs and rings of 30-200 agents,
#: delays near 0.3 s, root radius near 2.8: 0.1-10.7 s under load, docs/benchmarks.md)
_SECONDS_PER_N25 = 2e-5
#: the root radius of those measurements (more shifts and count samples above it)
_MEASURED_RADIUS = 3.3


#: what a user changes when a per-link root is refused
_DOMINANT_SETTING = ("the number of agents (topology.n, --n) or the delays (delays.tau1, delays.tau2, "
                     "--tau1, --tau2, --tau1-box, --tau2-box, the delay files)")


def dominant_cost(team: LinkTeam) -> tuple[float, float]:
    """Estimated peak bytes and seconds of :func:`dominant_of_team` (module docstring, "Cost").

    Time: the measured N^2.5 growth, times how far the root radius R (which grows
    like e^{tau |c|} with the delays) exceeds the measured one, since the
    seeds' Arnoldi shifts along the imaginary axis and the certificate's samples
    both grow with R. Memory: a few N x N complex matrices (Newton, the count),
    the shifts and their eigenvalues, and the sparse LU of the 2N (M + 1) states.
    """
    n = float(team.n)
    R = root_radius(team, -0.5)
    shifts = (R + 0.5) / 0.75 + 1.0
    states = 2.0 * n * (_degree(team, R, 3) + 1.0)
    nbytes = 64.0 * n * n + 500.0 * shifts + 400.0 * states
    seconds = _SECONDS_PER_N25 * n**2.5 * max(1.0, (R + 0.5) / _MEASURED_RADIUS)
    return nbytes, seconds


def require_dominant(team: LinkTeam, *, times: int = 1, what: str | None = None) -> None:
    """Refuse, before any work, ``times`` certified per-link roots beyond the budget (:mod:`delayform.resources`).

    Parameters
    ----------
    team
        The checked per-link team (:class:`~delayform.analysis.network.links.LinkTeam`).
    times
        How many such roots the job computes (a box's corners, a map's cells).
    what
        The job as the user asked for it, for the message; default: the certified per-link root.
    """
    from delayform.resources import require

    nbytes, seconds = dominant_cost(team)
    longest = team.max_delay
    job = what or f"the certified per-link root of {team.n:,} agents (longest delay {longest:g} s)"
    require(what=job, setting=_DOMINANT_SETTING, nbytes=nbytes, seconds=times * seconds)


def dominant_of_team(team: LinkTeam) -> LinkDominantRoot:
    """:func:`link_dominant_root` of an already checked :class:`LinkTeam`.

    Raises
    ------
    DelayError
        When the delays make the root bound overflow (no seed search is possible).
    ResourceLimitError
        When the estimate (:func:`dominant_cost`) exceeds the machine's memory or time budget.
    """
    require_seed_search(team, _FIRST_GUESS)
    require_dominant(team)
    with single_threaded_blas():
        return _dominant(team)


#: the first line the seeds are sought right of (:func:`_dominant`)
_FIRST_GUESS = -0.5
#: seconds of one shift-and-invert Arnoldi solve per state of the generator (measured on 2 shared cores,
#: 0.2-1.4 s at 1932 states and 8 s at 9660: rough, the guard is for orders of magnitude)
_SECONDS_PER_STATE = 5e-4


def require_seed_search(team: LinkTeam, c: float) -> None:
    """Refuse, before any work, a team whose seed search right of Re s = ``c`` overflows or would take too long.

    The root bound of :func:`~delayform.analysis.network.count.root_radius` grows like
    e^{-tau c} with the longest delay tau, and the seeds need one Arnoldi solve per
    0.75 of it along the imaginary axis: delays of a few tens of seconds already need
    hours, and at 10^3 s the bound is no float.

    Raises
    ------
    DelayError
        When the bound is not a finite number (the delays are too long to analyse).
    ResourceLimitError
        When the solves would exceed the time budget (:mod:`delayform.resources`).
    """
    from delayform.errors import DelayError
    from delayform.resources import require

    with np.errstate(over="ignore"):
        R = root_radius(team, c)
    longest = team.max_delay
    if not math.isfinite(R):
        raise DelayError(f"delays up to {longest:.4g} s are too long for the per-link root finder: its bound on "
                         f"the roots, which grows like e^(tau/2), is no longer a finite number; choose shorter delays")  # fmt: skip
    size = 2 * team.n * (_degree(team, R, 0) + 1)
    if size <= DENSE_STATES:
        return  # one dense eigenvalue problem, no shifts
    shifts = R / SHIFT_SPACING + 1.0
    require(what=f"the per-link root finder for delays up to {longest:.4g} s ({shifts:.3g} Arnoldi solves of "
                 f"{size} states along the imaginary axis)",
            setting=_DOMINANT_SETTING, seconds=shifts * size * _SECONDS_PER_STATE)  # fmt: skip


def _upper_seeds(seeds: NDArray[np.complex128], left: float) -> NDArray[np.complex128]:
    """Seeds with Im >= 0 right of ``left``, rightmost first, near-duplicates (overlapping shifts) merged."""
    s = seeds[(seeds.imag >= 0.0) & (seeds.real > left)]
    s = s[np.argsort(-s.real, kind="stable")]
    if s.size < 2:
        return s
    # Arnoldi at neighbouring shifts returns the same eigenvalue twice; a seed within 1e-6 of a kept one adds nothing
    key = np.round(s.real * 1e6) + 1j * np.round(s.imag * 1e6)
    _, first = np.unique(key, return_index=True)
    return s[np.sort(first)]


def _dominant(team: LinkTeam) -> LinkDominantRoot:
    """Seeds, a line, Newton on the seeds that matter, the certified count (module docstring)."""
    zero_mult = team.zero_multiplicity()
    poles = np.roots([1.0, team.D, team.P]).real  # the zeros of p: poles of det(I - K/p), kept off the line
    guess = _FIRST_GUESS
    last: tuple[NDArray[np.complex128], NDArray[np.int64]] | None = None
    for attempt in range(4):
        R = root_radius(team, guess)
        M = _degree(team, R, attempt)
        seeds = _upper_seeds(generator_seeds(team, M, R + 0.5, nearest=30 + 20 * attempt), guess - 0.5)
        # the rightmost seeds fix the top; the line follows, and only seeds near or right of it are polished
        roots, _ = polish_roots(team, seeds[:_FIRST])
        nonzero = roots != 0.0
        if not nonzero.any():
            guess -= 1.0
            continue
        top = float(roots[nonzero].real.max())
        width = (0.1 if attempt == 0 else 0.3) * (1.0 + abs(top))
        # large teams: the coarse shifts may miss some of a crowded cluster; a band over the
        # line's whole window (and a little right of the top) is searched for every eigenvalue
        band = band_seeds(team, M, top - width - _SEED_MARGIN, top + _SEED_MARGIN, root_radius(team, top - width),
                          nearest=30 + 20 * attempt)  # fmt: skip
        seeds = _upper_seeds(np.concatenate([seeds, band]), guess - 0.5)
        c = _choose_line(np.concatenate([roots.real, seeds.real, [0.0], poles]), top, width)
        roots, kern = polish_roots(team, np.concatenate([roots, seeds[seeds.real > c - _SEED_MARGIN]]))
        nonzero = roots != 0.0
        last = (roots, kern)
        if roots[nonzero].real.max(initial=-np.inf) > top:  # a seed went right of the top: recentre the line
            top = float(roots[nonzero].real.max())
            c = _choose_line(np.concatenate([roots.real, seeds.real, [0.0], poles]), top, width)
        count = count_right_of(team, c)
        right = roots.real > c
        weight = np.where(roots.imag > 0.0, 2, 1)  # a conjugate pair counts twice
        found = int(np.sum((kern * weight)[right & nonzero])) + (zero_mult if c < 0.0 else 0)
        if count is not None and count == found:
            inside = roots[right]
            dom = roots[nonzero][int(np.argmax(roots[nonzero].real))]
            return LinkDominantRoot(complex(dom), team, c, count, inside, kern[right], zero_mult == 2)
        # a root was missed (count > found) or the line was too close to one: finer seeds, further left
        guess = min(guess, c - 0.5)
    raise NotConvergedError(
        "the dominant root of the per-link team could not be certified (argument-principle count and roots found differ)",
        partial=last,
    )
