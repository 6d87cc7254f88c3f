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

Each subpackage's ``__init__`` lists its public names; the modules inside are the
method's own business.
"""
