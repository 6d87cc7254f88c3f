"""The eigenvalue plane and certificates for classes of teams.

``boundary_curve``   L(j omega) = a(j omega) / b(j omega), the boundary of the stable eigenvalues
``region``           which eigenvalues of C are stable at fixed gains and delays (``lambda_region``)
``spectrum_sets``    the delays safe for every spectrum in a set (``safe_delays``)
``envelope``         where a spectrum set's safe delays end: envelopes of CTCR curves
``spectrum_bounds``  bounds on the spectrum of C for teams of 10^4 to 10^6 agents
"""

from delayform.analysis.plane.region import LambdaRegion, lambda_region
from delayform.analysis.plane.spectrum_bounds import SpectrumBound, spectrum_bound
from delayform.analysis.plane.spectrum_sets import SafeDelayMap, SpectrumSet, parse_spectrum, safe_delays

__all__ = [
    "LambdaRegion",
    "lambda_region",
    "SafeDelayMap",
    "SpectrumSet",
    "safe_delays",
    "parse_spectrum",
    "SpectrumBound",
    "spectrum_bound",
]
