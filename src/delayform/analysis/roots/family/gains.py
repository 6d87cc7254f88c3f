"""Certified rightmost roots of the formation's factors for many (P, D, tau1, tau2) at once.

:mod:`delayform.analysis.roots.dominant` batches over delays for fixed gains (one
quasi-polynomial, many delay pairs). Gain design (:mod:`delayform.design.gains`)
needs the other direction:
many gains (and, for the robust design, many delays) per factor. Every factor
of the paper's eq. 3 is, through its eigenvalue lam of C (a conjugate pair
through lam alone, as in :mod:`delayform.analysis.roots.dominant`),

    q(s) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s}),

so each *line* of a batch is one (P, D, tau1, tau2): a row of the factor family
(:mod:`delayform.analysis.roots.family.rows`) with its own gains, and the family's steps run on
all lines together -- seeds from the stacked discretized generator
(:mod:`delayform.analysis.roots.family.seeds`), Halley polishing on q (:mod:`delayform.analysis.roots.family.polish`,
Maehly's deflation of the persistent zero of the paper's eq. 4), the line choice and the
argument-principle walk (:mod:`delayform.analysis.roots.family.walk`); the count right of the line
must equal the number of polished roots there.

Lines the certificate rejects are redone with fresh discretization seeds at twice
the number, and any still rejected by the robust single-pair path
(:func:`~delayform.analysis.roots.single.rightmost_root`). Every root returned is
therefore certified: no root of its factor lies to its right. As in
:func:`~delayform.analysis.roots.dominant.dominant_root`, the centroid factor's
roots at s = 0 are not counted: the persistent one, and on tau1 = 0 the
second one (the centroid's drift), for which the spectrum module's
centroid path is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.dominant import _centroid_rightmost
from delayform.analysis.roots.family.polish import _q
from delayform.analysis.roots.family.rows import _Rows
from delayform.analysis.roots.family.solve import _certify_afresh, _certify_rows, _fresh_seeds
from delayform.analysis.roots.rightmost import _BATCH_SEEDS
from delayform.analysis.roots.single import rightmost_root
from delayform.characteristic import CharacteristicFactor
from delayform.topology import EigenvalueGroup

__all__ = ["GainLines", "gain_lines", "rightmost_roots", "root_gradients"]

_Arr = NDArray[np.float64]
_CArr = NDArray[np.complex128]


@dataclass(frozen=True)
class GainLines:
    """A batch of lines: line i is a factor at gains (P[i], D[i]) and delays (t1[i], t2[i]).

    Attributes
    ----------
    P, D, t1, t2
        Flat float arrays of one length (see :func:`gain_lines`).
    """

    P: _Arr
    D: _Arr
    t1: _Arr
    t2: _Arr

    @property
    def size(self) -> int:
        """The number of lines."""
        return int(self.P.size)

    def take(self, idx: NDArray[np.int64]) -> GainLines:
        """The lines at the indices ``idx``."""
        return GainLines(self.P[idx], self.D[idx], self.t1[idx], self.t2[idx])


def gain_lines(P: object, D: object, t1: object, t2: object) -> GainLines:
    """The lines of gains and delays broadcast together and flattened (C order).

    Parameters
    ----------
    P, D, t1, t2
        Gains and delays, numbers or arrays of broadcastable shapes.
    """
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (P, D, t1, t2)))
    return GainLines(*(np.ascontiguousarray(a).ravel() for a in arrays))


def rightmost_roots(
    group: EigenvalueGroup, L: GainLines, seeds: _CArr | None = None
) -> tuple[_CArr, _CArr]:
    """Certified rightmost root (Im >= 0 member) of the factor of ``group`` on every line.

    Parameters
    ----------
    group
        The eigenvalue group of C whose factor is solved.
    L
        The lines (:func:`gain_lines`).
    seeds
        (B, K) seeds, e.g. the roots of a nearby line (roots move continuously
        with the gains): they replace the discretization where the certificate
        accepts them.

    Returns
    -------
    roots, found
        The rightmost roots, and every line's distinct roots found
        (NaN-padded), the seeds for the next nearby batch.
    """
    B = L.size
    rows = _Rows(np.full(B, complex(group.lam)), L.t1, L.t2, np.full(B, not group.is_complex_pair),
                 np.full(B, group.is_centroid), L.P, L.D)  # fmt: skip
    with np.errstate(all="ignore"):  # far-left seeds and lines overflow; they fail the tests
        if seeds is None:
            seeds = _fresh_seeds(rows, _BATCH_SEEDS)
        out, cert, found = _certify_rows(rows, seeds)
        out = np.where(cert, out, np.nan + 0j)
        if group.is_centroid:  # on tau1 = 0 the second root at 0 is the centroid's drift: not counted either
            for i in np.flatnonzero(L.t1 == 0.0):
                f = CharacteristicFactor(group, float(L.P[i]), float(L.D[i]))
                r = _centroid_rightmost(f, 0.0, float(L.t2[i]))
                out[i] = complex(-np.inf, 0.0) if r is None else r
                cert[i] = True
                found = _merge_rows(found, np.array([i]), np.array([[out[i]]]))
        left = np.flatnonzero(~cert)
        if left.size:
            r, ok, more = _certify_afresh(rows, seeds, left)
            out[left[ok]] = r[ok]
            found = _merge_rows(found, left[ok], more[ok])
            left = left[~ok]
    for i in left:  # the robust single-pair path, certified or raising
        f = CharacteristicFactor(group, float(L.P[i]), float(L.D[i]))
        out[i] = rightmost_root(f, float(L.t1[i]), float(L.t2[i]))
        found = _merge_rows(found, np.array([i]), np.array([[out[i]]]))
    return out.real + 1j * np.abs(out.imag), found


def _merge_rows(found: _CArr, rows: NDArray[np.int64], new: _CArr) -> _CArr:
    """``found`` with the given rows replaced by ``new`` (widened with NaN as needed)."""
    if rows.size == 0:
        return found
    width = max(found.shape[1], new.shape[1])
    out = np.full((found.shape[0], width), np.nan + 0j)
    out[:, : found.shape[1]] = found
    out[rows] = np.nan
    out[rows, : new.shape[1]] = new
    return out


def root_gradients(
    lam: complex, L: GainLines, s: _CArr
) -> tuple[_Arr, _Arr, _Arr, _Arr]:
    """d Re s / d(P, D, tau1, tau2) of simple roots ``s`` of the factor of ``lam`` on the lines ``L``.

    By implicit differentiation of q(s) = 0.

    ds/dx = -(dq/dx) / (dq/ds) with dq/dP = 1 - lam e^{-tau1 s},
    dq/dD = s (1 - lam e^{-tau2 s}), dq/dtau1 = lam P s e^{-tau1 s} and
    dq/dtau2 = lam D s^2 e^{-tau2 s}. For a conjugate-pair factor the
    conjugate root of the conjugate factor has the same real part, so ``s``
    may be either member; a real-coefficient factor's mirror image likewise.
    """
    s = np.asarray(s, dtype=np.complex128)
    with np.errstate(all="ignore"):
        # the member of lam's own factor (for a complex lam the Im >= 0 member may be conj(lam)'s)
        q_now, _, a, b = _q(s, lam, L.t1, L.t2, L.P, L.D)
        z = np.abs(s)
        mag = z * (z + L.D) + L.P + np.abs(a) + np.abs(b) * z
        s = np.where(np.abs(q_now) > 1e-6 * mag, np.conj(s), s)
        _, dq, a, b = _q(s, lam, L.t1, L.t2, L.P, L.D)
        # a = lam P e^{-tau1 s}, b = lam D e^{-tau2 s}
        parts = (1.0 - a / L.P, s * (1.0 - b / L.D), s * a, s * s * b)
        grads = tuple(np.real(-p / dq) for p in parts)
    return grads  # type: ignore[return-value]
