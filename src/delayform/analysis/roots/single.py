"""Characteristic roots of one quasi-polynomial or factor: in a rectangle, right of a line, the rightmost.

These are the roots for any retarded quasi-polynomial of the paper's eq. 5 and for
the factors of the paper's eq. 3; :mod:`delayform.analysis.roots.dominant` builds the
formation's dominant root and the dominant-root maps on them.

Method
------
1. **Global approximation.** The infinitesimal generator of the DDE
   ``dx/dt = A x + sum_k B_k x(t - h_k)`` is discretized by Chebyshev
   collocation on ``[-h_max, 0]`` (Breda, Maset and Vermiglio, "Pseudospectral
   differencing methods for characteristic roots of delay differential
   equations", SIAM J. Sci. Comput. 27, 2005). Its eigenvalues approximate
   the characteristic roots. A factor of the paper's eq. 3 is realized by its own
   subsystem (paper, eq. 8) (paper, eq. 9; a conjugate pair, the paper's eq. 10,
   splits into the complex second-order factor of ``lam`` and its mirror image,
   which halves the work); a general retarded quasi-polynomial of degree N is
   realized in companion form with the delays tau1, tau2, 2 tau1, 2 tau2 and
   tau1 + tau2 of the paper's eq. 5.
2. **Newton polishing** on the quasi-polynomial itself. A root is accepted
   when its *relative residual*
   ``|q(s)| / sum_k sum_i |g_k,i| |s|^i |e^{-h_k s}|`` (the modulus of q over
   the sum of the moduli of its monomial terms, i.e. a backward error) is at
   most :data:`RESIDUAL_TOL` = 1e-10.
3. **Certificate by the argument principle.** No root may be missed. The
   number of roots inside a contour is computed from the winding of q along
   it, with a *certified* sampling: between two samples ``s_j, s_j+1`` the
   change of q is bounded by a Lipschitz bound ``L_j |s_j+1 - s_j|`` built
   from the moduli of the coefficients, and the sampling is refined until
   ``min(|q(s_j)|, |q(s_j+1)|) > L_j |s_j+1 - s_j| / 2``, which keeps each
   arg increment below pi, so the unwrapped phase, hence the count, is exact
   (up to floating-point rounding in evaluating q). For a right half-plane
   ``Re s > c`` the contour is the line ``Re s = c`` closed at infinity: a
   Cauchy-type bound ``Omega`` gives ``|g1(s)| > sum_k |g_k(s) e^{-h_k s}|``
   for ``|Im s| >= Omega`` on the line (Rouche), so the tails contribute the
   arg change of g1 in closed form. When the count differs from the number of
   polished roots found, the discretization degree is raised and the step
   repeated; after :data:`MAX_DEGREE`, :class:`~delayform.errors.NotConvergedError`
   carries the roots found so far.

Guarantee
---------
:func:`roots_in` returns every root in the rectangle (the count inside the
rectangle is certified). :func:`rightmost_root` and everything built on it
(:func:`dominant_root`, :func:`dominant_root_map`, :func:`schedule_delays`)
return a root such that the certified number of roots in ``Re s > c`` equals
the number of polished roots found there, for a line ``c`` placed in a gap
left of the returned root: no root to its right is missed.

Conventions: coefficients in increasing powers of s; delays in seconds,
``tau1`` on positions and ``tau2`` on velocities (paper, eq. 1); the
centroid factor's persistent root s = 0 (paper, eq. 4) is deflated with
Maehly's correction and excluded from dominant roots (its other roots count).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, validated
from delayform.analysis.roots import delegated
from delayform.analysis.roots.family.solve import family_rightmost
from delayform.analysis.roots.generator import (
    _eigenvalues_at,
    _igd_seeds,
    _initial_degree,
    _largest_degree,
    _max_delay,
    _needed_degree,
    _require_degree,
    _require_resolvable,
    _root_scale,
)
from delayform.analysis.roots.problem import (
    MAX_DEGREE,
    RESIDUAL_TOL,
    Region,
    _cluster,
    _abs_poly,
    evaluate,
    _mirror_problem,
    _multiplicity,
    _polish,
    _Problem,
    UNIT_DELAYS,
    _problem,
    _problem_of_factor,
    _problem_of_quasi,
)
from delayform.analysis.roots.long_delay import is_long
from delayform.analysis.roots.rightmost import _BATCH_SEEDS, _certify, _pick_rightmost, _solve_rightmost
from delayform.analysis.roots.argument_principle import _count_right_single, count_in_region
from delayform.analysis.roots.multiple import distinct_roots
from delayform.characteristic import CharacteristicFactor, TwoDelayQuasiPolynomial
from delayform.errors import InputError, NotConvergedError, QuasiPolynomialError
from delayform.quasipolynomial import QuasiPolynomial

__all__ = ["RESIDUAL_TOL", "roots_in", "rightmost_root", "count_roots_right_of", "relative_residual",
           "delay_reach", "require_reach"]


def relative_residual(
    qp: QuasiPolynomial | TwoDelayQuasiPolynomial, s: ArrayLike, *delays: ArrayLike
) -> NDArray[np.float64]:
    """|q(s)| over the sum of the moduli of its monomial terms (a backward error).

    This is the "relative" of the acceptance test ``<= RESIDUAL_TOL`` for
    every root this module returns.

    Parameters
    ----------
    qp
        A :class:`~delayform.quasipolynomial.QuasiPolynomial` or a
        quasi-polynomial of the paper's eq. 5.
    s
        Complex point(s) at which q is evaluated.
    *delays
        The delays ``tau1, ..., taum`` (``tau1, tau2`` on positions and on
        velocities for the paper's eq. 5); broadcast with ``s``. Not validated
        for the paper's eq. 5.

    Returns
    -------
    ndarray of float
        ``|q(s)| / sum_k sum_i |g_k,i| |s|^i |e^{-h_k s}|`` in the broadcast
        shape of s and the delays.

    >>> q = TwoDelayQuasiPolynomial([-1.0, 1.0])
    >>> float(relative_residual(q, 1.0, 0.0, 0.0))
    0.0
    """
    s_arr = np.asarray(s, dtype=np.complex128)
    if isinstance(qp, QuasiPolynomial):
        q = qp.evaluate(s_arr, *delays)
        mag = np.zeros(q.shape)
        for k, c in qp.terms.items():
            hk = sum((kk * np.asarray(t, dtype=float) for kk, t in zip(k, delays, strict=True) if kk),
                     start=np.zeros(()))  # fmt: skip
            mag = mag + _abs_poly(c, np.abs(s_arr)) * np.exp(-hk * s_arr.real)
        return np.abs(q) / mag
    if len(delays) != 2:
        raise InputError(f"relative_residual(qp, s, tau1, tau2): got {len(delays)} delay(s)")
    q, _, mag = evaluate(
        qp.terms(), s_arr, np.asarray(delays[0], dtype=float), np.asarray(delays[1], dtype=float)
    )
    return np.abs(q) / mag


# =====================================================================
def _check_reach(prob: _Problem, t1: float, t2: float) -> None:
    """Refuse, in one line, delays whose discretization exceeds the machine's memory or time budget.

    For the paths that discretize at every pair (maps, gain design): there is
    no fixed reach, the degree grows with the delay, and only a problem too
    large for the machine is refused (:class:`~delayform.errors.DelayError`).
    The single-pair finder checks its own budget only after the root chains.
    """
    h = max([a * t1 + b * t2 for _, a, b in prob.delayed] + [0.0])
    N = _needed_degree(h, _root_scale(prob))
    if N > MAX_DEGREE:
        _require_degree(prob, N, h)


def require_reach(factor: CharacteristicFactor, tau1: float, tau2: float) -> None:
    """Refuse delays whose discretization of this factor exceeds the machine's memory or time budget.

    The rule of the maps and of gain design, which discretize at every pair
    (:func:`delay_reach` gives the square of delays it accepts).

    Parameters
    ----------
    factor
        A factor of the paper's eq. 3 at its gains.
    tau1, tau2
        The largest delays the computation will meet.

    Raises
    ------
    DelayError
        Naming the delays and what to change.
    """
    _check_reach(_problem_of_factor(factor), tau1, tau2)


# =====================================================================
# the arguments: a quasi-polynomial (or factor), its delays, and what follows them
# =====================================================================
@dataclass(frozen=True)
class _Call:
    """A root function's arguments, checked: the problem, where the solvers evaluate it, and the rest."""

    prob: _Problem
    t1: float
    t2: float
    where: str
    rest: tuple[object, ...]


def _call(qp: object, args: tuple[object, ...], after: tuple[str, ...], func: str) -> _Call:
    """Split ``args`` into the delays and the ``after`` arguments, and build the problem.

    A :class:`~delayform.quasipolynomial.QuasiPolynomial` takes its m delays
    (``tau1, ..., taum``); a TwoDelayQuasiPolynomial or a factor takes
    ``tau1, tau2``. Messages name what the user gave.
    """
    if isinstance(qp, QuasiPolynomial):
        m = qp.n_delays
        names = tuple(f"tau{i + 1}" for i in range(m))
    elif isinstance(qp, (TwoDelayQuasiPolynomial, CharacteristicFactor)):
        m, names = 2, ("tau1", "tau2")
    else:
        raise InputError(
            f"{func} expects a QuasiPolynomial, TwoDelayQuasiPolynomial or CharacteristicFactor, "
            f"got {type(qp).__name__}"
        )
    if len(args) != m + len(after):
        wanted = ", ".join(("qp",) + names + after)
        raise InputError(f"{func}({wanted}): got {len(args)} argument(s) after qp, expected {m + len(after)}")
    taus = tuple(check_delay(name, v) for name, v in zip(names, args[:m], strict=True))
    if getattr(qp, "degree", None) == 0:  # retarded of degree 0: no delayed term can remain, a non-zero constant
        raise QuasiPolynomialError(f"{func}: the quasi-polynomial is a non-zero constant, which has no roots")
    where = f"({', '.join(names)}) = ({', '.join(f'{v:g}' for v in taus)})"
    if isinstance(qp, QuasiPolynomial):
        t1, t2 = UNIT_DELAYS
        return _Call(_problem_of_quasi(qp, taus), t1, t2, where, args[m:])
    return _Call(_problem(qp), taus[0], taus[1], where, args[m:])

def _iterable(value: object) -> tuple[object, ...]:
    try:
        return tuple(value)  # type: ignore[call-overload]
    except TypeError:
        return (value,)


def _box_reach(prob: _Problem) -> float:
    """Largest X such that :func:`_check_reach` accepts every pair in [0, X] x [0, X]."""
    widest = max([a + b for _, a, b in prob.delayed] + [0])  # h = (a + b) X at tau1 = tau2 = X
    if widest == 0:
        return math.inf
    # _needed_degree(h, scale) = ceil(1.2 scale h + 10) must stay within the machine's largest degree
    return (_largest_degree(prob) - 10) / (1.2 * _root_scale(prob) * widest)


@validated()
def delay_reach(fs: tuple[CharacteristicFactor, ...]) -> float:
    """The delays the discretization handles for these factors: every pair in [0, X]^2, X returned.

    The one source of the discretization's reach: :func:`_check_reach` (the
    dominant-root maps, gain design) refuses with the same rule, so a table
    built on this (the explorer's) can never allow a delay those then refuse.
    The single-pair finder (:func:`rightmost_root`, ``dominant_root``)
    reaches further: at long delays it solves on the root chains
    (:mod:`~delayform.analysis.roots.long_delay`). ``math.inf`` when there is no limit.

    Parameters
    ----------
    fs
        The factors of the paper's eq. 3 of a team at its gains.

    Raises
    ------
    InputError
        When ``fs`` is not a sequence of factors.
    """
    if isinstance(fs, (str, bytes)) or not all(isinstance(f, CharacteristicFactor) for f in _iterable(fs)):
        raise InputError("delay_reach: expected the factors of a team (delayform.characteristic.factors)")
    return min((_box_reach(_problem_of_factor(f)) for f in tuple(fs)), default=math.inf)




# =====================================================================
# public: roots of one quasi-polynomial
# =====================================================================
def _check_region(region: object) -> Region:
    try:
        vals = tuple(float(v) for v in region)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise InputError("region must be (re_min, re_max, im_min, im_max)") from exc
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise InputError("region must be four finite numbers (re_min, re_max, im_min, im_max)")
    if not (vals[0] < vals[1] and vals[2] < vals[3]):
        raise InputError(f"region must have re_min < re_max and im_min < im_max, got {vals}")
    return vals  # type: ignore[return-value]


def _check_abscissa(c: object) -> float:
    if isinstance(c, bool) or not isinstance(c, (int, float, np.integer, np.floating)) or not math.isfinite(c):
        raise InputError(f"c must be a finite real number (the line Re s = c), got {c!r}")
    return float(c)


def _with_mirror(prob: _Problem, roots: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Roots of q_lam and their conjugates, the roots of q_conj(lam) (a pair factor)."""
    if not prob.mirror:
        return roots
    return np.concatenate([roots, np.conj(roots)])


@validated()
def roots_in(
    qp: QuasiPolynomial | TwoDelayQuasiPolynomial | CharacteristicFactor, *delays_and_region: object
) -> NDArray[np.complex128]:
    """All characteristic roots in a rectangle of the complex plane.

    Parameters
    ----------
    qp
        A :class:`~delayform.quasipolynomial.QuasiPolynomial`, a
        quasi-polynomial of the paper's eq. 5, or a factor of the paper's eq. 3
        (for the centroid factor (paper, eq. 4) the persistent root 0 is
        *included*: this is the plain root set of q). A neutral one is
        solved by :func:`delayform.analysis.neutral.neutral_roots_in`.
    *delays_and_region
        The delays ``tau1, ..., taum`` (m = ``qp.n_delays``; two for the
        paper's forms), non-negative, then the rectangle
        ``region = (re_min, re_max, im_min, im_max)``.

    Returns
    -------
    ndarray of complex
        The roots in the rectangle, a multiple root repeated by its
        multiplicity (as numpy.roots does; its copies are one point,
        accurate to about eps^(1/m) for multiplicity m, see
        :mod:`~delayform.analysis.roots.multiple`), sorted by decreasing real part,
        each with relative residual <= RESIDUAL_TOL (:func:`relative_residual`).
        The count, with multiplicity, is certified by the argument principle
        on the rectangle's boundary.

    Raises
    ------
    ResourceLimitError
        When the rectangle reaches so far from the origin that the roots
        there cannot be resolved (|s| above about 2 MAX_DEGREE / largest delay).
    NotConvergedError
        When the count is not reached up to :data:`MAX_DEGREE`, or roots lie
        on the boundary of the rectangle and of slightly larger ones (a root
        on the boundary is otherwise reported, the rectangle taken closed);
        ``.partial`` holds the roots found.

    Examples
    --------
    >>> from delayform.characteristic import TwoDelayQuasiPolynomial
    >>> q = TwoDelayQuasiPolynomial([2.0, 3.0, 1.0])  # (s + 1)(s + 2)
    >>> roots_in(q, 0.0, 0.0, (-3, 0, -1, 1)).real.round(12)
    array([-1., -2.])
    """
    if _neutral(qp):  # solved by analysis/neutral (argument-principle subdivision), which sits above roots
        r, m = delegated.neutral().roots_in(qp, *delays_and_region[:-1], region=delays_and_region[-1])  # type: ignore[arg-type]
        return np.repeat(r, m)
    call = _call(qp, delays_and_region, ("region",), "roots_in")
    prob, t1, t2 = call.prob, call.t1, call.t2
    region = asked = _check_region(call.rest[0])
    base = prob if not prob.deflate_zero else replace(prob, deflate_zero=False)
    x0, x1, y0, y1 = region
    hmax = _max_delay(base, t1, t2)
    radius = max(abs(complex(x, y)) for x in (x0, x1) for y in (y0, y1))
    _require_resolvable(region, hmax)
    # when mirroring, roots of the lam-factor in the mirrored region are needed too
    yy = max(abs(y0), abs(y1))
    count_regions = [region] if not base.mirror else [(x0, x1, -yy, yy)]
    expected = count_in_region(base.terms, t1, t2, count_regions[0])
    # a root on the boundary (e.g. a real root on Im s = 0): count on a slightly larger
    # rectangle and report the roots of the closed one, boundary roots included
    size = max(abs(v) for v in region) + 1.0
    for nudge in (1e-9, 1e-7, 1e-5):
        if expected is not None:
            break
        d = nudge * size
        rx0, rx1, ry0, ry1 = count_regions[0]
        count_regions = [(rx0 - d, rx1 + d, ry0 - d, ry1 + d)]
        region = (x0 - d, x1 + d, y0 - d, y1 + d)
        expected = count_in_region(base.terms, t1, t2, count_regions[0])
    if expected is None:
        raise NotConvergedError(
            f"roots lie on (or within rounding of) the boundary of the rectangle {asked} "
            "and of every slightly larger rectangle tried; move the rectangle's edges",
            partial=np.zeros(0, dtype=np.complex128),
        )
    N = _initial_degree(hmax, max(radius, _root_scale(base)))
    a1, a2 = np.asarray(t1), np.asarray(t2)
    found = np.zeros(0, dtype=np.complex128)
    while True:
        eig = _eigenvalues_at(base, N, hmax, float(t1), float(t2))
        if prob.deflate_zero:
            roots, mult = _roots_beside_zero(prob, base, eig, t1, t2)
        else:
            polished, ok = _polish(base, eig, a1, a2)
            roots, mult = distinct_roots(base, polished[ok], t1, t2)
        rx0, rx1, ry0, ry1 = count_regions[0]
        inside = (roots.real > rx0) & (roots.real < rx1) & (roots.imag > ry0) & (roots.imag < ry1)
        found = np.repeat(roots[inside], np.maximum(mult[inside], 1))
        if found.size == expected:
            break
        if hmax == 0.0 or N >= MAX_DEGREE:
            raise NotConvergedError(
                f"found {found.size} of the {expected} characteristic roots in the rectangle {asked} "
                f"at {call.where}; choose a smaller rectangle",
                partial=_in_region(_with_mirror(base, found), region),
            )
        N = min(MAX_DEGREE, 2 * N)
    return _in_region(_with_mirror(base, found), region)


def _roots_beside_zero(
    prob: _Problem, base: _Problem, eig: NDArray[np.complex128], t1: float, t2: float
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Roots and multiplicities of the centroid factor (paper, eq. 4), its root 0 included.

    Polished with the persistent zero deflated, so a tiny delay's genuine
    root next to 0 (about -P tau1 / (1 + D tau2)) is resolved
    (:func:`_deflated_zero`) instead of being mistaken for a double root at 0;
    0 itself is simple, or double when the deflated polish also ends there
    (tau1 = 0, the centroid's drift).
    """
    a1, a2 = np.asarray(t1), np.asarray(t2)
    polished, ok = _polish(prob, eig, a1, a2)
    roots = _cluster(polished[ok])
    zero_is_double = bool(np.any(roots == 0.0))
    mult = _multiplicity(base, roots, t1, t2)
    near = np.abs(roots) < 1e-5  # q(s)/s is about linear there: its roots are simple
    mult = np.where(near, 1, mult)
    roots, mult = roots[roots != 0.0], mult[roots != 0.0]
    return np.append(roots, 0.0), np.append(mult, 2 if zero_is_double else 1)


def _in_region(roots: NDArray[np.complex128], region: Region) -> NDArray[np.complex128]:
    x0, x1, y0, y1 = region
    keep = (roots.real > x0) & (roots.real < x1) & (roots.imag > y0) & (roots.imag < y1)
    out = roots[keep]
    return out[np.lexsort((-out.imag, -out.real))]


@validated()
def count_roots_right_of(
    qp: QuasiPolynomial | TwoDelayQuasiPolynomial | CharacteristicFactor, *delays_and_c: object
) -> int:
    """Certified number of roots with Re s > c (multiplicity counted, persistent zero included).

    The argument principle along Re s = c closed at infinity (module
    docstring). Raises NotConvergedError when a root lies on the line.

    Parameters
    ----------
    qp
        A retarded :class:`~delayform.quasipolynomial.QuasiPolynomial`, a
        quasi-polynomial of the paper's eq. 5 or a factor of the paper's eq. 3 (a
        conjugate-pair factor counts the roots of lam and of conj(lam)). The
        centroid factor's persistent root s = 0 (paper, eq. 4) is not
        deflated here: it counts when ``c < 0``.
    *delays_and_c
        The delays ``tau1, ..., taum`` (two, on positions and on velocities,
        for the paper's forms), non-negative, then ``c``, the abscissa of
        the vertical line Re s = c (any real number).

    Returns
    -------
    int
        The number of roots strictly right of the line.

    Raises
    ------
    DelayError
        For a negative or non-finite delay.
    InputError
        When qp is neither a quasi-polynomial nor a factor.
    NotConvergedError
        When a root lies on (or within rounding of) the line.
    """
    if _neutral(qp):  # solved by analysis/neutral (only right of the essential spectrum)
        return delegated.neutral().count_right_of(qp, *delays_and_c[:-1], c=_check_abscissa(delays_and_c[-1]))  # type: ignore[arg-type]
    call = _call(qp, delays_and_c, ("c",), "count_roots_right_of")
    prob, t1, t2 = call.prob, call.t1, call.t2
    c = _check_abscissa(call.rest[0])
    base = replace(prob, deflate_zero=False)
    n = _count_right_single(base, t1, t2, c)
    if n is None:
        raise NotConvergedError(f"a root lies on (or within rounding of) the line Re s = {c:g} at {call.where}")
    if base.mirror:
        n += _count_right_single(_mirror_problem(base), t1, t2, c) or 0
    return n


@validated()
def rightmost_root(qp: QuasiPolynomial | TwoDelayQuasiPolynomial | CharacteristicFactor, *delays: float) -> complex:
    """The rightmost characteristic root (for a factor, the centroid's zero excluded).

    Parameters
    ----------
    qp
        A retarded :class:`~delayform.quasipolynomial.QuasiPolynomial`, a
        quasi-polynomial of the paper's eq. 5 or a factor of the paper's eq. 3. For
        the centroid factor (paper, eq. 4) the persistent root s = 0 is
        deflated; its other roots count (a second root at 0, as at
        tau1 = 0, is returned).
    *delays
        The delays ``tau1, ..., taum`` (two for the paper's forms), non-negative.
        There is no limit on their length: long delays get a finer
        discretization (module docstring), refused only beyond the
        machine's memory or time budget (ResourceLimitError).

    Returns
    -------
    complex
        The root with the largest real part (of a conjugate pair, the one
        with Im >= 0), relative residual <= RESIDUAL_TOL, certified as in the
        module docstring.

    Examples
    --------
    >>> from delayform.characteristic import TwoDelayQuasiPolynomial
    >>> q = TwoDelayQuasiPolynomial([1.0, 1.0], [1.0])  # s + 1 + e^{-s}
    >>> s = rightmost_root(q, 1.0, 0.0)
    >>> round(s.real, 6), round(s.imag, 6)
    (-0.605021, 1.788188)
    """
    if _neutral(qp):  # solved by analysis/neutral (EssentialSpectrumError when none lies right of it)
        return delegated.neutral().rightmost_root(qp, *delays)  # type: ignore[arg-type]
    call = _call(qp, delays, (), "rightmost_root")
    t1, t2 = call.t1, call.t2
    if isinstance(qp, CharacteristicFactor):  # a factor of eq. factorized: the vectorized family path
        return complex(family_rightmost((qp,), float(qp.P), float(qp.D), t1, t2)[0])
    return _rightmost(call.prob, t1, t2, where=call.where)


def _neutral(qp: object) -> bool:
    """A neutral quasi-polynomial: solved by :mod:`delayform.analysis.neutral`."""
    if isinstance(qp, QuasiPolynomial):
        return qp.is_neutral
    return isinstance(qp, TwoDelayQuasiPolynomial) and not qp.is_retarded


def _polynomial_seeds(prob: _Problem) -> NDArray[np.complex128]:
    """Roots of the principal and of the delay-free polynomial (no term delayed, every term undelayed)."""
    free = np.zeros(prob.terms[0][0].size, dtype=np.complex128)
    for c, _, _ in prob.terms:
        free[: c.size] += c
    seeds = [np.roots(c[::-1]) for c in (prob.terms[0][0], free) if c.size > 1 and c[-1] != 0.0]
    out = np.concatenate(seeds) if seeds else np.zeros(1, dtype=np.complex128)
    out = out.real + 1j * np.abs(out.imag)  # a real root's rounding below the axis would be dropped
    return out + 1e-3 * (1.0 + np.abs(out)) * (out == 0.0)  # Newton cannot leave an exact 0 of q'


def _rightmost(prob: _Problem, t1: float, t2: float, *, where: str | None = None) -> complex:
    if is_long(_max_delay(prob, t1, t2), _root_scale(prob)):
        # long delays: the root chains first, then (budget checked up front) the discretization
        return _pick_rightmost(prob, _solve_rightmost(prob, t1, t2, where=where).roots)
    a1, a2 = np.array([t1]), np.array([t2])
    if prob.scale > 0.0:
        # roots far right of the others see e^{-h s} small: the polynomials' roots seed them without
        # any discretization (long delays, roots of the principal term); the certificate decides
        root, certified, _ = _certify(prob, a1, a2, _polynomial_seeds(prob)[None, :])
        if certified[0]:
            return _pick_rightmost(prob, root)
    # fast path: the map's low-degree seeds; the certificate decides, else the robust path
    root, certified, _ = _certify(prob, a1, a2, _igd_seeds(prob, a1, a2, scale=1.0, k=_BATCH_SEEDS))
    if certified[0]:
        return _pick_rightmost(prob, root)
    res = _solve_rightmost(prob, t1, t2, where=where)
    return _pick_rightmost(prob, res.roots)
