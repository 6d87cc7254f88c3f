"""Neutral quasi-polynomials: difference operator, essential spectrum, strong stability, roots."""

from delayform.analysis.neutral.difference import DifferenceOperator, difference_operator
from delayform.analysis.neutral.spectrum import (
    NeutralSpectrum,
    neutral_count_right_of,
    neutral_rightmost_root,
    neutral_roots_in,
    neutral_spectrum,
)

__all__ = [
    "DifferenceOperator",
    "difference_operator",
    "NeutralSpectrum",
    "neutral_spectrum",
    "neutral_roots_in",
    "neutral_rightmost_root",
    "neutral_count_right_of",
]
