"""Independent reference computations for tests/test_spectrum.py.

Nothing here uses :mod:`delayform.analysis.roots.dominant`. The characteristic function is
either the full 2n x 2n determinant of eq. protocolss
(:func:`delayform.characteristic.full_characteristic`, which does not use the
eigenvalues of C or the factorization of Lemma 1) or a quasi-polynomial's own
``evaluate``. Roots are found by a different route than the library's
(spectral discretization + Newton + certified winding):

* a QPmR-like mesh: local minima of |f| on a fine rectangular grid,
* Muller's method (derivative-free) to refine each minimum,
* a plain argument principle on densely sampled rectangle edges
  (np.unwrap of the phase, no certificate) to count roots,
* the Lambert W function for s + a + b e^{-tau s} (closed form).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.special import lambertw

from delayform.characteristic import full_characteristic
from delayform.topology import Topology

Func = Callable[[NDArray[np.complex128]], NDArray[np.complex128]]


def muller(f: Func, s0: complex, *, h: float = 1e-3, maxiter: int = 100, tol: float = 1e-15) -> complex:
    """Muller's method from the three points s0 - h, s0 + h, s0 (derivative-free)."""
    x0, x1, x2 = complex(s0 - h), complex(s0 + h), complex(s0)
    f0, f1, f2 = (complex(f(np.asarray(x))) for x in (x0, x1, x2))
    for _ in range(maxiter):
        if f2 == 0:
            return x2
        h1, h2 = x1 - x0, x2 - x1
        d1, d2 = (f1 - f0) / h1, (f2 - f1) / h2
        a = (d2 - d1) / (h2 + h1)
        b = a * h2 + d2
        disc = np.sqrt(b * b - 4.0 * f2 * a)
        den = b + disc if abs(b + disc) > abs(b - disc) else b - disc
        if den == 0:
            return x2
        dx = -2.0 * f2 / den
        x0, x1, x2 = x1, x2, x2 + dx
        f0, f1, f2 = f1, f2, complex(f(np.asarray(x2)))
        if abs(dx) <= tol * (1.0 + abs(x2)):
            break
    return x2


def mesh_roots(
    f: Func, box: tuple[float, float, float, float], shape: tuple[int, int] = (301, 301)
) -> NDArray[np.complex128]:
    """Roots of f in box: local minima of |f| on a grid, refined by Muller, deduplicated."""
    x0, x1, y0, y1 = box
    re = np.linspace(x0, x1, shape[0])
    im = np.linspace(y0, y1, shape[1]) + 1.234567e-7  # keep the grid off s = 0 exactly
    S = re[:, None] + 1j * im[None, :]
    F = np.abs(f(S))
    core = F[1:-1, 1:-1]
    is_min = np.ones_like(core, dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_min &= core <= F[1 + di : F.shape[0] - 1 + di, 1 + dj : F.shape[1] - 1 + dj]
    seeds = S[1:-1, 1:-1][is_min]
    out: list[complex] = []
    for s0 in seeds:
        r = muller(f, complex(s0))
        if not (x0 - 0.1 <= r.real <= x1 + 0.1 and y0 - 0.1 <= r.imag <= y1 + 0.1):
            continue
        if abs(complex(f(np.asarray(r)))) > 1e-9 * (1.0 + np.max(F)):
            continue
        if all(abs(r - z) > 1e-7 for z in out):
            out.append(r)
    return np.asarray(out, dtype=np.complex128)


def argument_count(f: Func, box: tuple[float, float, float, float], points: int = 20000) -> float:
    """Winding number of f around the rectangle box, by dense sampling and np.unwrap."""
    x0, x1, y0, y1 = box
    t = np.linspace(0.0, 1.0, points, endpoint=False)
    corners = [complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1), complex(x0, y0)]
    path = np.concatenate([a + t * (b - a) for a, b in zip(corners[:-1], corners[1:])])
    path = np.append(path, corners[0])
    phase = np.unwrap(np.angle(f(path)))
    return float((phase[-1] - phase[0]) / (2.0 * np.pi))


def formation_function(topology: Topology, P: float, D: float, tau1: float, tau2: float) -> Func:
    """det of the characteristic matrix of eq. protocolss divided by s (the persistent zero removed)."""

    def f(s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        s = np.asarray(s, dtype=np.complex128)
        return full_characteristic(topology, P, D, s, tau1, tau2) / s

    return f


def reference_dominant_root(
    topology: Topology, P: float, D: float, tau1: float, tau2: float,
    box: tuple[float, float, float, float] = (-1.5, 1.0, -0.3, 3.0),
) -> complex:
    """Rightmost root of det(...)/s in box (Im >= 0 member), from the mesh and Muller."""
    f = formation_function(topology, P, D, tau1, tau2)
    roots = mesh_roots(f, box)
    top = roots[np.argmax(roots.real)]
    return complex(top.real, abs(top.imag))


def lambert_rightmost(a: float, b: float, tau: float, branches: int = 4) -> complex:
    """Rightmost root of s + a + b e^{-tau s} from the Lambert W function.

    s = W_k(-b tau e^{a tau}) / tau - a over branches k; the rightmost is
    taken over |k| <= branches (the principal branch for real arguments).
    """
    z = -b * tau * np.exp(a * tau)
    cands = [complex(lambertw(z, k)) / tau - a for k in range(-branches, branches + 1)]
    best = max(cands, key=lambda s: (round(s.real, 12), abs(s.imag)))
    return complex(best.real, abs(best.imag))
