"""A box of constant per-link delays, certified stable.

Question: is the team stable for *every* assignment of constant delays with
``tau1_ik in [lo1, hi1]`` and ``tau2_ik in [lo2, hi2]`` on every link, each link
free to take its own value?

Certificate (zero exclusion with a Perron bound)
------------------------------------------------
1. The centre of the box, tau-bar, is checked exactly
   (:func:`~delayform.analysis.network.per_link.dominant_of_team`).
2. The persistent root s = 0 is removed from det M without dividing by s: with
   u = w (the centroid's weights, u^T 1 = 1) and g(s) = M(s) 1 / s,

       Mh(s) = M(s) + (1 - s) g(s) u^T,   det Mh(s) = det M(s) / s,
       g_i(s) = s + D + P sum_k C_ik (1 - e^{-tau1_ik s}) / s - D sum_k C_ik e^{-tau2_ik s}

   (in the basis (1, V) with u^T V = 0, Mh only replaces the column M 1 = s g by g).
3. For s = i w and any assignment in the box, entry by entry (for w > 0 the same
   test on M itself, without the deflation term, is also valid and tighter)
   ``|Mh_tau(iw) - Mh_bar(iw)| <= B(w)`` with
   ``|e^{-iw tau} - e^{-iw bar}| <= beta(w h) = 2 sin(min(w h, pi) / 2)`` (h the half-width)
   and ``|(e^{-iw bar} - e^{-iw tau}) / (iw)| <= beta(w h) / w <= h``. If
   ``rho(|Mh_bar(iw)^{-1}| B(w)) < 1`` then ``Mh_bar^{-1} (Mh_tau - Mh_bar)`` has
   spectral radius below one (rho(X) <= rho(|X|), and rho is monotone on
   non-negative matrices), so Mh_tau(iw) is nonsingular for every assignment:
   the structured-singular-value bound with every link's delay an independent
   complex perturbation (Doyle 1982; for delays, the frequency-sweeping tests of
   Chen, Gu & Nett 1995, and the per-link heterogeneous conditions of
   Lestas & Vinnicombe 2006 and Muenz, Papachristodoulou & Allgoewer 2010 are
   the same zero-exclusion idea on the Nyquist plane).
4. Between frequency samples a closed-form bound ``L`` on |d Mh_tau / dw| over the
   box widens B by ``L (w_b - w_a)``; past ``Omega`` (the root of
   w^3 - 2 P w - 2 P D, where |p(iw)| > P + D w >= ||K(iw)||_inf) M itself is
   row-diagonally dominant, so the whole axis is covered.
5. The box is connected and the roots of a retarded quasi-polynomial move
   continuously with the delays and cannot come from infinity into Re s >= 0, so
   none crosses the imaginary axis anywhere in the box: every assignment is
   stable when the centre is.

When the bound fails somewhere the box is *undecided*, and corners plus random
assignments are checked exactly; an unstable one makes the answer *unstable*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.network.links import LinkTeam, link_team
from delayform.analysis.network.per_link import dominant_of_team, require_seed_search
from delayform._validation import FloatOrNaN, check_count, validated
from delayform.errors import DelayError, NotConvergedError
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["RobustStability", "robust_stability"]

#: Most frequency samples spent on one box.
MAX_SAMPLES = 100_000


@validated()
@dataclass(frozen=True, eq=False)
class RobustStability:
    """Whether every constant per-link assignment in a box of delays is stable.

    Attributes
    ----------
    status
        ``"certified"`` (every assignment stable, proven), ``"unstable"`` (an
        unstable assignment was found, see ``witness``) or ``"undecided"``.
    method
        How the answer was reached.
    reason
        Why it is not certified ("" when it is).
    tau1, tau2
        The box, (lo, hi) per stream (arrays per link when given so).
    margin
        1 - max over frequency of the Perron bound (> 0 when certified).
    worst_frequency
        The frequency (rad/s) where the Perron bound is largest; NaN where
        the centre is unstable (no bound is computed).
    witness
        An unstable assignment found (per-link arrays tau1, tau2), or None.
    witness_root
        Its dominant root.
    checked
        How many assignments were checked exactly.
    """

    status: Literal["certified", "unstable", "undecided"]
    method: str
    reason: str
    tau1: tuple[NDArray[np.float64], NDArray[np.float64]]
    tau2: tuple[NDArray[np.float64], NDArray[np.float64]]
    margin: float
    worst_frequency: FloatOrNaN
    witness: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
    witness_root: complex | None = None
    checked: int = 0

    @property
    def certified(self) -> bool:
        """True only when every assignment in the box is proven stable."""
        return self.status == "certified"

    def plot(self, ax: Axes | None = None) -> Axes:
        """The box in the (tau1, tau2) plane, coloured by the answer (link ranges as a rectangle)."""
        import matplotlib.pyplot as plt
        from matplotlib.patches import Rectangle

        if ax is None:
            ax = plt.figure().add_subplot()
        lo1, hi1 = float(self.tau1[0].min()), float(self.tau1[1].max())
        lo2, hi2 = float(self.tau2[0].min()), float(self.tau2[1].max())
        colour = {"certified": "tab:green", "unstable": "tab:red"}.get(self.status, "tab:orange")
        ax.add_patch(Rectangle((lo1, lo2), hi1 - lo1, hi2 - lo2, fc=colour, alpha=0.35, ec=colour, label=self.status))
        ax.autoscale_view()
        ax.set_xlabel("tau1 (s)")
        ax.set_ylabel("tau2 (s)")
        ax.legend(loc="best", fontsize="small")
        return ax


def _beta(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """max |e^{-i t} - 1| over |t| <= x."""
    return 2.0 * np.sin(0.5 * np.minimum(x, math.pi))


def _omega_tail(P: float, D: float) -> float:
    """Past this frequency |p(iw)| > P + D w: M(iw) is row-diagonally dominant for every delay."""
    roots = np.roots([1.0, 0.0, -2.0 * P, -2.0 * P * D])
    return 1.01 * float(np.max(roots[np.abs(roots.imag) < 1e-9].real)) + 1e-9


class DelayBox:
    """The centre team and the per-link half-widths and upper ends of a box."""

    def __init__(self, centre: LinkTeam, h1: NDArray[np.float64], h2: NDArray[np.float64],
                 hi1: NDArray[np.float64], hi2: NDArray[np.float64]) -> None:  # fmt: skip
        self.t, self.h1, self.h2, self.hi1, self.hi2 = centre, h1, h2, hi1, hi2
        self.u = centre.left_null_vector()

    def _rows(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.bincount(self.t.rows, self.t.weights * v, minlength=self.t.n)

    def centre_matrix(self, w: NDArray[np.float64]) -> NDArray[np.complex128]:
        """Mh(iw) of the centre (module docstring, step 2)."""
        t = self.t
        s = 1j * w
        M = t.matrix(s)
        sl = s[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.where(np.abs(sl) > 0, (1.0 - np.exp(-t.tau1 * sl)) / sl, t.tau1 + 0j)
        into = np.zeros((t.rows.size, t.n))
        into[np.arange(t.rows.size), t.rows] = 1.0  # link -> its receiver: row sums as one product
        g = (s + t.D)[:, None] + (t.weights * (t.P * phi - t.D * np.exp(-t.tau2 * sl))) @ into
        return M + ((1.0 - s)[:, None] * g)[:, :, None] * self.u[None, None, :]

    def perturbation(self, w: float) -> NDArray[np.float64]:
        """B(w): entrywise bound of Mh_tau(iw) - Mh_bar(iw) over the box."""
        t = self.t
        b1, b2 = _beta(w * self.h1), _beta(w * self.h2)
        B = np.zeros((t.n, t.n))
        B[t.rows, t.cols] = t.weights * (t.P * b1 + t.D * w * b2)
        d1 = np.where(w > 0, b1 / max(w, 1e-300), self.h1)
        dg = self._rows(t.P * d1 + t.D * b2)
        return B + abs(1.0 - 1j * w) * np.outer(dg, np.abs(self.u))

    def plain_perturbation(self, w: float) -> NDArray[np.float64]:
        """Entrywise bound of M_tau(iw) - M_bar(iw) over the box (no deflation term)."""
        t = self.t
        B = np.zeros((t.n, t.n))
        B[t.rows, t.cols] = t.weights * (t.P * _beta(w * self.h1) + t.D * w * _beta(w * self.h2))
        return B

    def plain_lipschitz(self, wb: float) -> NDArray[np.float64]:
        """Entrywise bound of |d M_tau(iw) / dw| for w <= wb over the box."""
        t = self.t
        L = np.zeros((t.n, t.n))
        L[np.arange(t.n), np.arange(t.n)] = 2.0 * wb + t.D
        L[t.rows, t.cols] += t.weights * (t.P * self.hi1 + t.D * (1.0 + wb * self.hi2))
        return L

    def lipschitz_stack(self, wb: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`lipschitz` at every entry of ``wb`` at once: shape ``wb.shape + (N, N)``."""
        t = self.t
        wb = np.asarray(wb, dtype=np.float64)[..., None, None]
        n = np.arange(t.n)
        L = np.zeros(wb.shape[:-2] + (t.n, t.n))
        L[..., n, n] = 2.0 * wb[..., 0] + t.D
        L[..., t.rows, t.cols] += t.weights * (t.P * self.hi1 + t.D * (1.0 + wb[..., 0] * self.hi2))
        g = wb[..., 0] + t.D + self._rows(t.P * self.hi1 + t.D)
        dg = 1.0 + self._rows(0.5 * t.P * self.hi1**2 + t.D * self.hi2)
        return L + (g + np.hypot(1.0, wb[..., 0]) * dg)[..., :, None] * np.abs(self.u)

    def lipschitz(self, wb: float) -> NDArray[np.float64]:
        """Entrywise bound of |d Mh_tau(iw) / dw| for w <= wb over the box (one frequency of :meth:`lipschitz_stack`)."""
        return self.lipschitz_stack(np.asarray(wb, dtype=np.float64))


