"""Gain design for a plant under delayed PD feedback (delayform.design.loop_gains, issue 23).

Checked against an independent method: with equal delays the closed loop is
1 + (P + D s) G e^{-tau s}, whose stability at tau is decided by the exact
delay margin of the loop (P + D s) G (elimination over every gain crossover,
no root finding), so the sign of the design's rightmost-root abscissa must
agree with "margin > tau" at every grid point.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

import delayform as df
from delayform.design.loop_gains import design_loop_gains, pd_loop_quasi_polynomial
from delayform.errors import GainError, LoopError, NoStableGainsError

PLANTS = [control.tf([1.0], [1.0, 0.0, 0.0]), control.tf([1.0], [1.0, 1.0, 0.0]), control.tf([2.0], [1.0, 3.0, 3.0, 1.0])]


@pytest.mark.parametrize("plant", PLANTS)
def test_grid_stability_agrees_with_the_exact_delay_margin(plant: control.TransferFunction) -> None:
    tau = 0.6
    d = design_loop_gains(plant, tau, tau, P_bounds=(0.1, 3.0), D_bounds=(0.1, 3.0), grid=5)
    checked = 0
    for i, D in enumerate(d.D_values):
        for j, P in enumerate(d.P_values):
            margin = df.delay_margin(control.tf([D, P], [1.0]) * plant).tau
            if abs(margin - tau) < 1e-3 or abs(d.grid_abscissa[i, j]) < 1e-6:
                continue  # on the boundary: either answer is within rounding
            assert (d.grid_abscissa[i, j] < 0.0) == (margin > tau), (P, D, margin)
            checked += 1
    assert checked >= 20
    assert df.delay_margin(control.tf([d.D, d.P], [1.0]) * plant).tau > tau


def test_design_is_certified_and_beats_every_grid_point() -> None:
    d = design_loop_gains(PLANTS[0], 0.3, 0.2, P_bounds=(0.1, 2.0), D_bounds=(0.1, 2.0), grid=7)
    assert d.certified and d.abscissa < 0
    assert d.abscissa <= d.grid_abscissa.min() + 1e-12
    q = pd_loop_quasi_polynomial(PLANTS[0], d.P, d.D)
    assert df.rightmost_root(q, 0.3, 0.2).real == pytest.approx(d.abscissa, abs=1e-9)
    assert 0.1 <= d.P <= 2.0 and 0.1 <= d.D <= 2.0
    assert d._repr_png_().startswith(b"\x89PNG")


def test_double_integrator_without_delay_matches_the_closed_form() -> None:
    # s^2 + D s + P: for D^2 >= 4P the rightmost root is (-D + sqrt(D^2 - 4P)) / 2; the box optimum
    # at tau = 0 is the critically damped corner D = D_max, P = D_max^2 / 4, abscissa -D_max / 2
    d = design_loop_gains(PLANTS[0], 0.0, 0.0, P_bounds=(0.1, 1.0), D_bounds=(0.1, 2.0), grid=9)
    assert d.abscissa == pytest.approx(-1.0, abs=2e-3)
    assert d.D == pytest.approx(2.0) and d.P == pytest.approx(1.0, abs=5e-3)


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        (dict(plant=control.tf([1.0], [1.0, 1.0])), LoopError, "relative degree 1"),
        (dict(P_bounds=(2.0, 1.0)), GainError, "0 < low < high"),
        (dict(D_bounds="big"), GainError, "D_bounds must be a tuple of two"),  # the checking layer names it
        (dict(grid=2), GainError, "grid"),
        (dict(tau1=-1.0), df.errors.DelayError, "tau1"),
    ],
)
def test_bad_input_is_named(kwargs: dict, error: type, words: str) -> None:
    args = dict(plant=PLANTS[0], tau1=0.3, tau2=0.2, P_bounds=(0.1, 2.0), D_bounds=(0.1, 2.0), grid=3) | kwargs
    with pytest.raises(error, match=None) as info:
        design_loop_gains(**args)
    assert words in str(info.value)


def test_no_stable_gains_is_said() -> None:
    with pytest.raises(NoStableGainsError, match="no gains"):
        design_loop_gains(PLANTS[0], 20.0, 20.0, P_bounds=(1.0, 2.0), D_bounds=(1.0, 2.0), grid=3)
    assert math.isfinite(df.delay_margin(control.tf([1.0, 1.0], [1.0]) * PLANTS[0]).tau)
