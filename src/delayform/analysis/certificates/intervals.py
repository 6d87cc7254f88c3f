"""A Lyapunov-Krasovskii functional for several delays, each varying in its own interval.

The system is

    x'(t) = A0 x(t) + sum_k A_k x(t - h_k(t)),   h_k(t) in [a_k, b_k],

each h_k(t) varying arbitrarily fast (or with |h_k'| <= mu). The positive
lower ends a_k cut [t - max a_k, t] into *constant* windows shared by all
delays; each carries a single and a double integral (bounded by the
Bessel-Legendre inequality of order N) and its N Legendre moments augment the
state of the quadratic term: their derivatives do not involve any h_k', so the
augmentation is allowed for any variation (without it a Wirtinger bound is no
better than Jensen's). Per delay, the outer window [t - b_k, t - a_k] carries
the interval-delay terms of
:func:`~delayform.analysis.certificates.krasovskii.time_varying` (its double
integral split at t - h_k(t), each part bounded, the two recombined by
reciprocal convexity); with ``outer`` its whole integral joins the state too
(derivative free of h_k', value affine in h_k(t)) and the recombination is the
improved reciprocally convex inequality, both affine in h_k(t), so the
derivative bound is checked at the 2^K corners of the delays. With ``cover`` the
constant windows go on over the delays' intervals, and the integral of x over
each interval, both the sum of its windows' and that of its two parts', ties the
two descriptions together (Finsler's lemma, affine in h_k(t)). Derivation in
docs/theory.md, "Several delays varying in intervals, and the team's delays varying together".

Constant solutions (the centroid's zero)
----------------------------------------
When ``(A0 + sum_k A_k) e = 0`` every constant x = c e is a solution for any
delays, and no functional with V >= eps |x|^2 can exist. With ``invariant=e``
the functional is made blind to such shifts: the matrices of the quadratic and
the single-integral terms are restricted to the complement of the shift
direction (``P = W P^ W'`` with W' annihilating it), and the derivative bound
is required negative only on a complement of the shift direction of zeta
(``N' Phi N < 0``). Since a shifted solution is a solution, V' <= zeta' Phi zeta
holds for every shift of zeta, in particular for the one in the range of N;
the conclusion is stability of the quotient (the solution converges to a
constant multiple of e).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import itertools
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.certificates.krasovskii import _bessel_terms, _moments, _Signals, _Sum, _t
from delayform.analysis.certificates.lmi import LmiProblem, Variables

__all__ = ["IntervalDelays", "interval_delays", "orthogonal_basis", "constant_nodes", "integral_tie"]

Matrix = NDArray[Any]


@dataclass(frozen=True)
class IntervalDelays:
    """A0, the delayed matrices A_k and their delay intervals [lo_k, hi_k] (hi_k > lo_k >= 0).

    ``invariant``: a vector e with (A0 + sum A_k) e = 0 whose constant multiples are
    projected out (module docstring), or None.
    """

    A0: NDArray[np.float64]
    delayed: tuple[NDArray[np.float64], ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    mu: float | None = None
    invariant: NDArray[np.float64] | None = None

    def matrices(self, exact: bool) -> tuple[Matrix, list[Matrix]]:
        """(A0, [A_k]) as float64, or (``exact``) as object arrays of Fractions equal to the floats."""
        if not exact:
            return self.A0, list(self.delayed)
        conv = np.vectorize(Fraction, otypes=[object])
        return conv(self.A0), [conv(A) for A in self.delayed]


def orthogonal_basis(s: NDArray[Any]) -> NDArray[Any]:
    """Columns spanning the orthogonal complement of the non-zero vector ``s``, rational when ``s`` is.

    With p the index of the largest |s_p|, the columns e_j - (s_j / s_p) e_p (j != p)
    satisfy c' s = s_j - s_j = 0 and are independent: they span s-perp, which is
    also a complement of s. Used both ways: W' s = 0 makes P = W P^ W' blind to s,
    and N' Phi N < 0 asks Phi negative on a complement of s.
    """
    m = s.shape[0]
    p = int(np.argmax([abs(float(v)) for v in s]))
    cols = []
    for j in range(m):
        if j == p:
            continue
        c = np.zeros(m, dtype=s.dtype)
        c[j] = 1
        c[p] = -s[j] / s[p]
        cols.append(c)
    return np.array(cols, dtype=s.dtype).T


#: An upper end that would leave a constant window shorter than this fraction of the longest is not a cut.
SHORTEST_WINDOW = 0.1


def constant_nodes(lo: Sequence[float], split: int, hi: Sequence[float] = (), cover: bool = False) -> list[float]:
    """The lags 0 < c_1 < ... of the constant windows: every positive lower end, each gap cut in ``split`` pieces.

    Every upper end in ``hi`` below the largest lower end is an end too (the windows are then cut
    where another delay's interval ends). With ``cover`` the windows go on to the largest upper
    end, every upper end cutting them: they then also cover the delays' intervals. An upper end
    within :data:`SHORTEST_WINDOW` of the longest window from another end is left out.
    """
    top = max((*lo, *(hi if cover else ())), default=0.0)
    ends = sorted({0.0, *(v for v in lo if v > 0.0), *(v for v in hi if 0.0 < v <= top)})
    # an upper end closer than SHORTEST_WINDOW times the longest window to another end is not a cut: so
    # short a window only makes the LMIs ill-conditioned (that delay's interval is then not tied)
    longest = max((w - u for u, w in zip(ends[:-1], ends[1:], strict=True)), default=0.0)
    fixed = {0.0, *lo}
    ends = [v for v in ends if v in fixed or min(abs(v - u) for u in ends if u != v) >= SHORTEST_WINDOW * longest]
    out: list[float] = []
    for u, w in zip(ends[:-1], ends[1:], strict=True):
        out += [u + (w - u) * i / split for i in range(1, split)] + [w]
    return out


def interval_delays(data: IntervalDelays, order: int, *, split: int = 1, outer: bool = True,
                    upper: bool = False, cover: bool = False) -> LmiProblem:  # fmt: skip
    """The LMIs of the several-delay functional (module docstring) at Bessel-Legendre order N.

    Parameters
    ----------
    data
        The system, the intervals, the rate bound and the direction of constant solutions.
    order
        The Bessel-Legendre order N of every bound; N moments augment the state per constant window.
    split
        Each gap between consecutive lower ends (0 first) is cut into this many constant windows
        (delay partitioning: more windows, less conservatism, larger LMIs).
    outer
        With N >= 1, augment the state by each outer window's integral (its value is affine in
        h_k(t): the derivative bound is then checked at the 2^K corners of the delays).
    upper
        Also cut the constant windows at every upper end hi_k below the largest lower end
        (docs/theory.md): x(t - hi_k) is then one of the windows' ends, shared with the delay's term.
    cover
        The constant windows go on to the largest upper end, cut at every upper end, so that they
        also cover the delays' intervals (implies ``upper``); with ``outer``, the integral of x over
        each delay's interval, summed over the windows that tile it, is tied to the sum over its two
        parts at t - h_k(t) (:func:`integral_tie`, docs/theory.md).
    """
    n = data.A0.shape[0]
    K = len(data.delayed)
    nodes = constant_nodes(data.lo, split, data.hi if upper or cover else (), cover)
    node_name = {c: f"c{i}" for i, c in enumerate(nodes)}
    node_name[0.0] = "x"
    tops = ["x", *(node_name[c] for c in nodes[:-1])]
    lengths = [c - u for u, c in zip([0.0, *nodes][:-1], nodes, strict=True)]
    wins = [_moments(f"w{i}_", order) for i in range(len(nodes))]
    pa = [_moments(f"p{k}_", order) for k in range(K)]
    qb = [_moments(f"q{k}_", order) for k in range(K)]
    outer = outer and order >= 1
    eta_blocks = 1 + order * len(nodes) + (K if outer else 0)
    e = data.invariant
    r = n if e is None else n - 1  # the single-integral matrices live on the complement of e
    m = n * (order + 1)
    var = Variables()
    var.symmetric("P", n * eta_blocks - (0 if e is None else 1))
    for i in range(len(nodes)):
        var.symmetric(f"S1_{i}", r)
        var.symmetric(f"R1_{i}", n)
    for k in range(K):
        var.symmetric(f"S2_{k}", r)
        var.symmetric(f"R2_{k}", n)
        if data.mu is not None:
            var.symmetric(f"Q_{k}", r)
        if outer:  # the improved reciprocally convex bound, affine in h_k(t)
            var.symmetric(f"Z1_{k}", m, normalize=False)
            var.symmetric(f"Z2_{k}", m, normalize=False)
            var.full(f"Y1_{k}", m, m)
            var.full(f"Y2_{k}", m, m)
        else:
            var.full(f"X_{k}", m, m)

    names = ["x", *(node_name[c] for c in nodes), *(w for ws in wins for w in ws)]
    # with ``cover`` the windows inside a delay's interval tile it: the integral of x over the interval
    # is both the sum of theirs and the sum of its two parts' (at t - h_k(t)), a relation affine in
    # h_k(t) imposed at the corners by Finsler's lemma (docs/theory.md)
    starts = [0.0, *nodes[:-1]]
    ties = {k: [i for i in range(len(nodes)) if data.lo[k] <= starts[i] and nodes[i] <= data.hi[k]]
            for k in range(K) if cover and outer and data.hi[k] in nodes}  # tiled: both ends are nodes
    aliases = {f"a{k}": node_name[data.lo[k]] for k in range(K)}
    aliases.update({f"b{k}": node_name[data.hi[k]] for k in range(K) if data.hi[k] in node_name})
    for k in range(K):
        names += [f"h{k}", *([] if f"b{k}" in aliases else [f"b{k}"]), *pa[k], *qb[k]]

    # rows of the system without delayed terms: x_r' = A0[r] x, so over a constant window of length L
    # e_r' Gamma_j = L A0[r] Omega_j (j < N), a linear relation among the entries of zeta
    free_rows, free_cols = _delay_free(data)
    window_rows = [(i, j, r) for i in range(len(nodes)) for j in range(order) for r in free_rows]
    zsize = n * len(names) - len(window_rows) - (0 if e is None else 1)
    for k in ties:
        var.full(f"Y_{k}", zsize, n)

    def _relations(sig: _Signals, A0: Matrix, exact: bool) -> Matrix | None:
        if not window_rows:
            return None
        rows = []
        for i, j, r in window_rows:
            gamma = sig.legendre(tops[i], node_name[nodes[i]], wins[i], j)[r]
            rows.append(gamma - _num(lengths[i], exact) * (A0[r] @ sig.e(wins[i][j])))
        return np.array(rows, dtype=sig.dtype)

    def pivots(sig: _Signals) -> list[int]:
        """One entry of zeta per relation, solved for: a component of its Omega_j (:func:`_delay_free`)."""
        col = dict(zip(free_rows, free_cols, strict=True))
        return [sig.index[wins[i][j]] * n + col[r] for i, j, r in window_rows]

    def shift(sig: _Signals, exact: bool) -> tuple[Matrix, Matrix]:
        """The shift directions of zeta and of eta under x -> x + c e (moments Omega_0 shift, higher ones not)."""
        ev = np.array([Fraction(v) for v in e], dtype=object) if exact else np.asarray(e, dtype=float)  # type: ignore[union-attr]
        z = np.zeros(sig.size, dtype=sig.dtype)
        for nm in names:
            if nm[0] not in "wpq" or nm.split("_")[1] == "0":
                i = sig.index[nm]
                z[i * n : (i + 1) * n] = ev
        y = [ev] + [(_num(L, exact) * ev if j == 0 else 0 * ev) for L in lengths for j in range(order)]
        if outer:
            y += [(_num(data.hi[k], exact) - _num(data.lo[k], exact)) * ev for k in range(K)]
        return z, np.concatenate(y)

    def build(v: Mapping[str, Matrix], exact: bool) -> dict[str, Matrix]:
        A0, Ak = data.matrices(exact)
        full = _Signals(names, n, exact, aliases)
        # zeta lies in the kernel of the delay-free rows' relations (module docstring), and with an
        # invariant only a complement of its shift direction matters: zeta = B z, the signals in z
        B = _relation_basis(_relations(full, A0, exact), pivots(full), exact)
        zdir = ydir = None
        if e is not None:
            zdir, ydir = shift(full, exact)
            # zdir is in the kernel (a constant has Gamma_j = 0): its coordinates are its free entries
            B = _complement(B, zdir if B is None else zdir[_free(full.size, pivots(full))])
        sig = full if B is None else _Signals(names, n, exact, aliases, basis=B)
        e0 = sig.e("x")
        F = A0 @ e0
        for k in range(K):
            F = F + Ak[k] @ sig.e(f"h{k}")
        # eta = (x, L_i Omega^i_0..Omega^i_{N-1} over each constant window, outer integrals);
        # eta' = H zeta: d/dt (L Omega_j) = Gamma_j, d/dt int_{t-b}^{t-a} x = x(t - a) - x(t - b)
        G, H = [e0], [F]
        for i, c in enumerate(nodes):
            L = _num(lengths[i], exact)
            for j, w in enumerate(wins[i]):
                G.append(L * sig.e(w))
                H.append(sig.legendre(tops[i], node_name[c], wins[i], j))
        if outer:
            H += [sig.e(f"a{k}") - sig.e(f"b{k}") for k in range(K)]
        Hm = np.vstack(H)
        Pm, Wr = v["P"], None
        if ydir is not None:
            Pm = orthogonal_basis(ydir) @ v["P"] @ _t(orthogonal_basis(ydir))
            Wr = orthogonal_basis(ydir[:n])

        def lift(M: Matrix) -> Matrix:
            return M if Wr is None else Wr @ M @ _t(Wr)

        # Phi, a sum of quadratic forms (in exact arithmetic summed in integers: krasovskii._Sum)
        Phi = _Sum(sig.size, exact)
        for i, c in enumerate(nodes):  # int S1 and L int int R1 over each constant window
            S1, R1, L = lift(v[f"S1_{i}"]), v[f"R1_{i}"], _num(lengths[i], exact)
            top, bottom = sig.e(tops[i]), sig.e(node_name[c])
            Phi.add(1, top, S1)
            Phi.add(-1, bottom, S1)
            Phi.add(L * L, F, R1)
            Phi.add_terms(-1, _bessel_terms(sig, tops[i], node_name[c], wins[i], order), R1)
        rcc: dict[int, tuple[Matrix, Matrix]] = {}
        psi: dict[int, Matrix] = {}
        side: dict[str, Matrix] = {}
        for k in range(K):
            ea, eh, eb = sig.e(f"a{k}"), sig.e(f"h{k}"), sig.e(f"b{k}")
            d = _num(data.hi[k], exact) - _num(data.lo[k], exact)
            S2, R2 = lift(v[f"S2_{k}"]), v[f"R2_{k}"]
            Phi.add(1, ea, S2)
            Phi.add(-1, eb, S2)
            Phi.add(d * d, F, R2)
            # the R2 integral split at t - h_k(t), each part bounded, recombined by reciprocal convexity
            Psi = np.vstack([sig.legendre(f"a{k}", f"h{k}", pa[k], i) for i in range(order + 1)]
                            + [sig.legendre(f"h{k}", f"b{k}", qb[k], i) for i in range(order + 1)])  # fmt: skip
            psi[k] = Psi
            Rt = _rtilde(R2, order, n, sig.dtype)
            if outer:
                Z1, Z2, Y1, Y2 = v[f"Z1_{k}"], v[f"Z2_{k}"], v[f"Y1_{k}"], v[f"Y2_{k}"]
                rcc[k] = (np.block([[Rt + Z1, Y2], [_t(Y2), Rt]]), np.block([[Rt, Y1], [_t(Y1), Rt + Z2]]))
                side[f"RC1_{k}"] = np.block([[Rt - Z1, Y1], [_t(Y1), Rt]])
                side[f"RC2_{k}"] = np.block([[Rt, Y2], [_t(Y2), Rt - Z2]])
            else:
                rcc[k] = (np.block([[Rt, v[f"X_{k}"]], [_t(v[f"X_{k}"]), Rt]]),) * 2
                side[f"RCC_{k}"] = rcc[k][0]
            if data.mu is not None:  # d/dt int_{t-h_k(t)}^t x'Qx <= x'Qx - (1 - mu) xh'Q xh
                Q = lift(v[f"Q_{k}"])
                Phi.add(1, e0, Q)
                Phi.add(-(1 - _num(data.mu, exact)), eh, Q)
        out: dict[str, Matrix] = {}
        # eta is affine in h(t) (the outer integrals), so Phi is: negative on the box of delays
        # when negative at its corners (one matrix without the outer integrals)
        for corner in itertools.product(*[(0, 1)] * (K if outer else 0)):
            rows = list(G)
            for k, up in enumerate(corner):
                a, b = _num(data.lo[k], exact), _num(data.hi[k], exact)
                hv = b if up else a
                rows.append((hv - a) * sig.e(pa[k][0]) + (b - hv) * sig.e(qb[k][0]))
            Phv = Phi.copy()
            Phv.add(1, np.vstack(rows), Pm, Hm, sym=True)
            for k, inside in ties.items():  # Finsler: + Y C(h) + C(h)' Y' where C(h) zeta = 0, affine in h_k
                a, b = _num(data.lo[k], exact), _num(data.hi[k], exact)
                C = integral_tie(sig, a, b, b if corner[k] else a, (pa[k][0], qb[k][0]),
                                 [(_num(lengths[i], exact), wins[i][0]) for i in inside])  # fmt: skip
                Phv.add(1, np.eye(sig.size, dtype=sig.dtype), v[f"Y_{k}"], C, sym=True)
            for k in range(K):  # the reciprocal-convexity bound at h_k = a_k (alpha 0) or b_k (alpha 1)
                Phv.add(-1, psi[k], rcc[k][corner[k] if outer else 0])
            label = "".join("+" if up else "-" for up in corner)
            out[f"-Phi{label}"] = Phv.value(-1)
        out["P"] = v["P"]
        out.update(side)
        for name in v:
            if name[0] in "SRQ":
                out[name] = v[name]
        return out

    return LmiProblem(var, build)


def integral_tie(sig: _Signals, a: Any, b: Any, h: Any, parts: tuple[str, str], windows: Sequence[tuple[Any, str]]) -> Matrix:
    """C with C zeta = 0 on every history: the integral of x over [t - b, t - a] summed two ways.

    Over the constant windows that tile the interval, sum L_i Omega^i_0; over its two parts at
    t - h (means ``parts``), (h - a) Omega^p_0 + (b - h) Omega^q_0. Affine in h, so one Finsler
    multiplier serves every h in [a, b] when the derivative bound is checked at the corners.

    Parameters
    ----------
    sig
        The blocks of zeta (the signals' names).
    a, b, h
        The interval's ends and the delay in it (floats, or Fractions for the exact re-check).
    parts
        The names of the means of x over [t - h, t - a] and over [t - b, t - h].
    windows
        (length L_i, name of the mean Omega^i_0) of each constant window tiling the interval.
    """
    C = -(h - a) * sig.e(parts[0]) - (b - h) * sig.e(parts[1])
    for length, mean in windows:
        C = C + length * sig.e(mean)
    return C


def _delay_free(data: IntervalDelays) -> tuple[list[int], list[int]]:
    """The rows r of the system without delayed terms (x_r' = A0[r] x), independent, and a column for each.

    Row reduction of those rows of A0 with the largest remaining entry as pivot: the columns make
    the square submatrix A0[rows, cols] non-singular (a row left without a clear pivot is dropped).
    """
    n = data.A0.shape[0]
    cand = [r for r in range(n) if all(not np.any(A[r] != 0.0) for A in data.delayed) and np.any(data.A0[r] != 0.0)]
    M = data.A0[cand].astype(float).copy()
    scale = float(np.abs(data.A0).max()) if data.A0.size else 1.0
    rows: list[int] = []
    cols: list[int] = []
    for k, r in enumerate(cand):
        c = int(np.argmax(np.abs(M[k])))
        if abs(M[k, c]) <= 1e-9 * scale:
            continue
        rows.append(r)
        cols.append(c)
        M[k + 1 :] -= np.outer(M[k + 1 :, c] / M[k, c], M[k])
    return rows, cols


def _complement(T: Matrix | None, u: Matrix) -> Matrix:
    """T @ orthogonal_basis(u) (T None: the identity), formed column by column: e_j - (u_j / u_p) e_p."""
    W = orthogonal_basis(u)
    if T is None:
        return W
    p = int(np.argmax([abs(float(v)) for v in u]))
    others = [j for j in range(u.shape[0]) if j != p]
    return T[:, others] + np.outer(T[:, p], W[p, :])


def _free(size: int, pivots: list[int]) -> NDArray[np.intp]:
    """The entries of zeta not solved for by a relation."""
    return np.array([i for i in range(size) if i not in set(pivots)], dtype=np.intp)


def _relation_basis(C: Matrix | None, pivots: list[int], exact: bool) -> Matrix | None:
    """A basis T of the kernel of C: identity on the free entries, the pivot entries solved for.

    C z = 0 with the pivot entries z_p gives z_p = -C_p^-1 C_f z_f; C_p (square, one pivot per row)
    is inverted by Gauss-Jordan elimination, exactly in Fractions when ``exact``.
    """
    if C is None:
        return None
    size = C.shape[1]
    free = _free(size, pivots)
    Cp, Cf = C[:, pivots], C[:, free]
    k = len(pivots)
    if exact:
        aug = np.concatenate([Cp, -Cf], axis=1)
        for col in range(k):  # Gauss-Jordan: the pivot rows are independent by construction
            piv = next(r for r in range(col, k) if aug[r, col] != 0)
            aug[[col, piv]] = aug[[piv, col]]
            aug[col] = aug[col] / aug[col, col]
            for r in range(k):
                if r != col and aug[r, col] != 0:
                    aug[r] = aug[r] - aug[r, col] * aug[col]
        solved = aug[:, k:]
    else:
        solved = np.linalg.solve(Cp, -Cf)
    T = np.zeros((size, free.size), dtype=C.dtype)
    T[free, np.arange(free.size)] = 1
    T[pivots, :] = solved
    return T


def _rtilde(R2: Matrix, order: int, n: int, dtype: Any) -> Matrix:
    """R~ = diag((2i + 1) R2, i <= N), the weight of the stacked Gamma's of one part."""
    m = n * (order + 1)
    Rt = np.zeros(R2.shape[:-2] + (m, m), dtype=dtype)
    for i in range(order + 1):
        Rt[..., i * n : (i + 1) * n, i * n : (i + 1) * n] = (2 * i + 1) * R2
    return Rt


def _num(value: float, exact: bool) -> Any:
    return Fraction(value) if exact else value
