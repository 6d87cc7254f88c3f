"""Certificates for classes of teams: the delays safe for every spectrum in a set.

A team is stable at (tau1, tau2) exactly when every eigenvalue of its C lies
in the stable region of the eigenvalue plane (:mod:`delayform.analysis.plane.region`),
the centroid's root s = 0 aside. So a delay pair is *safe for a set S* of
eigenvalues when S (minus the centroid eigenvalue 1) lies in the region, and
then every team whose spectrum lies in S is stable there, whatever its size or
graph. S is a real interval [a, b] (``"undirected"`` is [-1, 1]: C = Delta^-1 A
of an undirected graph is similar to the symmetric Delta^-1/2 A Delta^-1/2) or
a closed disc (``"any"`` is the unit disc, which holds the spectrum of every
row-stochastic C).

The construction (exact pointwise; see docs/theory.md)
-------------------------------------------------------
NU(lam) only changes where lam crosses the boundary curve ``L(j omega)``, so S
lies in the region exactly when NU = 0 at one point of S (its *base*: the left
end a of an interval, the centre of a disc) and the curve does not meet S
(the point 1 aside):

* **Base.** NU of the factor ``q(s, base)`` is read from the exact CTCR map of
  that factor (:func:`~delayform.analysis.ctcr.stability_map.crossing_map`).
* **Interval [a, b].** ``L(j omega) - 1 = j omega m(j omega) / b(j omega)`` with
  ``m(s) = s - D expm1(-tau2 s) - P expm1(-tau1 s) / s`` (smooth at 0), so the
  real points of the curve other than L(0) = 1 are the zeros of
  ``r(omega) = Re(m conj b)`` for omega > 0, with
  ``Re L = 1 - omega Im(m conj b) / |b|^2``. The curve meets (a, b) exactly when r
  has a zero where ``(1 - a)|b|^2 - omega Im(m conj b) > 0`` and
  ``(1 - b)|b|^2 - omega Im(m conj b) < 0``.
* **Disc |lam - c| <= rho.** The curve meets the disc exactly where
  ``k(omega) = |a - c b|^2 - rho^2 |b|^2 <= 0``. When 1 lies on the circle
  (it always lies on the curve, at omega = 0) and c is real, both are tangent
  there and the curve leaves 1 outward exactly when
  ``tau1^2 - 2 rho Re L2 > 0``, ``L2 = (1 - D tau1 + D tau2) / P + tau1^2 / 2``
  the second Taylor coefficient of L at 0; for the unit disc this is
  ``D (tau1 - tau2) > 1``. A disc with 1 inside, or with 1 on its circle and c
  not real, is never safe (real lam > 1 has an unstable real root; a curve
  crossing the circle at 1 enters the disc).

The chart draws the boundary: the CTCR curves of the base factors and the
envelope of the CTCR curves of the set's family of eigenvalues (the interior
of an interval, the circle of a disc), where an eigenvalue of the family
gets an imaginary root that does not move under a change of the eigenvalue
along the family (:mod:`delayform.analysis.plane.envelope`).

Each condition is decided on omega in [0, omega_max] (beyond which |L| exceeds
every |lam| of S) by *certified* sampling: on a sample interval of width h a
function with the Lipschitz bound Lip (closed-form bounds on |m|, |m'|, |b|,
|b'| there) has no zero when ``|f(l)| + |f(r)| > Lip h``; intervals are halved
until each is certified empty, certified to hold a witness (a sign change
with the other conditions certain), or narrower than 1e-10 omega_max. Such
undecided points are reported as not safe, so "safe" is always certified;
:attr:`SafeDelayMap.undecided` tells how many there were.

References
----------
Cepeda-Gomez and Perico, Lemma 1 (paper, eq. 3), the paper's eq. 4, Lemma 2;
Section "Stability Analysis Using CTCR".
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import check_delay_array, check_gains, check_positive, validated
from delayform.analysis.plane.boundary_curve import omega_limit
from delayform.analysis.ctcr.stability_map import StabilityMap, lam_factor, crossing_map
from delayform.analysis.plane.envelope import envelope_of_family, tangency_parabola
from delayform.errors import DelayError, InputError
from delayform.resources import require

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = [
    "SpectrumSet",
    "SafeDelayMap",
    "safe_delays",
    "parse_spectrum",
    "omega_limit",  # from delayform.analysis.plane.boundary_curve
]

_MIN_WIDTH = 1e-10
_MAX_ROUNDS = 60
_SAMPLES = 96
#: omega below which the tangency at lam = 1 is decided by its Taylor coefficient.
_W_EPS = 1e-4


# ===================================================================== spectrum sets
@validated()
@dataclass(frozen=True)
class SpectrumSet:
    """A closed set of the eigenvalue plane: a real interval or a disc.

    Attributes
    ----------
    kind
        ``"interval"`` (real eigenvalues in [low, high]) or ``"disc"``
        (``|lam - center| <= radius``).
    low, high
        Ends of the interval (kind "interval").
    center, radius
        Centre and radius of the disc (kind "disc").
    label
        How it is named in tables and figures.
    """

    kind: str
    low: float = 0.0
    high: float = 0.0
    center: complex = 0j
    radius: float = 0.0
    label: str = ""

    @classmethod
    def interval(cls, low: float, high: float, label: str | None = None) -> SpectrumSet:
        """The real eigenvalues in [low, high].

        Parameters
        ----------
        low, high
            Ends, ``low < high``, finite.
        label
            Name in tables; default ``"interval [low, high]"``.
        """
        lo, hi = _finite("interval low", low), _finite("interval high", high)
        if not lo < hi:
            raise InputError(f"an interval needs low < high, got [{lo:g}, {hi:g}]")
        return cls("interval", low=lo, high=hi, label=label or f"interval [{lo:g}, {hi:g}]")

    @classmethod
    def disc(cls, center: complex, radius: float, label: str | None = None) -> SpectrumSet:
        """The closed disc ``|lam - center| <= radius``.

        Parameters
        ----------
        center
            Centre (complex).
        radius
            Positive radius.
        label
            Name in tables; default ``"disc |lam - c| <= r"``.
        """
        if isinstance(center, bool) or not isinstance(center, (numbers.Complex, np.number)):
            raise InputError(f"disc center must be a number, got {center!r}")
        c = complex(center)
        if not np.isfinite(c):
            raise InputError("disc center must be finite")
        r = check_positive("disc radius", radius)
        return cls("disc", center=c, radius=r, label=label or f"disc |lam - {_fmt(c)}| <= {r:g}")

    def contains(self, lam: ArrayLike) -> NDArray[np.bool_]:
        """True for the eigenvalues inside the set (boundary included, 1e-12 slack).

        Parameters
        ----------
        lam
            Complex values, any shape.
        """
        z = np.asarray(lam, dtype=complex)
        if self.kind == "interval":
            tol = 1e-12 * max(1.0, abs(self.low), abs(self.high))
            return (np.abs(z.imag) <= tol) & (z.real >= self.low - tol) & (z.real <= self.high + tol)
        return np.abs(z - self.center) <= self.radius * (1.0 + 1e-12)

    @property
    def base(self) -> complex:
        """The point of the set where NU is read from the CTCR map (left end or centre)."""
        return complex(self.low) if self.kind == "interval" else self.center

    @property
    def outer_radius(self) -> float:
        """Largest |lam| in the set."""
        if self.kind == "interval":
            return max(abs(self.low), abs(self.high))
        return abs(self.center) + self.radius


def _fmt(c: complex) -> str:
    return f"{c.real:g}" if c.imag == 0 else f"({c.real:g}{c.imag:+g}j)"


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        raise InputError(f"{name} must be a real number, got {value!r}")
    out = float(value)
    if not np.isfinite(out):
        raise InputError(f"{name} must be finite, got {out}")
    return out


UNDIRECTED = SpectrumSet("interval", low=-1.0, high=1.0, label="undirected: real spectrum in [-1, 1]")
ANY = SpectrumSet("disc", center=0j, radius=1.0, label="any: closed unit disc")


def parse_spectrum(spectrum: object) -> SpectrumSet:
    """A spectrum set from what :func:`safe_delays` accepts.

    Parameters
    ----------
    spectrum
        ``"undirected"``, ``"any"``, ``"interval:a,b"``, ``"disc:c,r"`` (c real)
        or ``"disc:re,im,r"``, a :class:`SpectrumSet`, or any object with a
        ``spectrum_set`` attribute (a :class:`~delayform.analysis.plane.spectrum_bounds.SpectrumBound`).

    Returns
    -------
    SpectrumSet

    Raises
    ------
    InputError
        For anything else.

    Examples
    --------
    >>> parse_spectrum("interval:-0.5,0.9").label
    'interval [-0.5, 0.9]'
    """
    if isinstance(spectrum, SpectrumSet):
        return spectrum
    inner = getattr(spectrum, "spectrum_set", None)
    if isinstance(inner, SpectrumSet):
        return inner
    if not isinstance(spectrum, str):
        raise InputError(f"spectrum must be 'undirected', 'any', 'interval:a,b', 'disc:c,r' or a SpectrumSet, got {spectrum!r}")
    text = spectrum.strip().lower()
    if text == "undirected":
        return UNDIRECTED
    if text == "any":
        return ANY
    kind, sep, rest = text.partition(":")
    try:
        values = [float(v) for v in rest.split(",")] if sep else []
    except ValueError:
        raise InputError(f"spectrum {spectrum!r}: expected numbers after '{kind}:'") from None
    if kind == "interval" and len(values) == 2:
        return SpectrumSet.interval(*values)
    if kind == "disc" and len(values) == 2:
        return SpectrumSet.disc(values[0], values[1])
    if kind == "disc" and len(values) == 3:
        return SpectrumSet.disc(complex(values[0], values[1]), values[2])
    raise InputError(
        f"spectrum {spectrum!r}: expected 'undirected', 'any', 'interval:a,b', 'disc:c,r' or 'disc:re,im,r'"
    )


# ===================================================================== the functions on omega
def _parts(P: float, D: float, t1: NDArray, t2: NDArray, w: NDArray) -> tuple[NDArray, NDArray]:
    """m(j w) and b(j w), with ``a - b = s m`` (expm1 keeps m accurate at small omega)."""
    s = 1j * w
    z1 = -t1 * s
    with np.errstate(invalid="ignore", divide="ignore"):
        phi1 = np.where(z1 == 0, 1.0 + 0j, np.expm1(z1) / np.where(z1 == 0, 1.0, z1))
    m = s - D * np.expm1(-t2 * s) + P * t1 * phi1
    b = D * s * np.exp(-t2 * s) + P * np.exp(-t1 * s)
    return m, b


def _bounds(P: float, D: float, t1: NDArray, t2: NDArray, w: NDArray) -> tuple[NDArray, ...]:
    """Upper bounds of |m|, |dm/domega|, |b|, |db/domega| for |omega| <= w."""
    m = w + D * np.minimum(2.0, t2 * w) + P * t1
    dm = 1.0 + D * t2 + 0.5 * P * t1 * t1
    b = P + D * w
    db = D + D * t2 * w + P * t1
    return m, dm, b, db


@dataclass
class _Scan:
    """Pending intervals of every point: point index, ends and end values."""

    pid: NDArray[np.int64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    flo: NDArray[np.float64]
    fhi: NDArray[np.float64]


def _interval_values(P: float, D: float, t1: NDArray, t2: NDArray, w: NDArray, a: float, b: float) -> NDArray:
    """(r, g_a, g_b) at omega: r = 0 at a real point of the curve, Re L > a iff g_a > 0, Re L < b iff g_b < 0."""
    m, bb = _parts(P, D, t1, t2, w)
    mb = m * np.conj(bb)
    b2 = np.abs(bb) ** 2
    return np.stack([mb.real, (1.0 - a) * b2 - w * mb.imag, (1.0 - b) * b2 - w * mb.imag], axis=-1)


def _interval_lips(P: float, D: float, t1: NDArray, t2: NDArray, wmax: NDArray, a: float, b: float) -> NDArray:
    """Lipschitz bounds in omega of (r, g_a, g_b) on intervals ending at ``wmax``."""
    m, dm, bb, db = _bounds(P, D, t1, t2, wmax)
    lr = dm * bb + m * db
    lg = 2.0 * bb * db * max(abs(1.0 - a), abs(1.0 - b)) + m * bb + wmax * lr
    return np.stack([lr, lg, lg], axis=-1)


def _interval_decide(fl: NDArray, fr: NDArray, lip: NDArray, h: NDArray) -> NDArray[np.int64]:
    """0: certified no real point in (a, b); 1: certified one; 2: halve."""
    lh = lip * h[:, None]
    no_zero = np.abs(fl[:, 0]) + np.abs(fr[:, 0]) > lh[:, 0]
    below = 0.5 * (fl[:, 1] + fr[:, 1] + lh[:, 1]) <= 0.0   # Re L <= a throughout
    above = 0.5 * (fl[:, 2] + fr[:, 2] - lh[:, 2]) >= 0.0   # Re L >= b throughout
    inside = (0.5 * (fl[:, 1] + fr[:, 1] - lh[:, 1]) > 0.0) & (0.5 * (fl[:, 2] + fr[:, 2] + lh[:, 2]) < 0.0)
    witness = (fl[:, 0] * fr[:, 0] < 0.0) & inside
    out = np.full(fl.shape[0], 2, np.int64)
    out[no_zero | below | above] = 0
    out[witness] = 1
    return out


def _disc_values(
    P: float, D: float, t1: NDArray, t2: NDArray, w: NDArray, c: complex, rho: float, through_one: bool
) -> NDArray:
    """k(omega) = |a - c b|^2 - rho^2 |b|^2 (<= 0 where the curve is in the disc), as a last axis of length 1."""
    m, bb = _parts(P, D, t1, t2, w)
    if through_one:
        # a - c b = s m + (1 - c) b and |1 - c| = rho: k = w^2 |m|^2 - 2 w Im(m conj((1 - c) b))
        k = w * w * np.abs(m) ** 2 - 2.0 * w * (m * np.conj((1.0 - c) * bb)).imag
    else:
        a = 1j * w * m + bb
        k = np.abs(a - c * bb) ** 2 - rho * rho * np.abs(bb) ** 2
    return k[..., None]


def _disc_lips(
    P: float, D: float, t1: NDArray, t2: NDArray, wmax: NDArray, c: complex, rho: float, through_one: bool
) -> NDArray:
    """Lipschitz bound in omega of k on intervals ending at ``wmax``."""
    m, dm, bb, db = _bounds(P, D, t1, t2, wmax)
    if through_one:
        # k = w kt with kt = w |m|^2 - 2 Im(m conj((1 - c) b)) odd in w (c real), so |kt| <= w sup|kt'|
        # and |k'| <= |kt| + w |kt'| <= 2 w sup|kt'|: small next to omega = 0, where k ~ w^2
        dkt = m * m + 2.0 * wmax * m * dm + 2.0 * abs(1.0 - c) * (dm * bb + m * db)
        return (2.0 * wmax * dkt)[..., None]
    amb = wmax * m + abs(1.0 - c) * bb                       # |a - c b| = |s m + (1 - c) b|
    d_amb = m + wmax * dm + abs(1.0 - c) * db
    lip = 2.0 * amb * d_amb + 2.0 * rho * rho * bb * db
    return lip[..., None]


def _disc_decide(fl: NDArray, fr: NDArray, lip: NDArray, h: NDArray) -> NDArray[np.int64]:
    out = np.full(fl.shape[0], 2, np.int64)
    out[0.5 * (fl[:, 0] + fr[:, 0] - lip[:, 0] * h) > 0.0] = 0
    out[(fl[:, 0] < 0.0) | (fr[:, 0] < 0.0)] = 1
    return out


def _certified_scan(
    values: Any, lips: Any, decide: Any, t1: NDArray, t2: NDArray, w_lo: float, w_hi: float
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Per point: (witness found, undecided) over omega in [w_lo, w_hi] (see module docstring)."""
    n = t1.size
    witness = np.zeros(n, bool)
    undecided = np.zeros(n, bool)
    if n == 0:
        return witness, undecided
    grid = np.linspace(w_lo, w_hi, _SAMPLES + 1)
    vals = values(t1[:, None], t2[:, None], grid[None, :])            # (n, S+1, k)
    pid = np.repeat(np.arange(n), _SAMPLES)
    scan = _Scan(pid, np.tile(grid[:-1], n), np.tile(grid[1:], n),
                 vals[:, :-1].reshape(n * _SAMPLES, -1), vals[:, 1:].reshape(n * _SAMPLES, -1))
    min_width = _MIN_WIDTH * max(w_hi, 1.0)
    for _ in range(_MAX_ROUNDS):
        if scan.pid.size == 0:
            break
        h = scan.hi - scan.lo
        lip = lips(t1[scan.pid], t2[scan.pid], scan.hi)
        verdict = decide(scan.flo, scan.fhi, lip, h)
        witness[scan.pid[verdict == 1]] = True
        split = (verdict == 2) & ~witness[scan.pid]
        tiny = split & (h < min_width)
        undecided[scan.pid[tiny]] = True
        split &= ~tiny & ~undecided[scan.pid]
        if not np.any(split):
            scan = _Scan(scan.pid[:0], scan.lo[:0], scan.hi[:0], scan.flo[:0], scan.fhi[:0])
            break
        p, lo, hi, flo, fhi = scan.pid[split], scan.lo[split], scan.hi[split], scan.flo[split], scan.fhi[split]
        mid = 0.5 * (lo + hi)
        fm = values(t1[p], t2[p], mid)
        scan = _Scan(np.concatenate([p, p]), np.concatenate([lo, mid]), np.concatenate([mid, hi]),
                     np.concatenate([flo, fm]), np.concatenate([fm, fhi]))
    undecided[scan.pid] = True
    undecided &= ~witness
    return witness, undecided


