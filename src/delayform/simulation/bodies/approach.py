"""Robots with bodies: the exact closest approach of a run and the contacts between robots.

Method
------
Between two saved samples ``t_k`` and ``t_{k+1} = t_k + h`` the motion of a
robot is the cubic Hermite interpolant of its saved positions and
velocities (the same interpolant the integrator uses for its delayed
look-ups, :mod:`delayform.simulation.delayed.integrator`, so with every step saved it
is the integrator's own fourth-order continuous extension). The separation
``d(s) = x_i - x_j`` of a pair is then a planar cubic in ``s in [0, 1]``,
``d = a0 + a1 s + a2 s^2 + a3 s^3``, its squared length ``|d|^2`` a
polynomial of degree 6, and

* the interval's closest approach is the smaller of the end values and the
  values at the real roots in ``(0, 1)`` of the quintic ``d/ds |d|^2``,
  found as eigenvalues of its companion matrix (batched over all intervals
  at once) and polished by Newton steps on the quintic itself;
* a contact starts and ends at the real roots of ``|d|^2 - R^2`` (degree 6,
  the same companion construction), ``R`` the sum of the two radii.

So the closest approach is exact for the interpolated motion, between saved
steps too, not just the minimum over saved samples (which it never exceeds).

Pruning
-------
Only intervals that could come close are solved: on an interval every
robot stays within ``reach`` of both its end samples (:func:`_reach`), so
``|d(s)| >= max(|d_k|, |d_k+1|) - reach_i - reach_j``, and an interval whose
bound is above both the closest saved sample and ``R`` cannot matter.
Small teams (at most :data:`_ALL_PAIRS` robots) first prune whole blocks of
:data:`_BLOCK` intervals per pair by the same argument on the block (each
robot's spread from its first sample), so only the blocks where a pair
comes near are bounded interval by interval; larger teams take the
candidate pairs of each stretch of samples from a KD-tree
(:class:`scipy.spatial.cKDTree`) on the stretch's middle positions, with a
search radius grown by how far any robot moves within the stretch. The
kept intervals are solved in one batch at the end, after a second, tighter
bound from the pair's own Bezier control points (:func:`_hull_bound`);
where ``|d|^2`` is convex on the interval (the usual case) its minimum is
found by bisection and Newton on the increasing derivative, and a
contact's entry and exit as the one sign change of ``|d|^2 - R^2``, instead
of the companion matrix. An interval with a sample in contact is a contact
whatever its minimum, so its minimum is solved only where its bound lets
it fall below the closest sample of its run in contact
(:meth:`_Search.finish`): the contacts' and the run's closest approach stay
exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform._validation import check_non_negative, check_shaped, validated
from delayform.errors import SimulationInputError

__all__ = ["Contact", "Approach", "closest_approach", "sample_min_distance", "approach_cost"]

_Array = NDArray[np.float64]
_Index = NDArray[np.intp]

#: teams up to this size test every pair; larger ones use a KD-tree per stretch
_ALL_PAIRS = 64

#: about this many (interval x pair) entries are handled at once
_CHUNK_ENTRIES = 400_000

#: intervals per stretch (one KD-tree each) in teams above _ALL_PAIRS robots: at least, at most
_STRETCH = 8
_LONGEST = 512

#: a stretch ends when the fastest robots could have strayed this far (m) in it
_STRAY = 0.5

#: intervals per block of the small teams' first pruning (:meth:`_Search.blocks`)
_BLOCK = 32

#: Newton steps that polish a companion-matrix root on the polynomial itself
_NEWTON = 3


@validated(SimulationInputError)
@dataclass(frozen=True)
class Contact:
    """Two robots closer than the sum of their radii during one stretch of time.

    Attributes
    ----------
    agents
        The pair ``(i, j)``, ``i < j``, as agent indices (from 0).
    start, end
        When the bodies first touched and separated again (s); ``end`` is the
        end of the run when they were still in contact then.
    closest
        Smallest centre-to-centre distance during the contact (m).
    closest_at
        When it happened (s).
    contact_distance
        The sum of the two radii (m): a contact is ``distance < contact_distance``.
    """

    agents: tuple[int, int]
    start: float
    end: float
    closest: float
    closest_at: float
    contact_distance: float

    @property
    def duration(self) -> float:
        """How long the bodies overlapped (s)."""
        return self.end - self.start

    @property
    def depth(self) -> float:
        """How far the bodies overlapped at the closest point (m)."""
        return self.contact_distance - self.closest

    def sentence(self, labels: tuple[object, ...] = ()) -> str:
        """One line for a reader, agents by their topology ``labels`` (else numbered from 1)."""
        i, j = self.agents
        a, b = (labels[i], labels[j]) if labels else (i + 1, j + 1)
        return (
            f"robots {a} and {b} touched from t = {self.start:.4g} s to {self.end:.4g} s "
            f"({self.duration:.3g} s), {self.closest:.3g} m apart at t = {self.closest_at:.4g} s "
            f"(bodies need {self.contact_distance:.3g} m)"
        )


@validated(SimulationInputError)
@dataclass(frozen=True)
class Approach:
    """The closest approach of a run and its contacts (:func:`closest_approach`).

    Attributes
    ----------
    min_distance
        Smallest centre-to-centre distance of two robots over the run (m),
        exact for the interpolated motion; ``inf`` for one robot.
    at
        When it happened (s); NaN for one robot.
    pair
        Which two robots (indices from 0); ``(-1, -1)`` for one robot.
    contacts
        Every contact, ordered by start time.
    """

    min_distance: float
    at: float
    pair: tuple[int, int]
    contacts: tuple[Contact, ...]


# ----------------------------------------------------------- polynomials
def _hermite_coefficients(d0: _Array, d1: _Array, w0: _Array, w1: _Array, h: _Array) -> tuple[_Array, ...]:
    """Power-basis coefficients ``a0..a3`` (each ``(..., 2)``) of the cubic Hermite separation."""
    m0, m1 = w0 * h[..., None], w1 * h[..., None]
    step = d1 - d0
    return d0, m0, 3.0 * step - 2.0 * m0 - m1, -2.0 * step + m0 + m1


def _squared_length(a: tuple[_Array, ...]) -> _Array:
    """``(..., 7)`` coefficients (ascending) of ``|a0 + a1 s + a2 s^2 + a3 s^3|^2``."""
    out = np.zeros(a[0].shape[:-1] + (7,))
    for p in range(4):
        for q in range(4):
            out[..., p + q] += np.einsum("...k,...k->...", a[p], a[q])
    return out


#: iterates of the roots' Newton polish stay within this distance of [0, 1]
_NEWTON_WINDOW = 1.0

def _polyval(coef: _Array, s: _Array) -> _Array:
    """Evaluate ascending coefficients ``(M, m)`` at ``s`` ``(M, r)`` (Horner)."""
    out = np.zeros_like(s) + coef[:, -1:]
    for c in range(coef.shape[1] - 2, -1, -1):
        out = out * s + coef[:, c : c + 1]
    return out


def _unit_roots(coef: _Array) -> tuple[_Array, _Array]:
    """Real roots in ``[0, 1]`` of polynomials with ascending coefficients ``(M, m)``.

    Returns ``(roots, valid)``, both ``(M, m - 1)``: the companion matrix's
    eigenvalues, polished by Newton steps, and where they are real and in
    ``[0, 1]``. A vanishing leading coefficient (a lower degree) is lifted
    to a tiny one, which only adds a root far outside ``[0, 1]``.
    """
    M, m = coef.shape
    deg = m - 1
    scale = np.abs(coef).max(axis=1) + 1e-300
    lead = coef[:, -1].copy()
    tiny = 1e-13 * scale
    small = np.abs(lead) < tiny
    lead[small] = np.where(lead[small] < 0, -tiny[small], tiny[small])
    comp = np.zeros((M, deg, deg))
    comp[:, 1:, :-1] = np.eye(deg - 1)
    comp[:, :, -1] = -coef[:, :-1] / lead[:, None]
    eig = np.linalg.eigvals(comp)
    real = np.abs(eig.imag) <= 1e-6 * (1.0 + np.abs(eig.real))
    # Only roots near [0, 1] matter; the lifted leading coefficient can put the others
    # near 1e300, where Horner overflows, so every iterate is kept in a bounded window
    # (a root in [0, 1] that Newton converges to is never moved by it).
    # An eigenvalue outside the window is no candidate, whatever Newton makes of it.
    real &= (eig.real >= -_NEWTON_WINDOW) & (eig.real <= 1.0 + _NEWTON_WINDOW)
    s = np.clip(eig.real, -_NEWTON_WINDOW, 1.0 + _NEWTON_WINDOW)
    deriv = coef[:, 1:] * np.arange(1, m)
    for _ in range(_NEWTON):
        f, fp = _polyval(coef, s), _polyval(deriv, s)
        ok = np.abs(fp) > 0
        with np.errstate(over="ignore"):  # a step past 1e308 (fp subnormal) ends at the window's edge
            step = f / np.where(ok, fp, 1.0)
        s = np.clip(np.where(ok, s - step, s), -_NEWTON_WINDOW, 1.0 + _NEWTON_WINDOW)
    valid = real & (s >= -1e-9) & (s <= 1.0 + 1e-9)
    return np.clip(s, 0.0, 1.0), valid


def _separation_squared(a: tuple[_Array, ...], s: _Array) -> _Array:
    """``|a0 + a1 s + a2 s^2 + a3 s^3|^2`` from the separation itself, per row.

    The expanded squared length (:func:`_squared_length`) loses about eps
    times its coefficients to cancellation, which is sqrt(eps) ~ 1e-8 m after
    the square root near a contact; the separation's own cubic keeps the
    distance accurate to eps times the separation.
    """
    sep = a[0] + s[:, None] * (a[1] + s[:, None] * (a[2] + s[:, None] * a[3]))
    return np.einsum("mk,mk->m", sep, sep)


def _interval_minima(sq: _Array) -> tuple[_Array, _Array]:
    """Smallest ``|d|^2`` over ``[0, 1]`` and where, for squared-length coefficients ``(M, 7)``.

    Where ``|d|^2`` is convex on ``[0, 1]`` (every Bernstein coefficient of its
    second derivative non-negative, which bounds that derivative from below:
    the usual case on a short interval) its derivative increases, so the
    minimum is an end or the derivative's one root, bracketed by bisection
    and polished by Newton steps kept in the bracket. Elsewhere every real
    root of the derivative is a candidate (:func:`_unit_roots`).
    """
    M = sq.shape[0]
    d1 = sq[:, 1:] * np.arange(1, 7)  # (M, 6): the derivative
    d2 = d1[:, 1:] * np.arange(1, 6)  # (M, 5): the second derivative, degree 4
    convex = (d2 @ _BERNSTEIN4.T).min(axis=1) >= 0.0
    where = np.zeros(M)
    rest = np.flatnonzero(~convex)
    if rest.size:
        roots, valid = _unit_roots(d1[rest])
        cand = np.concatenate([np.zeros((rest.size, 1)), np.ones((rest.size, 1)), roots], axis=1)
        values = _polyval(sq[rest], cand)
        values[:, 2:][~valid] = np.inf
        where[rest] = cand[np.arange(rest.size), np.argmin(values, axis=1)]
    easy = np.flatnonzero(convex)
    if easy.size:
        where[easy] = _increasing_root(d1[easy], d2[easy])
    values = _polyval(sq, where[:, None])[:, 0]
    return np.maximum(values, 0.0), where


#: row i: the Bernstein coefficient i of a quartic from its power-basis coefficients (on [0, 1])
_BERNSTEIN4 = np.array([[math.comb(i, k) / math.comb(4, k) if k <= i else 0.0 for k in range(5)] for i in range(5)])

#: bisection steps before Newton's (the bracket shrinks to 2^-12)
_BISECT = 12


def _increasing_root(f: _Array, fp: _Array) -> _Array:
    """Where on ``[0, 1]`` an increasing polynomial ``f`` (coefficients ``(M, m)``, derivative ``fp``) is smallest in size.

    0 where ``f(0) >= 0``, 1 where ``f(1) <= 0``, else its root (:func:`_bracketed_root`).
    """
    s = _bracketed_root(f, fp, np.zeros(f.shape[0]), np.ones(f.shape[0]))
    s = np.where(f[:, 0] >= 0.0, 0.0, s)  # increasing from a non-negative start: smallest at 0
    return np.where(f.sum(axis=1) <= 0.0, 1.0, s)


def _bracketed_root(f: _Array, fp: _Array, lo: _Array, hi: _Array) -> _Array:
    """A root of ``f`` (coefficients ``(M, m)``, derivative ``fp``) in ``[lo, hi]``, where ``f`` changes sign.

    Bisection keeps the sign change bracketed (to ``2^-12`` of the
    bracket), Newton steps clipped to the bracket polish the root.
    """
    lo, hi = lo.copy(), hi.copy()
    above = _polyval(f, lo[:, None])[:, 0] > 0.0  # the sign at lo, kept at lo
    for _ in range(_BISECT):
        mid = 0.5 * (lo + hi)
        same = (_polyval(f, mid[:, None])[:, 0] > 0.0) == above
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    s = 0.5 * (lo + hi)
    for _ in range(_NEWTON):
        val, slope = _polyval(f, s[:, None])[:, 0], _polyval(fp, s[:, None])[:, 0]
        ok = slope != 0.0
        s = np.clip(np.where(ok, s - val / np.where(ok, slope, 1.0), s), lo, hi)
    return s


def _crossing(sq: _Array, level: float, lo: _Array, hi: _Array, first: NDArray[np.bool_]) -> _Array:
    """Per row the first (where ``first``, else the last) root of ``|d|^2 = level`` in ``[lo, hi]``; ``lo`` / ``hi`` if none.

    Where ``|d|^2`` is convex on ``[0, 1]`` (:func:`_interval_minima`'s test)
    the set where it is below the level is one interval, so with the entry's
    ``hi`` (the exit's ``lo``) below the level the crossing is the one sign
    change in ``[lo, hi]``, or none (:func:`_bracketed_root`); every other row
    takes every real root as a candidate (:func:`_unit_roots`).
    """
    shifted = sq.copy()
    shifted[:, 0] -= level
    out = np.where(first, lo, hi)  # no crossing in [lo, hi]
    f_lo, f_hi = _polyval(shifted, lo[:, None])[:, 0], _polyval(shifted, hi[:, None])[:, 0]
    d1 = shifted[:, 1:] * np.arange(1, 7)
    convex = ((d1[:, 1:] * np.arange(1, 6)) @ _BERNSTEIN4.T).min(axis=1) >= 0.0
    easy = convex & np.where(first, f_hi < 0.0, f_lo < 0.0)
    change = np.flatnonzero(easy & np.where(first, f_lo >= 0.0, f_hi >= 0.0))
    if change.size:
        out[change] = _bracketed_root(shifted[change], d1[change], lo[change], hi[change])
    rest = np.flatnonzero(~easy)
    if rest.size:
        roots, valid = _unit_roots(shifted[rest])
        valid &= (roots >= lo[rest, None] - 1e-12) & (roots <= hi[rest, None] + 1e-12)
        earliest = np.where(valid, roots, np.inf).min(axis=1)
        latest = np.where(valid, roots, -np.inf).max(axis=1)
        found = np.where(first[rest], earliest, latest)
        out[rest] = np.where(np.isfinite(found), found, out[rest])
    return out


# --------------------------------------------------------------- search
def _pairs_all(n: int) -> _Index:
    i, j = np.triu_indices(n, k=1)
    return np.column_stack([i, j])


def _pairs_near(frames: _Array, reach: _Array, threshold: float) -> _Index:
    """Pairs of a stretch of samples that may come closer than ``threshold`` (all that can matter).

    ``frames`` ``(m, n, 2)``; ``reach`` ``(n,)`` how far each robot's
    interpolated path strays from its samples within the stretch
    (:func:`_reach`). A pair farther apart at the middle sample than the
    threshold plus twice the largest excursion from it cannot come closer
    during the stretch. An infinite threshold (nothing found yet) is
    replaced by the closest distance at the middle sample, an upper bound.
    """
    from scipy.spatial import cKDTree

    mid = frames[frames.shape[0] // 2]
    tree = cKDTree(mid)
    if not math.isfinite(threshold):
        near, _ = tree.query(mid, k=2)
        threshold = float(near[:, 1].min())
    excursion = np.hypot(*(frames - mid[None]).transpose(2, 0, 1)).max(axis=0) + reach
    radius = threshold + 2.0 * float(excursion.max())
    return tree.query_pairs(radius, output_type="ndarray").astype(np.intp).reshape(-1, 2)


def sample_min_distance(positions: _Array) -> float:
    """Smallest distance of two robots over the saved samples only (the brute-force check).

    Parameters
    ----------
    positions
        ``(T, n, 2)``.
    """
    T, n, _ = positions.shape
    if n < 2:
        return math.inf
    pairs = _pairs_all(n)
    best = math.inf
    step = max(1, _CHUNK_ENTRIES // pairs.shape[0])
    for k in range(0, T, step):
        d = positions[k : k + step, pairs[:, 0]] - positions[k : k + step, pairs[:, 1]]
        best = min(best, float(np.sqrt((d**2).sum(axis=2)).min()))
    return best


#: seconds per (saved sample x pair) while every pair is still a candidate (ring teams closing into a
#: polygon, 1,000 and 2,000 agents, about 1,000 samples: 1.4e-8 and 3e-8 under load)
_SECONDS_PER_PAIR_SAMPLE = 3e-8


def approach_cost(n: int, samples: int) -> tuple[float, float]:
    """Estimated peak bytes and seconds of :func:`closest_approach` on ``samples`` saved samples of ``n`` robots.

    An upper estimate: every pair stays a candidate (a team still closing in
    does not let the KD-tree prune much): the first pruning keeps a distance and a
    spread per (block, pair), the interval bounds one float per (sample, pair).
    """
    pairs = 0.5 * float(n) * (n - 1)
    blocks = samples / _BLOCK + 1.0
    return 32.0 * blocks * pairs, _SECONDS_PER_PAIR_SAMPLE * samples * pairs


@validated(SimulationInputError)
def closest_approach(
    times: _Array, positions: _Array, velocities: _Array, contact_distance: float = 0.0
) -> Approach:
    """The exact closest approach of a run and its contacts (module doc).

    Parameters
    ----------
    times
        ``(T,)`` saved times, increasing.
    positions, velocities
        ``(T, n, 2)`` saved positions and Cartesian velocities.
    contact_distance
        Sum of two robots' radii (m); 0 for point agents (no contacts).

    Returns
    -------
    Approach

    Examples
    --------
    Two robots passing on parallel lines 0.1 m apart, closest between samples:

    >>> t = np.array([0.0, 1.0])
    >>> x = np.array([[[-0.5, 0.0], [0.5, 0.1]], [[0.5, 0.0], [-0.5, 0.1]]])
    >>> v = np.array([[[1.0, 0.0], [-1.0, 0.0]]] * 2)
    >>> a = closest_approach(t, x, v, 0.34)
    >>> round(a.min_distance, 12), a.at, len(a.contacts)
    (0.1, 0.5, 1)
    """
    times, positions, velocities, R = _check_run(times, positions, velocities, contact_distance)
    T, n, _ = positions.shape
    if n < 2:
        return Approach(math.inf, math.nan, (-1, -1), ())
    if T == 1:
        d2 = ((positions[0][:, None] - positions[0][None]) ** 2).sum(axis=2) + np.diag(np.full(n, np.inf))
        a, b = sorted(divmod(int(np.argmin(d2)), n))
        return Approach(math.sqrt(float(d2[a, b])), float(times[0]), (a, b), ())
    h_all = np.diff(times)
    reach = _reach(positions, velocities, h_all)
    search = _Search(times, h_all, R)
    if n <= _ALL_PAIRS:
        search.blocks(0, positions, velocities, reach, _pairs_all(n))
    else:  # stretches in which no robot strays far keep the KD-tree radii tight
        for k0, k1 in _stretches(reach):  # samples k0..k1, intervals k0..k1-1
            pairs = _pairs_near(positions[k0 : k1 + 1], reach[k0:k1].max(axis=0), search.threshold)
            if pairs.shape[0]:
                search.blocks(k0, positions[k0 : k1 + 1], velocities[k0 : k1 + 1], reach[k0:k1], pairs)
    search.finish()
    contacts = _contacts(times, search.hits, R) if search.hits else ()
    return Approach(math.sqrt(search.best2), search.best_at, search.best_pair, contacts)


def _check_run(times: object, positions: object, velocities: object, contact_distance: object) -> tuple[
    _Array, _Array, _Array, float
]:  # fmt: skip
    """The arguments of :func:`closest_approach` as finite float arrays of matching shapes, times increasing."""
    E = SimulationInputError
    t = check_shaped("times", times, (None,), E)  # type: ignore[arg-type]
    if t.size == 0:
        raise E("times must hold at least one saved time")
    if np.any(np.diff(t) <= 0.0):
        k = int(np.flatnonzero(np.diff(t) <= 0.0)[0])
        raise E(f"times must increase, got {t[k]:g} then {t[k + 1]:g} (entries {k} and {k + 1})")
    x = check_shaped("positions", positions, (t.size, None, 2), E)  # type: ignore[arg-type]
    v = check_shaped("velocities", velocities, x.shape, E)  # type: ignore[arg-type]
    return t, x, v, check_non_negative("contact_distance", contact_distance, E)


def _stretches(reach: _Array) -> list[tuple[int, int]]:
    """Stretches of samples ``(k0, k1)`` for the KD-tree search of large teams.

    A stretch ends once the fastest robots' strays (:func:`_reach`) add up
    to :data:`_STRAY` m since its start, but runs at least :data:`_STRETCH`
    and at most :data:`_LONGEST` intervals: short while the team moves, long
    once it has settled, so a settled team costs a few KD-trees, not one per
    sixteen samples.
    """
    cum = np.concatenate([[0.0], np.cumsum(reach.max(axis=1))])
    out, k0, T1 = [], 0, reach.shape[0]
    while k0 < T1:
        k1 = int(np.searchsorted(cum, cum[k0] + _STRAY, side="right")) - 1
        k1 = min(T1, max(k0 + _STRETCH, min(k1, k0 + _LONGEST)))
        out.append((k0, k1))
        k0 = k1
    return out


def _reach(positions: _Array, velocities: _Array, h: _Array) -> _Array:
    """``(T - 1, n)``: how far each robot's interpolated path can stray from either end sample.

    The cubic Hermite segment lies in the convex hull of its Bezier control
    points ``x0, x0 + h v0 / 3, x1 - h v1 / 3, x1``; each is within
    ``|x1 - x0| + h (|v0| + |v1|) / 3`` of both ends.
    """
    # as complex numbers each length is one abs (hypot); in-place sums spare large temporaries
    speed = np.abs(_complex(velocities))
    out = speed[:-1] + speed[1:]
    out *= h[:, None] / 3.0
    out += np.abs(np.diff(_complex(positions), axis=0))
    return out


def _complex(xy: _Array) -> NDArray[np.complex128]:
    """``(..., 2)`` planar points as ``x + iy`` (a view when contiguous)."""
    return np.ascontiguousarray(xy).view(np.complex128)[..., 0]


class _Search:
    """The running closest approach, stretch by stretch, and the intervals that may beat it or touch.

    Stretches only prune (against the closest saved sample so far, an upper
    bound of the closest approach) and keep their candidate intervals;
    :meth:`finish` solves them all at once (one batch, not one per stretch).
    """

    def __init__(self, times: _Array, h: _Array, R: float) -> None:
        self.times, self.h, self.R = times, h, R
        self.best2, self.best_at, self.best_pair = math.inf, math.nan, (-1, -1)
        self.hits: list[tuple[_Index, _Index, _Index, _Array, _Array, _Array]] = []
        self.found: list[tuple[_Index, _Index, _Index, _Array, _Array, _Array, _Array, _Array]] = []

    @property
    def threshold(self) -> float:
        """Intervals that may come closer than this matter: the best so far, or a contact."""
        return max(math.sqrt(self.best2), self.R) if self.best2 < math.inf else math.inf

    def _keep(self, k0: int, k: _Index, i: _Index, j: _Index, bound: _Array, z0: _Array, z1: _Array,
              w: _Array) -> None:  # fmt: skip
        """Keep intervals ``k0 + k`` of pairs ``(i, j)`` (separations z0, z1; velocities w from k0 on) for :meth:`finish`."""
        w0, w1 = w[k, i] - w[k, j], w[k + 1, i] - w[k + 1, j]
        self.found.append((k0 + k, i, j, bound, z0, z1, w0, w1))

    def blocks(self, k0: int, positions: _Array, velocities: _Array, reach: _Array, pairs: _Index) -> None:
        """Samples ``k0 ..`` of the candidate ``pairs``, pruned block by block before any interval is looked at.

        On a block of :data:`_BLOCK` intervals every robot stays within
        ``spread`` of its position at the block's first sample (its samples'
        farthest excursion plus :func:`_reach`), so a pair whose first-sample
        distance exceeds the threshold by both spreads cannot matter there;
        only the other blocks' intervals are bounded one by one.
        """
        T = positions.shape[0]
        z, w = _complex(positions), _complex(velocities)
        starts = np.arange(0, T - 1, _BLOCK)
        ends = np.minimum(starts + _BLOCK, T - 1)
        own = np.minimum(np.arange(T) // _BLOCK, starts.size - 1)
        spread = np.maximum.reduceat(np.abs(z - z[starts[own]]), starts, axis=0)
        spread = np.maximum(spread, np.abs(z[ends] - z[starts])) + np.maximum.reduceat(reach, starts, axis=0)
        i, j = pairs[:, 0], pairs[:, 1]
        first = np.abs(z[starts][:, i] - z[starts][:, j])
        self._sample_best(first.ravel(), k0 + np.repeat(starts, i.size), np.tile(i, starts.size), np.tile(j, starts.size))
        b, p = np.nonzero(first - spread[:, i] - spread[:, j] < self.threshold)
        chunk = max(1, _CHUNK_ENTRIES // _BLOCK)
        for c in range(0, b.size, chunk):
            bb, pb = b[c : c + chunk], p[c : c + chunk]
            k = (starts[bb][:, None] + np.arange(_BLOCK)).ravel()
            pp = np.repeat(pb, _BLOCK)
            inside = k < np.repeat(ends[bb], _BLOCK)
            k, pp = k[inside], pp[inside]
            ii, jj = i[pp], j[pp]
            z0, z1 = z[k, ii] - z[k, jj], z[k + 1, ii] - z[k + 1, jj]
            d0, d1 = np.abs(z0), np.abs(z1)
            self._sample_best(d0, k0 + k, ii, jj)
            self._sample_best(d1, k0 + k + 1, ii, jj)
            bound = np.maximum(d0, d1) - reach[k, ii] - reach[k, jj]
            near = np.flatnonzero(bound < self.threshold)
            if near.size:
                self._keep(k0, k[near], ii[near], jj[near], bound[near], z0[near], z1[near], w)

    def _sample_best(self, dist: _Array, k: _Index, i: _Index, j: _Index) -> None:
        """The closest saved sample so far, from the distances of pairs ``(i, j)`` at samples ``k``."""
        e = int(np.argmin(dist))
        if dist[e] ** 2 < self.best2:
            self.best2, self.best_at, self.best_pair = float(dist[e] ** 2), float(self.times[k[e]]), (int(i[e]), int(j[e]))

    def finish(self) -> None:
        """Solve every kept interval that may still matter (module doc): the exact minima and contacts.

        An interval with a sample in contact is a contact whatever its
        minimum, and its minimum matters only where it may fall below the
        closest sample of its run of such intervals (which bounds its
        contact episode's closest approach from above: sound, if more than
        needed where an episode holds several runs): its lower bound
        (``bound``, from the samples and :func:`_reach`) decides. The others
        keep their closer sample as their lowest point, which is exact at
        that sample and never below the episode's true closest approach, so
        each episode's and the run's minimum stay exact.
        """
        if not self.found:
            return
        k, i, j, bound, z0, z1, w0, w1 = (np.concatenate(parts) for parts in zip(*self.found))
        bound = np.maximum(bound, _hull_bound(z0, z1, w0 * self.h[k], w1 * self.h[k]))
        keep = bound < self.threshold  # the best sample of the whole run prunes the early stretches too
        k, i, j, bound, z0, z1, w0, w1 = (x[keep] for x in (k, i, j, bound, z0, z1, w0, w1))
        if not k.size:
            return
        h = self.h[k]
        pair = [np.stack([c.real, c.imag], axis=-1) for c in (z0, z1, w0, w1)]
        a = _hermite_coefficients(*pair, h)
        sq = _squared_length(a)
        near = np.minimum(np.abs(z0), np.abs(z1))
        where = (np.abs(z1) < np.abs(z0)).astype(float)  # the closer sample, unless solved
        inside = near < self.R
        # apart at both samples: could dip into contact, or below the best sample, between them
        solve = ~inside
        if np.any(inside):
            rows = np.flatnonzero(inside)
            order, starts, _ = _runs(k[rows], i[rows], j[rows])
            rows = rows[order]
            closest = np.repeat(np.minimum.reduceat(near[rows], starts), np.diff(np.append(starts, rows.size)))
            margin = 1e-9 * (1.0 + closest)  # the bound's rounding, generously
            solve[rows[bound[rows] < closest + margin]] = True
        solve = np.flatnonzero(solve)
        if solve.size:
            where[solve] = _interval_minima(sq[solve])[1]
        low = _separation_squared(a, where)
        m = int(np.argmin(low))
        if low[m] < self.best2:
            self.best2 = float(low[m])
            self.best_at = float(self.times[k[m]] + where[m] * h[m])
            self.best_pair = (int(i[m]), int(j[m]))
        hit = inside | (low < self.R**2)
        if np.any(hit):
            self.hits.append((k[hit], i[hit], j[hit], low[hit], where[hit], sq[hit]))


def _hull_bound(z0: NDArray[np.complex128], z1: NDArray[np.complex128], m0: NDArray[np.complex128],
                m1: NDArray[np.complex128]) -> _Array:  # fmt: skip
    """A lower bound of ``|d(s)|`` on each interval, from the separation's own Bezier control points.

    The cubic Hermite separation (ends ``z0``, ``z1``, tangents ``m0``,
    ``m1`` = velocity times step) is the Bezier curve of ``z0``,
    ``z0 + m0 / 3``, ``z1 - m1 / 3``, ``z1`` and lies in their convex hull;
    along the unit direction ``u`` of ``z0 + z1`` every point of the hull
    is at least the smallest control point's component, so ``|d(s)| >=
    min_k Re(P_k conj(u))``. Much tighter than the robots' separate reaches
    (:func:`_reach`) where a pair moves together or slides past. 0 where the
    direction is undefined; a hair below the bound for its rounding.
    """
    mid = z0 + z1
    size = np.abs(mid)
    u = np.where(size > 0.0, mid / np.where(size > 0.0, size, 1.0), 0.0)
    c0, c3 = (z0 * u.conj()).real, (z1 * u.conj()).real
    c1, c2 = c0 + (m0 * u.conj()).real / 3.0, c3 - (m1 * u.conj()).real / 3.0
    low = np.minimum(np.minimum(c0, c1), np.minimum(c2, c3))
    scale = np.abs(z0) + np.abs(z1) + np.abs(m0) + np.abs(m1)
    return np.maximum(low - 1e-12 * scale, 0.0)


def _runs(k: _Index, i: _Index, j: _Index) -> tuple[_Index, _Index, _Index]:
    """Runs of consecutive intervals ``k`` of one pair ``(i, j)``: the sorting order, and each run's first and last position in it."""
    order = np.lexsort((k, j, i))
    k, i, j = k[order], i[order], j[order]
    new = np.ones(k.size, dtype=bool)
    new[1:] = (i[1:] != i[:-1]) | (j[1:] != j[:-1]) | (k[1:] != k[:-1] + 1)
    starts = np.flatnonzero(new)
    return order, starts, np.append(starts[1:], k.size) - 1


def _contacts(
    times: _Array, hits: list[tuple[_Index, _Index, _Index, _Array, _Array, _Array]], R: float
) -> tuple[Contact, ...]:
    """Group the intervals in contact into episodes per pair, with exact start and end times."""
    # each interval belongs to exactly one stretch: no duplicates to remove
    k, i, j, low, where, sq = (np.concatenate([hh[c] for hh in hits]) for c in range(6))
    order, starts, ends = _runs(k, i, j)
    k, i, j, low, where, sq = k[order], i[order], j[order], low[order], where[order], sq[order]
    h = np.diff(times)
    n = starts.size
    # the entries and exits in one batch of roots: first crossing before each episode's
    # lowest point in its first interval, last one after it in its last interval
    s = _crossing(
        np.concatenate([sq[starts], sq[ends]]), R * R,
        np.concatenate([np.zeros(n), where[ends]]), np.concatenate([where[starts], np.ones(n)]),
        np.arange(2 * n) < n,
    )  # fmt: skip
    s_in, s_out = s[:n], s[n:]
    # each episode's lowest interval: the first of its lowest in (episode, low) order, as argmin picks
    lowest = np.lexsort((low, np.repeat(np.arange(n), ends - starts + 1)))[starts]
    start, end = times[k[starts]] + s_in * h[k[starts]], times[k[ends]] + s_out * h[k[ends]]
    at = times[k[lowest]] + where[lowest] * h[k[lowest]]
    rows = zip(i[starts].tolist(), j[starts].tolist(), start.tolist(), end.tolist(),
               np.sqrt(low[lowest]).tolist(), at.tolist())  # fmt: skip
    out = [_contact((a, b), t0, t1, c, c_at, R) for a, b, t0, t1, c, c_at in rows]
    out.sort(key=lambda c: (c.start, c.agents))
    return tuple(out)


def _contact(agents: tuple[int, int], start: float, end: float, closest: float, closest_at: float, R: float) -> Contact:
    """A :class:`Contact` of this module's own numbers, without the argument check.

    A crowded run has thousands of contacts, and checking each one's fields
    cost more than the search that found them; these are Python ints and
    finite floats by construction.
    """
    contact = object.__new__(Contact)
    for name, value in (("agents", agents), ("start", start), ("end", end), ("closest", closest),
                        ("closest_at", closest_at), ("contact_distance", R)):  # fmt: skip
        object.__setattr__(contact, name, value)  # a frozen dataclass's own way to set its fields
    return contact
