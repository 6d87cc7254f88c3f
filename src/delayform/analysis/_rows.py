"""Rows of the factor family: a factor of eq. factorized at a delay pair, as flat arrays.

Every factor of eq. factorized is (for a conjugate pair, through its complex
second-order factor of lam) the same quasi-polynomial

    q(s) = s^2 + D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s})

with its own eigenvalue lam of C, so a *row* is (lam, tau1, tau2) and the
vectorized root finding (:mod:`delayform.analysis._family`) runs on arrays of rows.
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


class _Rows:
    """Flat arrays describing rows (factor, delay pair): lam, tau1, tau2, two flags and the gains."""

    __slots__ = ("lam", "t1", "t2", "real", "deflate", "P", "D")

    def __init__(
        self, lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
        real: NDArray[np.bool_], deflate: NDArray[np.bool_], P: Gain, D: Gain,
    ) -> None:
        self.lam, self.t1, self.t2, self.real, self.deflate = lam, t1, t2, real, deflate
        self.P, self.D = P, D

    def take(self, idx: NDArray[np.int64]) -> _Rows:
        return _Rows(self.lam[idx], self.t1[idx], self.t2[idx], self.real[idx], self.deflate[idx],
                     _at(self.P, idx), _at(self.D, idx))  # fmt: skip

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