# ===================================================================== the result
@validated()
@dataclass(frozen=True, eq=False)
class SafeDelayMap(FigureRepr):
    """Delay pairs at which every team whose spectrum lies in a set is stable.

    Attributes
    ----------
    P, D
        Gains of the paper's eq. 1.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max].
    spectrum
        The set S of eigenvalues covered.
    base_maps
        Exact CTCR maps of the factors at the ends of an interval (or the
        centre of a disc): their curves bound the safe set where an end of S
        becomes unstable.
    never_safe
        A reason when no delay pair can be safe for S (e.g. S holds real lam > 1), else "".
    """

    P: float
    D: float
    tau1_max: float
    tau2_max: float
    spectrum: SpectrumSet
    base_maps: tuple[StabilityMap, ...]
    never_safe: str = ""
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def envelope(self) -> tuple[NDArray[np.float64], ...]:
        """Polylines ``(k, 2)`` (columns tau1, tau2) of the envelope of the set's family (computed on first use).

        The envelope of the CTCR curves of the interior eigenvalues of an
        interval (or of the circle of a disc, and its tangency at 1): where an
        eigenvalue inside the set becomes unstable before its ends (its base).
        Empty when no pair can be safe, or when the window would need more
        than :data:`MAX_LATTICE_IMAGES` lattice images (see :attr:`envelope_note`).
        """
        if "envelope" not in self._cache:
            images = _lattice_images(self.P, self.D, self.spectrum, self.tau1_max, self.tau2_max)
            if self.never_safe or images > MAX_LATTICE_IMAGES:
                self._cache["envelope"] = ()
            else:
                self._cache["envelope"] = _set_envelope(self.spectrum, self.P, self.D, self.tau1_max, self.tau2_max)
        return self._cache["envelope"]

    @property
    def envelope_note(self) -> str:
        """Why the envelope is not drawn, or "" when it is."""
        images = _lattice_images(self.P, self.D, self.spectrum, self.tau1_max, self.tau2_max)
        if images > MAX_LATTICE_IMAGES:
            return f"envelope not drawn: the window needs {images} lattice images (at most {MAX_LATTICE_IMAGES})"
        return ""

    def _classify(self, tau1: ArrayLike, tau2: ArrayLike) -> tuple[NDArray[np.bool_], NDArray[np.bool_], tuple[int, ...]]:
        t1 = check_delay_array("tau1", tau1)
        t2 = check_delay_array("tau2", tau2)
        x, y = np.broadcast_arrays(t1, t2)
        shape = x.shape
        x, y = x.ravel().astype(float), y.ravel().astype(float)
        if np.any(x > self.tau1_max * (1 + 1e-12)) or np.any(y > self.tau2_max * (1 + 1e-12)):
            raise DelayError(f"delays must lie in the window [0, {self.tau1_max:g}] x [0, {self.tau2_max:g}]")
        safe = np.zeros(x.size, bool)
        undecided = np.zeros(x.size, bool)
        if self.never_safe or x.size == 0:
            return safe, undecided, shape
        ok = np.ones(x.size, bool)
        for m in self.base_maps:
            ok &= m.unstable_count(x, y) == 0
        idx = np.flatnonzero(ok)
        S = self.spectrum
        P, D = self.P, self.D
        wmax = omega_limit(P, D, S.outer_radius)
        if S.kind == "interval":
            a, b = S.low, S.high
            wit, und = _certified_scan(
                lambda p, q, w: _interval_values(P, D, p, q, w, a, b),
                lambda p, q, w: _interval_lips(P, D, p, q, w, a, b),
                _interval_decide, x[idx], y[idx], 0.0, wmax,
            )
        else:
            wit, und = self._disc_scan(x[idx], y[idx], wmax)
        safe[idx] = ~wit & ~und
        undecided[idx] = und
        return safe, undecided, shape

    def _disc_scan(self, x: NDArray, y: NDArray, wmax: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        S, P, D = self.spectrum, self.P, self.D
        c, rho = S.center, S.radius
        through = abs(abs(1.0 - c) - rho) <= 1e-12 * max(1.0, rho)
        vals = lambda p, q, w: _disc_values(P, D, p, q, w, c, rho, through)  # noqa: E731
        lips = lambda p, q, w: _disc_lips(P, D, p, q, w, c, rho, through)  # noqa: E731
        if not through:
            wit = np.zeros(x.size, bool)
            und = np.zeros(x.size, bool)
            for lo, hi in ((-wmax, 0.0), (0.0, wmax)) if c.imag != 0 else ((0.0, wmax),):
                wi, un = _certified_scan(vals, lips, _disc_decide, x, y, lo, hi)
                wit |= wi
                und |= un
            return wit, und & ~wit
        # 1 on the circle, c real: tangent at 1; the curve leaves 1 outward iff tau1^2 - 2 rho Re L2 > 0
        L2 = (1.0 - D * x + D * y) / P + 0.5 * x * x
        local = x * x - 2.0 * rho * L2
        wit = local < 0.0
        und = np.abs(local) <= 1e-9
        rest = np.flatnonzero(~wit & ~und)
        wi, un = _certified_scan(vals, lips, _disc_decide, x[rest], y[rest], _W_EPS, wmax)
        wit[rest] |= wi
        und[rest] |= un
        return wit, und & ~wit

    def is_safe(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.bool_]:
        """True where every eigenvalue in the set is stable (certified; vectorized, broadcasting).

        Parameters
        ----------
        tau1, tau2
            Delays inside the window.

        Returns
        -------
        ndarray of bool
            Undecided points (within ~1e-10 of the boundary) are False.
        """
        safe, _, shape = self._classify(tau1, tau2)
        return safe.reshape(shape)

    def undecided(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.bool_]:
        """True where the certified scan could not decide (reported as not safe).

        Parameters
        ----------
        tau1, tau2
            Delays inside the window.
        """
        _, und, shape = self._classify(tau1, tau2)
        return und.reshape(shape)

    def grid(self, resolution: int = 200) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """(tau1 cell centres, tau2 cell centres, safe[i2, i1]) on a grid, cached.

        Parameters
        ----------
        resolution
            Cells per axis.
        """
        key = ("grid", int(resolution))
        if key not in self._cache:
            t1 = (np.arange(resolution) + 0.5) * self.tau1_max / resolution
            t2 = (np.arange(resolution) + 0.5) * self.tau2_max / resolution
            self._cache[key] = (t1, t2, self.is_safe(t1[None, :], t2[:, None]))
        return self._cache[key]

    def safe_fraction(self, *, resolution: int = 200) -> float:
        """Fraction of the window's area that is safe, on a grid of cell centres.

        Parameters
        ----------
        resolution
            Cells per axis.
        """
        return float(np.mean(self.grid(resolution)[2]))

    def plot(self, ax: Axes | None = None, points: dict[str, tuple[float, float]] | None = None) -> Axes:
        """Draw the safe set like the stability chart (see :func:`delayform.plots.safe_delay_chart`).

        Parameters
        ----------
        ax
            Axes to draw on; new ones when None.
        points
            Label -> (tau1, tau2) to mark.
        """
        from delayform.plots import safe_delay_chart

        return safe_delay_chart(self, ax=ax, points=points)


@validated()
def safe_delays(
    P: float, D: float, tau1_max: float, tau2_max: float, *, spectrum: object = "undirected"
) -> SafeDelayMap:
    """The delay pairs safe for every team whose eigenvalues of C lie in a set.

    Parameters
    ----------
    P, D
        Positive gains of the paper's eq. 1.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max].
    spectrum
        ``"undirected"`` (real spectrum in [-1, 1]: every undirected team),
        ``"any"`` (the closed unit disc: every team), ``"interval:a,b"``,
        ``"disc:c,r"``, ``"disc:re,im,r"``, a :class:`SpectrumSet`, or a
        :class:`~delayform.analysis.plane.spectrum_bounds.SpectrumBound` of a team.

    Returns
    -------
    SafeDelayMap
        ``.is_safe(tau1, tau2)`` (certified), ``.safe_fraction()``, ``.plot()``.

    Raises
    ------
    GainError, InputError
        For bad gains or spectrum.
    DelayError
        For a window that is not positive.
    ResourceLimitError
        For a window so large that the exact CTCR maps of the base factors
        would not fit the machine (:mod:`delayform.resources`; the message says
        how much memory).

    Examples
    --------
    >>> m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="undirected")
    >>> bool(m.is_safe(0.3, 0.2)), bool(m.is_safe(1.0, 2.0))
    (True, False)
    >>> safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="any").safe_fraction(resolution=20)
    0.0
    """
    P, D = check_gains(P, D)
    t1 = check_positive("tau1_max", tau1_max, DelayError)
    t2 = check_positive("tau2_max", tau2_max, DelayError)
    S = parse_spectrum(spectrum)
    reason = ""
    if S.kind == "interval" and S.high > 1.0 + 1e-12:
        reason = "the set holds real eigenvalues > 1, whose factor has an unstable real root"
    if S.kind == "disc":
        d1 = abs(1.0 - S.center)
        if d1 < S.radius * (1.0 - 1e-12):
            reason = "the disc holds real eigenvalues > 1, whose factor has an unstable real root"
        elif abs(d1 - S.radius) <= 1e-12 * max(1.0, S.radius) and S.center.imag != 0.0:
            reason = "the boundary curve crosses the disc's circle at lam = 1 (not tangent): points inside are unstable"
    images = _lattice_images(P, D, S, t1, t2)
    # the exact CTCR maps of the base factors grow with the number of offspring images
    require(
        what=f"a safe-delay map of the window [0, {t1:g}] x [0, {t2:g}] s (about {images:,} offspring images)",
        setting="the window (--tau1-max, --tau2-max)",
        nbytes=images * _BYTES_PER_IMAGE, seconds=images * _SECONDS_PER_IMAGE,
    )
    bases = [] if reason else [S.base]
    if S.kind == "interval" and S.high < 1.0 and not reason:
        bases.append(complex(S.high))
    maps = tuple(crossing_map(lam_factor(P, D, lam), t1, t2) for lam in bases)
    return SafeDelayMap(P, D, t1, t2, S, maps, reason)


# ===================================================================== the envelope
#: Most lattice images (delay shifts 2 pi n / omega of each phase) the envelope is traced on.
MAX_LATTICE_IMAGES = 2500
#: Memory and time per lattice image of the base CTCR maps (measured: about 0.15 MB, 1 ms).
_BYTES_PER_IMAGE = 160_000
_SECONDS_PER_IMAGE = 1e-3


def _lattice_images(P: float, D: float, S: SpectrumSet, tau1_max: float, tau2_max: float) -> int:
    wmax = omega_limit(P, D, S.outer_radius)
    return (int(np.ceil(tau1_max * wmax / (2 * np.pi))) + 1) * (int(np.ceil(tau2_max * wmax / (2 * np.pi))) + 1)


def _set_envelope(S: SpectrumSet, P: float, D: float, tau1_max: float, tau2_max: float) -> tuple[NDArray[np.float64], ...]:
    """The envelope curves of a spectrum set (interval: its interior; disc: its circle, and the tangency at 1)."""
    R = S.outer_radius
    if S.kind == "interval":
        return tuple(envelope_of_family(P, D, lambda x: x + 0j, lambda x: np.ones_like(x) + 0j, S.low, S.high, R,
                               tau1_max, tau2_max))  # fmt: skip
    c, rho = S.center, S.radius
    out: list[NDArray[np.float64]] = []
    # omega > 0 roots of the circle's factors; omega < 0 ones are those of the mirror circle
    for centre in ((c,) if c.imag == 0 else (c, np.conj(c))):
        out += envelope_of_family(P, D, lambda p, centre=centre: centre + rho * np.exp(1j * p),
                         lambda p: 1j * rho * np.exp(1j * p), 0.0, 2 * np.pi, R, tau1_max, tau2_max, n_t=240)  # fmt: skip
    if abs(abs(1.0 - c) - rho) <= 1e-12 * max(1.0, rho) and c.imag == 0:
        # tangent to the curve at lam = 1: tau1^2 - 2 rho Re L2 = 0 (module docstring), a parabola
        parabola = tangency_parabola(P, D, rho, tau1_max, tau2_max)
        if parabola is not None:
            out.append(parabola)
    return tuple(out)