def _spectral_radius(X: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.max(np.abs(np.linalg.eigvals(X)), axis=-1)


def _bounds(box: DelayBox, w: NDArray[np.float64], deflated: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Perron bounds at the samples and on the pieces between them, with Mh (deflated) or M itself."""
    if deflated:
        C, pert, lip = box.centre_matrix(w), box.perturbation, box.lipschitz
    else:
        C, pert, lip = box.t.matrix(1j * w), box.plain_perturbation, box.plain_lipschitz
    with np.errstate(all="ignore"):
        det = np.abs(np.linalg.det(C))
        good = np.isfinite(det) & (det > 0.0)
        A = np.full(C.shape, np.inf)
        if good.any():
            A[good] = np.abs(np.linalg.inv(C[good]))
        B = np.stack([pert(float(x)) for x in w])
        Ls = np.stack([lip(float(b)) for b in w[1:]])
        point = np.full(w.size, np.inf)
        point[good] = _spectral_radius(A[good] @ B[good])
        piece = np.full(w.size - 1, np.inf)
        ok = good[:-1]
        piece[ok] = _spectral_radius(A[:-1][ok] @ (B[:-1][ok] + (Ls * np.diff(w)[:, None, None])[ok]))
    return point, piece


def box_certificate(box: DelayBox) -> tuple[bool, float, float, str]:
    """The frequency sweep of steps 3 and 4: (certified, margin, worst frequency, reason).

    Each piece passes with the bound of Mh, or with that of M itself (valid away
    from w = 0, where M(0) is singular, and tighter there: no deflation term).
    """
    Omega = _omega_tail(box.t.P, box.t.D)
    w = np.linspace(0.0, Omega, 257)
    while True:
        point_h, piece_h = _bounds(box, w, True)
        point_m, piece_m = _bounds(box, w, False)
        point, piece = np.minimum(point_h, point_m), np.minimum(piece_h, piece_m)
        k = int(np.argmax(point))
        if not point[k] < 1.0:
            return False, 1.0 - float(point[k]), float(w[k]), (
                f"the Perron bound of the box reaches {point[k]:.3g} >= 1 at w = {w[k]:.3g} rad/s: "
                "the box is too wide for this certificate there"
            )
        bad = ~(piece < 1.0)
        if not bad.any():
            return True, 1.0 - float(max(piece.max(), point.max())), float(w[k]), ""
        if w.size > MAX_SAMPLES:
            return False, 1.0 - float(point.max()), float(w[k]), "the frequency sweep ran out of samples"
        w = np.sort(np.concatenate([w, 0.5 * (w[:-1] + w[1:])[bad]]))


def _ends(name: str, value: object) -> tuple[ArrayLike, ArrayLike]:
    try:
        lo, hi = value  # type: ignore[misc]
    except (TypeError, ValueError):
        raise DelayError(f"{name} must be a pair (lo, hi) of delays or of N x N arrays") from None
    return lo, hi


@validated()
def robust_stability(
    topology: Topology,
    P: float,
    D: float,
    tau1: tuple[ArrayLike, ArrayLike],
    tau2: tuple[ArrayLike, ArrayLike],
    *,
    samples: int = 24,
    seed: int = 0,
) -> RobustStability:
    """Is the team stable for every assignment of constant per-link delays in the box?

    Parameters
    ----------
    topology, P, D
        The team and its gains (as for :func:`~delayform.analysis.network.links.link_team`).
    tau1, tau2
        ``(lo, hi)``: scalars, or N x N arrays per link (entries without a link ignored).
    samples
        Random assignments checked exactly when the box is not certified (plus its corners).
    seed
        Seed of those draws.

    Returns
    -------
    RobustStability
        ``certified`` only when proven (module docstring); never True where an
        assignment in the box is unstable.

    Raises
    ------
    DelayError
        Malformed ends, negative or non-finite delays, or lo > hi on a link.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> robust_stability(paper_six(), 1.0, 0.5, (0.95, 1.05), (0.45, 0.55)).certified
    True
    """
    lo1, hi1 = _ends("tau1", tau1)
    lo2, hi2 = _ends("tau2", tau2)
    low = link_team(topology, P, D, lo1, lo2)
    high = link_team(topology, P, D, hi1, hi2)
    for name, a, b in (("tau1", low.tau1, high.tau1), ("tau2", low.tau2, high.tau2)):
        if np.any(a > b):
            raise DelayError(f"{name}: the box has lo > hi on a link ({a[a > b][0]:g} > {b[a > b][0]:g})")
    samples = check_count("samples", samples)
    # the corners of the box are solved exactly when it is not certified: the longest delays decide
    require_seed_search(high, -0.5)
    centre = replace(low, tau1=0.5 * (low.tau1 + high.tau1), tau2=0.5 * (low.tau2 + high.tau2))
    ends1, ends2 = (low.tau1, high.tau1), (low.tau2, high.tau2)
    nominal = dominant_of_team(centre)
    if not nominal.is_stable:
        return RobustStability("unstable", "exact per-link roots at the centre", "the centre of the box is unstable",
                               ends1, ends2, -math.inf, float("nan"), (_full(centre, centre.tau1), _full(centre, centre.tau2)),
                               nominal.root, 1)  # fmt: skip
    box = DelayBox(centre, 0.5 * (high.tau1 - low.tau1), 0.5 * (high.tau2 - low.tau2), high.tau1, high.tau2)
    ok, margin, worst, reason = box_certificate(box)
    method = "zero exclusion on the imaginary axis with a Perron bound per link (docs/theory.md)"
    if ok:
        return RobustStability("certified", method, "", ends1, ends2, margin, worst, checked=1)
    rng = np.random.default_rng(seed)
    n_links = centre.rows.size
    corners = [(np.full(n_links, a), np.full(n_links, b)) for a in (0.0, 1.0) for b in (0.0, 1.0)]
    draws = corners + [(rng.random(n_links), rng.random(n_links)) for _ in range(samples)]
    checked = 1
    for f1, f2 in draws:
        t1 = low.tau1 + f1 * (high.tau1 - low.tau1)
        t2 = low.tau2 + f2 * (high.tau2 - low.tau2)
        try:
            r = dominant_of_team(replace(centre, tau1=t1, tau2=t2))
        except NotConvergedError:  # an assignment that could not be certified is no witness either way
            continue
        checked += 1
        if not r.is_stable:
            return RobustStability("unstable", "an unstable assignment found by exact per-link roots", reason,
                                   ends1, ends2, margin, worst, (_full(centre, t1), _full(centre, t2)), r.root, checked)  # fmt: skip
    return RobustStability("undecided", method, f"cannot decide: {reason}; {checked} assignments checked exactly were stable",
                           ends1, ends2, margin, worst, checked=checked)  # fmt: skip


def _full(team: LinkTeam, values: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.zeros((team.n, team.n))
    out[team.rows, team.cols] = values
    return out
