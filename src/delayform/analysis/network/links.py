"""Per-link delays: their checks and the N x N matrix quasi-polynomial of the team.

With a delay per link, agent i hears informer k's position ``tau1[i, k]`` and
velocity ``tau2[i, k]`` old (the convention of
:mod:`delayform.model.network`: entry ``[i, k]`` is what i receives from k).
The paper's eq. 1 then reads

    x_i'' = -P x_i - D x_i' + sum_k C_ik (P x_k(t - tau1_ik) + D x_k'(t - tau2_ik)),

and the characteristic function is det M(s) with the N x N matrix

    M(s) = p(s) I - K(s),   p(s) = s^2 + D s + P,
    K_ik(s) = C_ik (P e^{-tau1_ik s} + D s e^{-tau2_ik s}).

With equal delays K(s) = C (P e^{-tau1 s} + D s e^{-tau2 s}) and det M(s) is the
product of the paper's eq. 3; with per-link delays it no longer factorizes. Because
the rows of C sum to one, M(0) = P (I - C) is singular for *every* assignment of
delays: the centroid's persistent root s = 0 of the paper's eq. 4 survives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_gains, real_numbers
from delayform.errors import DelayError, InputError
from delayform.topology import Topology

__all__ = ["LinkTeam", "link_team", "uniform_link_delays"]


@dataclass(frozen=True, eq=False)
class LinkTeam:
    """A team with one constant delay per link and stream (the data of the paper's eq. 1 per link).

    Attributes
    ----------
    C
        Dense N x N matrix C = Delta^-1 A (row i: what agent i receives).
    P, D
        The gains.
    rows, cols
        The links (receiver, informer), ``C[rows, cols] > 0``.
    weights
        ``C[rows, cols]``.
    tau1, tau2
        Delays of the links, aligned with ``rows`` / ``cols``.
    """

    C: NDArray[np.float64]
    P: float
    D: float
    rows: NDArray[np.int64]
    cols: NDArray[np.int64]
    weights: NDArray[np.float64]
    tau1: NDArray[np.float64]
    tau2: NDArray[np.float64]

    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.C.shape[0])

    @property
    def max_delay(self) -> float:
        """Longest delay of any link and stream."""
        return float(max(self.tau1.max(initial=0.0), self.tau2.max(initial=0.0)))

    def matrix(self, s: ArrayLike) -> NDArray[np.complex128]:
        """M(s) = p(s) I - K(s) at each s: shape ``s.shape + (N, N)``."""
        s = np.asarray(s, dtype=np.complex128)
        out = np.zeros(s.shape + (self.n, self.n), dtype=np.complex128)
        idx = np.arange(self.n)
        out[..., idx, idx] = (s * s + self.D * s + self.P)[..., None]
        sl = s[..., None]
        out[..., self.rows, self.cols] -= self.weights * (
            self.P * np.exp(-self.tau1 * sl) + self.D * sl * np.exp(-self.tau2 * sl)
        )
        return out

    def derivative(self, s: ArrayLike) -> NDArray[np.complex128]:
        """dM/ds at each s: shape ``s.shape + (N, N)``."""
        s = np.asarray(s, dtype=np.complex128)
        out = np.zeros(s.shape + (self.n, self.n), dtype=np.complex128)
        idx = np.arange(self.n)
        out[..., idx, idx] = (2.0 * s + self.D)[..., None]
        sl = s[..., None]
        e2 = np.exp(-self.tau2 * sl)
        out[..., self.rows, self.cols] -= self.weights * (
            -self.P * self.tau1 * np.exp(-self.tau1 * sl) + self.D * e2 - self.D * self.tau2 * sl * e2
        )
        return out

    def left_null_vector(self) -> NDArray[np.float64]:
        """w >= 0 with w^T C = w^T and sum w = 1 (the centroid's weights; C has a spanning tree)."""
        vals, vecs = np.linalg.eig(self.C.T)
        w = np.real(vecs[:, int(np.argmin(np.abs(vals - 1.0)))])
        w = w / w.sum()
        return np.where(np.abs(w) < 1e-14, 0.0, w)

    def zero_multiplicity(self) -> int:
        """Multiplicity of the persistent root s = 0 of det M (1, or 2 for the drift).

        With right null vector 1 and left null vector w of M(0) = P (I - C),
        d det M / ds (0) is proportional to w^T M'(0) 1 = P sum_i w_i sum_k C_ik tau1_ik:
        the zero is simple unless every position delay into an agent the centroid
        weighs is zero (the drift of the paper's eq. 4 on tau1 = 0).
        """
        w = self.left_null_vector()
        weighted = float(np.sum(w[self.rows] * self.weights * self.tau1))
        return 1 if weighted > 1e-14 * max(self.max_delay, 1.0) else 2


def _per_link(name: str, value: ArrayLike, n: int, mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    # booleans (True read as 1 s) and complex delays (the imaginary part dropped) are refused
    arr = real_numbers(name, value, DelayError, f"a delay or a {n} x {n} array of delays (real numbers)")
    if arr.ndim == 0:
        # one delay for every link: only the links need it (an N x N array would cost seconds for 5,000 agents)
        links = np.full(int(np.count_nonzero(mask)), float(arr))
    else:
        if arr.shape != (n, n):
            raise DelayError(f"{name} must be a {n} x {n} array of per-link delays, got shape {arr.shape}")
        links = arr[mask]
    if not np.all(np.isfinite(links)):
        raise DelayError(f"{name} must be finite on every link")
    if np.any(links < 0.0):
        raise DelayError(f"{name} must be non-negative on every link, found {links.min():g}")
    return links


def _require_dense(n: int) -> None:
    """Refuse a team whose N x N link matrices would not fit the machine (:mod:`delayform.resources`).

    Per-link analyses keep C dense (eight bytes an entry) beside the link mask (one);
    N x N delays given by the caller are the caller's memory.
    """
    from delayform.resources import require

    require(what=f"the per-link matrices of {n:,} agents ({n:,} x {n:,})",
            setting="the number of agents (topology.n, --n)", nbytes=9.0 * float(n) ** 2,
            seconds=2e-8 * float(n) ** 2)  # fmt: skip


def link_team(topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike) -> LinkTeam:
    """Check a team with per-link delays and gather it as a :class:`LinkTeam`.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    P, D
        Positive gains of the paper's eq. 1.
    tau1, tau2
        A delay for every link, or N x N arrays (entry ``[i, k]``: what i receives
        from k); entries where there is no link are ignored.

    Raises
    ------
    DelayError
        Wrong shape, or a negative or non-finite delay on a link.
    """
    if not isinstance(topology, Topology):
        raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
    topology.require_spanning_tree()
    P, D = check_gains(P, D)
    _require_dense(topology.n)
    C = np.asarray(topology.C_sparse.toarray(), dtype=np.float64)
    mask = C > 0.0
    rows, cols = np.nonzero(mask)
    t1 = _per_link("tau1", tau1, topology.n, mask)
    t2 = _per_link("tau2", tau2, topology.n, mask)
    return LinkTeam(C, P, D, rows.astype(np.int64), cols.astype(np.int64), C[mask], t1, t2)


def uniform_link_delays(topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike) -> tuple[float, float]:
    """The two delays of per-link arrays equal on every link, for the actuated factors; else DelayError.

    The per-link matrix quasi-polynomial has no actuation terms, so an
    actuation delay with delays that differ between links is refused rather
    than answered without it.

    Parameters
    ----------
    topology, P, D, tau1, tau2
        As for :func:`link_team`.

    Returns
    -------
    tuple of float
        ``(tau1, tau2)`` on every link (0.0 for a team without links).

    Raises
    ------
    DelayError
        When a delay differs between links, or as :func:`link_team` does.
    """
    team = link_team(topology, P, D, tau1, tau2)
    out = []
    for name, values in (("tau1", team.tau1), ("tau2", team.tau2)):
        if values.size and np.ptp(values) > 0.0:
            raise DelayError(
                f"actuation_delay with per-link {name} that differs between links "
                f"({values.min():g} to {values.max():g} s) is not solved: the per-link determinant has "
                "no actuation terms; give equal delays on every link or actuation_delay = 0"
            )
        out.append(float(values[0]) if values.size else 0.0)
    return out[0], out[1]
