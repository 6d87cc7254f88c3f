"""Factors of a two-delay quasi-polynomial in one monomial ``w = z1^a z2^b``, split off exactly.

Why
---
If ``q(s, z1, z2) = F(s, w) G(s, z1, z2)`` with ``w = z1^a z2^b``, then at a
crossing frequency of F every point of a whole line ``a theta1 + b theta2 =
const`` of the torus solves q. The two-delay sweep eliminates a phase at each
frequency: its eliminant vanishes identically at those isolated frequencies
and nowhere else, so F's crossings (straight lines ``a tau1 + b tau2 = T`` in
the delay plane) would be invisible to it. Split off, F is a one-delay
problem in ``T = a tau1 + b tau2`` solved exactly, G goes through the sweep,
and the unstable-root counts of the parts add (the roots of q are those of F
and of G, with multiplicity).

How the factor is found
-----------------------
With integers (c, d), ``a d - b c = 1``, the monomial change ``z1 = x^d y^-b``,
``z2 = x^-c y^a`` is invertible over the Laurent monomials and makes
``w = x``: a term ``z1^k1 z2^k2`` becomes ``x^(d k1 - c k2) y^(a k2 - b k1)``.
Grouping by the power of y, ``q = sum_k y^k Q_k(s, x)``, and a factor in
``(s, x)`` alone divides every ``Q_k``: it is their greatest common divisor F.

The gcd is computed by linear algebra, not by roots: cofactors
``G_k = Q_k / F`` solve the linear system ``Q_r G_k - Q_k G_r = 0`` (r a
reference group) with each ``G_k`` confined to its bidegree box (degrees in s
and in x of ``Q_k`` less those of F). Its null space is
``{G*_k t}`` for polynomials t of bidegree ``deg gcd - deg F``, so it is
non-trivial exactly when F's bidegree is at most the gcd's, and one-dimensional
at equality: the largest x-degree, then the largest s-degree, with a null
space gives the gcd's bidegree, its null vector the cofactors, and F follows by
least squares from ``Q_k = F G_k``. The part of F in s alone (a factor of q
that no delay moves) is handed back to G, and the split is accepted only when
``F G`` reproduces every coefficient of q to 1e-10 of the moduli that make its
term (the convolution of ``|F|`` and ``|G|``, largest over the term's powers of s); a factor seen but not reproduced is
refused, never guessed. A squared factor is found twice (the gcd of a
``Q_k`` holding ``F^2`` is split once, then its cofactor again).

Candidate directions (a, b): a factor's Newton polygon is a segment from
(0, 0) to ``m (a, b)``, an edge direction of q's Newton polygon (a Minkowski
sum), so (a, b) is the primitive difference of two exponent vectors of q, with
``a, b >= 0`` since F keeps the principal term.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.errors import QuasiPolynomialError
from delayform.quasipolynomial import QuasiPolynomial

__all__ = ["split_monomial_factors", "factor_direction", "MonomialSplit"]

#: smallest over largest singular value below which the cofactor system has a null space
_NULL_TOL = 1e-9
#: F G must reproduce each coefficient of q to this fraction of the moduli that make its term
_REPRODUCE_TOL = 1e-10
#: coefficients of a factor below this fraction of its largest are rounding noise (exactly zero)
_NOISE = 1e-13

Terms = dict[tuple[int, int], NDArray[np.complex128]]


@dataclass(frozen=True)
class MonomialSplit:
    """``q = F_1 ... F_r G``: each factor in one monomial, and the rest.

    Attributes
    ----------
    factors
        The factors ``F_i(s, z1^a z2^b)``, each a one-delay problem in ``a tau1 + b tau2``.
    directions
        ``(a, b)`` of each factor.
    rest
        G, without a factor in one monomial.
    """

    factors: tuple[QuasiPolynomial, ...]
    directions: tuple[tuple[int, int], ...]
    rest: QuasiPolynomial

    @property
    def pieces(self) -> tuple[QuasiPolynomial, ...]:
        """The factors, then the rest: their product is q."""
        return (*self.factors, self.rest)


def split_monomial_factors(qp: QuasiPolynomial) -> MonomialSplit:
    """Split every factor ``F(s, z1^a z2^b)`` off a two-delay quasi-polynomial (module docstring).

    Parameters
    ----------
    qp
        A quasi-polynomial in two delays.

    Returns
    -------
    MonomialSplit
        No factors when q has none (``rest`` is q itself), and none when every
        delayed term of q is already a power of one monomial (q is one line family).

    Raises
    ------
    QuasiPolynomialError
        When q has two delays' worth of keys missing, or a factor in one monomial
        is detected but cannot be split off to 1e-10 of q's coefficients.
    """
    if qp.n_delays != 2:
        raise QuasiPolynomialError(f"a split in one monomial needs two delays; this qp has {qp.n_delays}")
    factors: list[QuasiPolynomial] = []
    directions: list[tuple[int, int]] = []
    rest: Terms = {(int(k[0]), int(k[1])): np.asarray(c, complex) for k, c in qp.terms.items()}
    while True:
        found = _split_once(rest, real=qp.is_real, retarded=qp.is_retarded)
        if found is None:
            break
        f, g, direction = found
        factors.append(QuasiPolynomial(f))
        directions.append(direction)
        rest = g
    return MonomialSplit(tuple(factors), tuple(directions), QuasiPolynomial(rest) if factors else qp)


def factor_direction(terms: Terms) -> tuple[int, int] | None:
    """(a, b) of a factor ``F(s, z1^a z2^b)`` of q (not q itself in one monomial), or None.

    Parameters
    ----------
    terms
        ``{(k1, k2): coefficients ascending in s}``, the principal term (0, 0) among them.
    """
    terms = {k: np.asarray(c, complex) for k, c in terms.items() if np.any(np.asarray(c) != 0)}
    terms = _negligible_dropped(terms)  # a term at rounding level of q's largest shows no factor
    if _one_line(terms):
        return None
    for a, b in _directions(terms):
        groups, _ = _groups(terms, a, b)
        if len(groups) > 1 and _has_factor(list(_scaled(groups, terms[(0, 0)])[0].values()), 0, 1):
            return a, b
    return None


# ----------------------------------------------------------------------------- the split
def _split_once(
    terms: Terms, *, real: bool, retarded: bool
) -> tuple[Terms, Terms, tuple[int, int]] | None:
    """(F, G, (a, b)) for the first direction with a factor, or None."""
    given = terms
    # coefficients at rounding level of q's largest are zeros here, as in F and G below: a group
    # scaled up from 1e-308 would otherwise show a common factor that is only noise
    terms = _negligible_dropped(terms)
    direction = factor_direction(terms)
    if direction is None:
        return None
    a, b = direction
    c, d = bezout(a, b)
    groups, low = _groups(terms, a, b)
    scaled, rho, norms = _scaled(groups, terms[(0, 0)])
    keys = sorted(scaled)
    polys = [scaled[k] for k in keys]
    f, _ = _gcd(polys, in_x=True)  # type: ignore[misc]  # a factor was seen in this direction
    f, _ = _strip_content(f)
    f, _ = _radical(f)  # one copy of each factor of F; the others stay in G (split next round)
    # G_k = Q_k / F by one division each (least squares in the exact box): no product of three
    # computed factors, whose rounding would leave noise in coefficients that are exactly zero
    cof = [np.linalg.lstsq(_conv_matrix(f, (p.shape[0] - f.shape[0] + 1, p.shape[1] - f.shape[1] + 1)),
                           p.ravel(), rcond=None)[0].reshape(p.shape[0] - f.shape[0] + 1, -1) for p in polys]
    # back to s (mu = s / rho) and the groups' scales; F monic in its principal polynomial
    f = f / rho ** np.arange(f.shape[0])[:, None]
    lead = f[-1, 0]  # the principal polynomial has F's full degree in s (that of q's is the sum)
    f = f / lead
    f_terms: Terms = {(j * a, j * b): f[:, j] for j in range(f.shape[1])}
    g_terms: Terms = {}
    for k, g in zip(keys, cof, strict=True):
        g = g * (norms[k] * lead) / rho ** np.arange(g.shape[0])[:, None]
        for j in range(g.shape[1]):
            p = j + low[k]
            key = (a * p + c * k, b * p + d * k)  # the inverse of the monomial change
            if min(key) < 0:
                raise QuasiPolynomialError(_REFUSED.format(a=a, b=b, why="a cofactor with a negative power"))
            g_terms[key] = g[:, j]
    f_terms = _cleaned(f_terms, real=real, retarded=retarded)
    g_terms = _cleaned(g_terms, real=real, retarded=retarded)
    err = _reproduction_error(given, f_terms, g_terms)
    if not err <= _REPRODUCE_TOL:
        raise QuasiPolynomialError(_REFUSED.format(a=a, b=b, why=f"F G reproduces q only to {err:.1e}"))
    return f_terms, g_terms, (a, b)


_REFUSED = ("the quasi-polynomial has a factor in z1^{a} z2^{b} alone (a function of {a} tau1 + {b} tau2), "
            "whose crossings are whole lines, but it could not be split off exactly ({why}): map its factors "
            "separately (their unstable-root counts add)")


def _one_line(terms: Terms) -> bool:
    """True when every delayed term is a power of one monomial (q is itself one line family)."""
    keys = [k for k in terms if k != (0, 0)]
    if not keys:
        return True
    a0, b0 = keys[0]
    return all(k1 * b0 == k2 * a0 for k1, k2 in keys)


def _directions(terms: Terms) -> list[tuple[int, int]]:
    """Primitive (a, b), a, b >= 0, of the differences of two exponent vectors (module docstring)."""
    keys = sorted(terms)
    out: set[tuple[int, int]] = set()
    for i, (a1, b1) in enumerate(keys):
        for a2, b2 in keys[i + 1 :]:
            da, db = a2 - a1, b2 - b1
            g = int(np.gcd(da, db))
            if g and da * db >= 0:
                out.add((abs(da) // g, abs(db) // g))
    return sorted(out)


def bezout(a: int, b: int) -> tuple[int, int]:
    """(c, d) with ``a d - b c = 1`` for coprime non-negative a, b (extended Euclid)."""
    r0, r1, x0, x1, y0, y1 = a, b, 1, 0, 0, 1
    while r1:
        k = r0 // r1
        r0, r1, x0, x1, y0, y1 = r1, r0 - k * r1, x1, x0 - k * x1, y1, y0 - k * y1
    # x0 a + y0 b = r0 = 1, so d = x0 and c = -y0
    return -y0, x0


def _groups(terms: Terms, a: int, b: int) -> tuple[dict[int, NDArray[np.complex128]], dict[int, int]]:
    """``Q_k[i, j]``: coefficient of ``s^i x^(j + low_k)`` in the group of ``y^k``, and ``low_k``."""
    c, d = bezout(a, b)
    by_k: dict[int, dict[int, NDArray[np.complex128]]] = {}
    for (k1, k2), coef in terms.items():
        by_k.setdefault(a * k2 - b * k1, {})[d * k1 - c * k2] = coef
    groups: dict[int, NDArray[np.complex128]] = {}
    low: dict[int, int] = {}
    for k, row in by_k.items():
        lo, hi = min(row), max(row)
        n = max(v.size for v in row.values())
        arr = np.zeros((n, hi - lo + 1), complex)
        for p, v in row.items():
            arr[: v.size, p - lo] = v
        groups[k], low[k] = arr, lo
    return groups, low


def _scaled(
    groups: dict[int, NDArray[np.complex128]], principal: NDArray[np.complex128]
) -> tuple[dict[int, NDArray[np.complex128]], float, dict[int, float]]:
    """Groups in ``mu = s / rho`` (rho balances the principal polynomial), each of unit largest coefficient."""
    nz = np.flatnonzero(principal)
    lo, hi = nz[0], nz[-1]
    rho = float((abs(principal[lo]) / abs(principal[hi])) ** (1.0 / (hi - lo))) if hi > lo else 1.0
    out, norms = {}, {}
    for k, g in groups.items():
        g = g * rho ** np.arange(g.shape[0])[:, None]
        norms[k] = float(np.max(np.abs(g)))
        out[k] = g.real / norms[k] + 1j * (g.imag / norms[k])  # no 1 / norm: it overflows for a subnormal term
    return out, rho, norms


# ----------------------------------------------------------------------------- linear algebra
def _conv_matrix(p: NDArray[np.complex128], shape: tuple[int, int]) -> NDArray[np.complex128]:
    """M with ``M @ g.ravel() == conv2(p, g).ravel()`` for g of the given shape."""
    out_shape = (p.shape[0] + shape[0] - 1, p.shape[1] + shape[1] - 1)
    M = np.zeros((out_shape[0] * out_shape[1], shape[0] * shape[1]), complex)
    for i in range(shape[0]):
        for j in range(shape[1]):
            block = np.zeros(out_shape, complex)
            block[i : i + p.shape[0], j : j + p.shape[1]] = p
            M[:, i * shape[1] + j] = block.ravel()
    return M


def _conv2(p: NDArray[np.complex128], g: NDArray[np.complex128]) -> NDArray[np.complex128]:
    return (_conv_matrix(p, g.shape) @ g.ravel()).reshape(p.shape[0] + g.shape[0] - 1, p.shape[1] + g.shape[1] - 1)


def _cofactor_system(polys: list[NDArray[np.complex128]], n: int, m: int) -> tuple[NDArray, list[tuple[int, int]]] | None:
    """The matrix of ``Q_r G_k - Q_k G_r = 0`` over the cofactor boxes, or None when a box is empty."""
    shapes = [(p.shape[0] - n, p.shape[1] - m) for p in polys]
    if min(min(sh) for sh in shapes) < 1:
        return None
    offsets = np.cumsum([0] + [sh[0] * sh[1] for sh in shapes])
    r = int(np.argmin([sh[0] * sh[1] for sh in shapes]))  # the smallest box as the reference
    rows = []
    for k in range(len(polys)):
        if k == r:
            continue
        a = _conv_matrix(polys[r], shapes[k])
        b = _conv_matrix(polys[k], shapes[r])
        block = np.zeros((a.shape[0], offsets[-1]), complex)
        block[:, offsets[k] : offsets[k + 1]] = a
        block[:, offsets[r] : offsets[r + 1]] -= b
        rows.append(block)
    return np.vstack(rows), shapes


def _has_factor(polys: list[NDArray[np.complex128]], n: int, m: int) -> bool:
    """True when the polys share a factor of bidegree (n, m) in (s, x) or more (module docstring)."""
    system = _cofactor_system(polys, n, m)
    if system is None:
        return False
    M, _ = system
    if M.shape[0] < M.shape[1]:
        return True
    sv = np.linalg.svd(M, compute_uv=False)
    return bool(sv[-1] <= _NULL_TOL * sv[0])


def _cofactors(polys: list[NDArray[np.complex128]], n: int, m: int) -> list[NDArray[np.complex128]]:
    """The cofactors ``Q_k / F`` (up to one scalar) from the null vector of the cofactor system."""
    system = _cofactor_system(polys, n, m)
    assert system is not None  # a null space was found at this bidegree
    M, shapes = system
    v = np.linalg.svd(M)[2][-1].conj()
    out, at = [], 0
    for sh in shapes:
        out.append(v[at : at + sh[0] * sh[1]].reshape(sh))
        at += sh[0] * sh[1]
    return out


def _factor_from_cofactors(
    polys: list[NDArray[np.complex128]], cof: list[NDArray[np.complex128]], shape: tuple[int, int]
) -> NDArray[np.complex128]:
    """F of the given shape by least squares from ``Q_k = F G_k`` for every k at once."""
    A = np.vstack([_conv_matrix(g, shape) for g in cof])
    rhs = np.concatenate([p.ravel() for p in polys])
    return np.linalg.lstsq(A, rhs, rcond=None)[0].reshape(shape)


def _tight(p: NDArray[np.complex128], scale: float) -> NDArray[np.complex128]:
    """p without trailing rows (powers of s) and columns (powers of x) of rounding noise: exact top degrees."""
    big = np.abs(p) > _NOISE * scale
    rows, cols = np.flatnonzero(big.any(axis=1)), np.flatnonzero(big.any(axis=0))
    return p[: rows[-1] + 1, : cols[-1] + 1]


def _gcd(
    polys: list[NDArray[np.complex128]], *, in_x: bool
) -> tuple[NDArray[np.complex128], list[NDArray[np.complex128]]] | None:
    """(gcd, cofactors) of polynomials in (s, x) with exact top degrees, or None when it is a constant.

    ``in_x``: the gcd's bidegree is sought with x-degree >= 1 (largest x-degree, then largest
    s-degree, module docstring); otherwise in s alone (x-degree 0), the largest s-degree.
    """
    if in_x:
        top = min(p.shape[1] for p in polys)
        ms = [m for m in range(1, top) if _has_factor(polys, 0, m)]
        if not ms:
            return None
        m = max(ms)
        n = max(n for n in range(min(p.shape[0] for p in polys)) if _has_factor(polys, n, m))
    else:
        m = 0
        n = max((n for n in range(1, min(p.shape[0] for p in polys)) if _has_factor(polys, n, 0)), default=0)
        if n == 0:
            return None
    cof = _cofactors(polys, n, m)
    return _factor_from_cofactors(polys, cof, (n + 1, m + 1)), cof


def _strip_content(f: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """(F / c, c) with c(s) the gcd of F's coefficients in x: a factor no delay moves, left to the rest."""
    scale = float(np.max(np.abs(f)))
    where = [j for j in range(f.shape[1]) if np.any(np.abs(f[:, j]) > _NOISE * scale)]
    found = _gcd([_tight(f[:, j : j + 1], scale) for j in where], in_x=False)
    if found is None:
        return f, np.ones((1, 1), complex)
    content, cof = found
    out = np.zeros((f.shape[0] - content.shape[0] + 1, f.shape[1]), complex)
    for j, g in zip(where, cof, strict=True):
        out[: g.shape[0], j] = g[:, 0]
    return out, content


