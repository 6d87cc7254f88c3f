"""Rows of the factor family: a factor of the paper's eq. 3 at a delay pair, as flat arrays.

Every factor of the paper's eq. 3 is (for a conjugate pair, through its complex
second-order factor of lam) the same quasi-polynomial

    q(s) = s^2 + D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s})

with its own eigenvalue lam of C, so a *row* is (lam, tau1, tau2) and the
vectorized root finding (:mod:`delayform.analysis.roots.family.solve`) runs on arrays of rows.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any, Union

import numpy as np
from numpy.typing import NDArray

from delayform.characteristic import CharacteristicFactor


#: The gains of a batch of rows: one value for all, or one per row (gain design).
Gain = Union[float, NDArray[np.float64]]


def _at(x: Any, idx: NDArray[np.int64]) -> Any:
    """x[idx] for a per-row array, x itself for a value shared by all rows."""
    return np.take(x, idx) if isinstance(x, np.ndarray) else x


def _delay_free(lam: Any, P: Gain, D: Gain) -> NDArray[np.complex128]:
    """Roots of s^2 + D (1 - lam) s + P (1 - lam), the factor of lam without delays, on a last axis of 2.

    With lam = 0 these are the roots of s^2 + D s + P (the walk's tails); broadcasting.
    """
    b, c0 = np.multiply(D, 1.0 - lam), np.multiply(P, 1.0 - lam)
    disc = np.sqrt(b * b - 4.0 * c0 + 0j)
    return np.stack([(-b + disc) / 2.0, (-b - disc) / 2.0], axis=-1)


def _root_scales(lam: Any, P: Gain, D: Gain) -> NDArray[np.float64]:
    """The root scale of the factor of lam (:func:`delayform.analysis.roots.generator._root_scale`) in closed form.

    max(1, the delay-free roots, ||A||) with A = [[0, 1], [-P, -D]]: A + B1 + B2 of the factor of lam
    is [[0, 1], [-P (1 - lam), -D (1 - lam)]], whose eigenvalues are the delay-free roots.
    """
    t = 1.0 + np.multiply(P, P) + np.multiply(D, D)  # ||A||_2^2: the larger eigenvalue of A^T A (det P^2)
    norm_a = np.sqrt((t + np.sqrt(np.maximum(t * t - 4.0 * np.multiply(P, P), 0.0))) / 2.0)
    return np.maximum(np.maximum(1.0, np.abs(_delay_free(lam, P, D)).max(axis=-1)), norm_a)  # type: ignore[no-any-return]


class _Rows:
    """Flat arrays describing rows (factor, delay pair): lam, tau1, tau2, two flags and the gains.

    ``ta`` is an actuation delay shared by all rows: > 0 makes them rows of the family of
    :mod:`delayform.analysis.roots.family.actuated`.
    """

    __slots__ = ("lam", "t1", "t2", "real", "deflate", "P", "D", "ta")

    def __init__(
        self, lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
        real: NDArray[np.bool_], deflate: NDArray[np.bool_], P: Gain, D: Gain, ta: float = 0.0,
    ) -> None:
        self.lam, self.t1, self.t2, self.real, self.deflate = lam, t1, t2, real, deflate
        self.P, self.D, self.ta = P, D, ta

    def take(self, idx: NDArray[np.int64]) -> _Rows:
        return _Rows(self.lam[idx], self.t1[idx], self.t2[idx], self.real[idx], self.deflate[idx],
                     _at(self.P, idx), _at(self.D, idx), self.ta)  # fmt: skip

    @property
    def size(self) -> int:
        return int(self.lam.size)


@lru_cache(maxsize=16)
def _lams(fs: tuple[CharacteristicFactor, ...]) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.bool_]]:
    """(lam, real lam, centroid) per factor; cached per factor tuple (read-only arrays)."""
    lam = np.array([complex(f.lam) for f in fs], dtype=np.complex128)
    real = ~np.array([f.group.is_complex_pair for f in fs], dtype=bool)
    centroid = np.array([f.is_centroid for f in fs], dtype=bool)
    for a in (lam, real, centroid):
        a.flags.writeable = False
    return lam, real, centroid
