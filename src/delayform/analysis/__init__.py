"""Analysis of the characteristic equation, grouped by method.

``ctcr/``
    The exact stability map in the (tau1, tau2) plane by the Cluster Treatment of
    Characteristic Roots: crossing sets in phase space, their kernel and offspring
    curves in the delay plane, and the count of unstable roots between them.
``roots/``
    Characteristic roots and their certificates: roots in a rectangle, the rightmost
    root, argument-principle counts, and the formation's dominant roots and maps.
``plane/``
    The eigenvalue plane and certificates for whole classes of teams: which
    eigenvalues of C are stable at given delays, the delays safe for every spectrum
    in a set, and spectrum bounds for teams too large for dense eigenvalues.
``certificates/``
    Lyapunov-Krasovskii certificates for x' = A0 x + A1 x(t - h(t)): LMIs with
    Bessel-Legendre inequalities for constant and time-varying delays, solved by
    Clarabel and re-checked in exact arithmetic, and the certified delay margin.
``neutral/``
    Neutral quasi-polynomials: the difference operator, the essential spectrum,
    strong stability, and roots right of the essential spectrum.
``network/``
    Guarantees for real networks: per-link delays, boxes of delays, jitter and
    packet loss.

Each subpackage's ``__init__`` lists its public names; the modules inside are the
method's own business. What they share is public in the module that defines it.

The subpackages import one another one way: ``roots`` at the bottom;
``neutral`` and ``certificates`` above it; ``ctcr`` above those; ``network`` and
``plane`` on top (``tests/test_architecture.py`` checks it). Two kinds of
problem that ``roots``' public functions accept are solved above it, neutral
quasi-polynomials by ``neutral`` and per-link delays by ``network``: their
solvers are lent to ``roots`` here (:mod:`delayform.analysis.roots.delegated`),
before any module of the package can be used.
"""

from delayform.analysis.network.links import uniform_link_delays
from delayform.analysis.network.per_link import link_dominant_root
from delayform.analysis.neutral.spectrum import neutral_count_right_of, neutral_rightmost_root, neutral_roots_in
from delayform.analysis.roots import delegated

delegated.lend(
    neutral=delegated.NeutralSolver(neutral_roots_in, neutral_count_right_of, neutral_rightmost_root),
    per_link=delegated.PerLinkSolver(link_dominant_root, uniform_link_delays),
)