def _radical(f: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """(R, H) with F = R H, R = F / gcd(F, dF/dx) (each factor of F once) and H that gcd."""
    scale = float(np.max(np.abs(f)))
    if f.shape[1] < 3:  # of degree 1 in x: no repeated factor
        return f, np.ones((1, 1), complex)
    fx = _tight(f[:, 1:] * np.arange(1, f.shape[1])[None, :], scale)
    found = _gcd([_tight(f, scale), fx], in_x=True)
    if found is None:
        return f, np.ones((1, 1), complex)
    h, (r, _) = found
    return r, h


# ----------------------------------------------------------------------------- checks
def _negligible_dropped(terms: Terms) -> Terms:
    """Terms with every coefficient at most ``_NOISE`` times q's largest set to zero (the principal kept)."""
    scale = max(float(np.max(np.abs(c))) for c in terms.values())
    out: Terms = {}
    for k, c in terms.items():
        c = np.where(np.abs(c) <= _NOISE * scale, 0.0, c).astype(complex)
        if k == (0, 0) or np.any(c != 0):
            out[k] = c
    return out


def _cleaned(terms: Terms, *, real: bool, retarded: bool) -> Terms:
    """Rounding noise removed: real parts for a real q, exact zeros, no delayed term at the principal degree."""
    scale = max(float(np.max(np.abs(c))) for c in terms.values())
    out: Terms = {}
    degree = int(np.flatnonzero(np.abs(terms[(0, 0)]) > _NOISE * scale)[-1])
    for k, c in terms.items():
        c = c.real.astype(complex) if real else c.copy()
        c[np.abs(c) <= _NOISE * scale] = 0.0
        if retarded and k != (0, 0):
            c[degree:] = 0.0  # a factor of a retarded q is retarded: its delayed terms are of lower degree
        nz = np.flatnonzero(c)
        if nz.size:
            out[k] = c[: nz[-1] + 1]
    return out


def _reproduction_error(q: Terms, f: Terms, g: Terms) -> float:
    """Largest ``|F G - q|`` of a term over the largest modulus ``|F| |G|`` making that term (module docstring)."""
    prod: dict[tuple[int, int], NDArray[np.complex128]] = {}
    mods: dict[tuple[int, int], NDArray[np.float64]] = {}
    n = max(c.size for c in f.values()) + max(c.size for c in g.values()) + max(c.size for c in q.values())
    for kf, cf in f.items():
        for kg, cg in g.items():
            key = (kf[0] + kg[0], kf[1] + kg[1])
            prod.setdefault(key, np.zeros(n, complex))[: cf.size + cg.size - 1] += np.convolve(cf, cg)
            mods.setdefault(key, np.zeros(n))[: cf.size + cg.size - 1] += np.convolve(np.abs(cf), np.abs(cg))
    worst = 0.0
    for key in set(prod) | set(q):
        want = np.zeros(n, complex)
        if key in q:
            want[: q[key].size] = q[key]
        got = prod.get(key, np.zeros(n, complex))
        mod = mods.get(key, np.zeros(n))
        diff = float(np.max(np.abs(got - want)))
        if diff > 0.0:
            # the largest modulus of the term: rounding of the factors spreads over its coefficients
            worst = max(worst, diff / float(np.max(mod))) if np.max(mod) > 0 else float("inf")
    return worst
