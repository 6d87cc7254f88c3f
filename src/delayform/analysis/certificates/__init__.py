"""Lyapunov-Krasovskii certificates for linear systems with time-varying delays.

``krasovskii``
    The functionals and their LMIs: the Bessel-Legendre hierarchy for constant
    delays, and for delays varying in an interval (with or without a rate
    bound) the split integral with reciprocal convexity.
``lmi``
    The LMIs in Clarabel's standard form, the solve, and the independent
    re-check (eigenvalues, then exact rational arithmetic).
``margin``
    The public questions: :func:`certify_time_varying` at one interval and
    :func:`time_varying_delay_margin`, the largest certified interval.
``intervals``, ``several``
    Several delayed terms, each delay varying in its own interval:
    :func:`certify_interval_delays` and :func:`interval_delay_margin`.
``team``
    The team's margin for delays varying together on every link, one
    certificate per mode of eq. factorized: :func:`team_delay_margin`, and the
    same certificates at a given deviation: :func:`certify_team_delays`.
``adversary``
    The other side: delay signals that destabilize one mode (greedy switching rules, and
    periodic signals proved destabilizing by their Floquet multiplier), to measure how far
    below the truth a certified margin lies.
"""

from delayform.analysis.certificates.margin import (
    MAX_ORDER,
    DelayCertificate,
    TimeVaryingMargin,
    certify_time_varying,
    time_varying_delay_margin,
)

from delayform.analysis.certificates.several import IntervalMargin, certify_interval_delays, interval_delay_margin
from delayform.analysis.certificates.team import TeamDelayMargin, certify_team_delays, team_delay_margin

__all__ = ["MAX_ORDER", "DelayCertificate", "TimeVaryingMargin", "certify_time_varying", "time_varying_delay_margin",
           "IntervalMargin", "certify_interval_delays", "interval_delay_margin", "TeamDelayMargin", "team_delay_margin",
           "certify_team_delays"]
