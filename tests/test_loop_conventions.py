"""python-control's conventions on delay margins: dead time in the loop, degrees, ControlPlot.

Every margin is checked against a method that does not use the crossover
formula: a closed form (e^{-theta s} / s), a frequency-domain computation
written here (brentq on |L(j omega)| = 1 and the phase there), python-control's
own crossovers (``stability_margins(..., returnall=True)``), and the spectrum
itself (the project's rightmost root of D + N e^{-tau s}, collocation and
Newton, scanned over tau).
"""

from __future__ import annotations

import math
import sys

import control
import matplotlib.pyplot as plt
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import delayform as df
from delayform._display import LoopPlot
from delayform.design.loop_gains import design_loop_gains
from delayform.errors import DelayError, UnstableLoopError

PLANT = control.tf([1.0], [1.0, 1.0])  # 1 / (s + 1), the delay-free part of the FOPDT plant


def _pi(kp: float, ki: float) -> control.TransferFunction:
    return control.tf([kp, ki], [1.0, 0.0])  # Kp + Ki / s


def _first_unstable_delay(qp: df.TwoDelayQuasiPolynomial, tau_min: float, tau_max: float) -> float:
    """The first delay beyond tau_min with a root Re s > 0: a scan of the rightmost root, then bisection."""
    taus = np.linspace(tau_min, tau_max, 151)
    assert df.rightmost_root(qp, tau_min, 0.0).real < 0.0
    hit = next(k for k, t in enumerate(taus) if df.rightmost_root(qp, t, 0.0).real > 0.0)
    lo, hi = float(taus[hit - 1]), float(taus[hit])
    while hi - lo > 1e-9 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if df.rightmost_root(qp, mid, 0.0).real > 0.0 else (mid, hi)
    return hi


# ------------------------------------------------------------------ a loop with its dead time
def test_fopdt_under_pi_control_leaves_the_closed_form_margin() -> None:
    # Kp = Ki = 1: C P = (s + 1) / (s (s + 1)) = 1 / s exactly (python-control keeps the common
    # factor), so L = e^{-0.3 s} / s: crossover 1 rad/s, total margin pi / 2, pi / 2 - 0.3 left
    m = df.delay_margin(_pi(1.0, 1.0) * PLANT, delay=0.3)
    assert m.tau == pytest.approx(math.pi / 2 - 0.3, rel=1e-12)
    assert m.total == pytest.approx(math.pi / 2, rel=1e-12) and m.delay == 0.3
    assert m.omega == pytest.approx(1.0, rel=1e-12)
    assert m.phase_margin == pytest.approx(90.0 - math.degrees(0.3), rel=1e-12)  # of L e^{-0.3 s}, degrees
    assert m.certified and m.is_stable(1.27) and not m.is_stable(1.271)


def _frequency_domain_remaining(kp: float, ki: float, theta: float) -> tuple[float, float]:
    """(omega_c, pm / omega_c - theta) of (Kp + Ki / s) e^{-theta s} / (s + 1), by brentq and the phase."""

    def loop(w: float) -> complex:
        s = 1j * w
        return (kp + ki / s) / (s + 1.0)

    wc = brentq(lambda w: math.log(abs(loop(w))), 1e-8, 1e8, xtol=1e-15, rtol=1e-15)
    pm = (math.pi + np.angle(loop(wc))) % (2 * math.pi)  # of the delay-free loop: it alone decides
    return wc, pm / wc - theta


@settings(max_examples=30, deadline=None)
@given(kp=st.floats(0.1, 3.0), ki=st.floats(0.1, 3.0), share=st.floats(0.05, 0.9))
def test_fopdt_margin_agrees_with_the_frequency_domain(kp: float, ki: float, share: float) -> None:
    # |L(j omega)| = sqrt(Kp^2 omega^2 + Ki^2) / (omega sqrt(omega^2 + 1)) falls monotonically: one crossover
    total = df.delay_margin(_pi(kp, ki) * PLANT).tau
    theta = share * total
    wc, remaining = _frequency_domain_remaining(kp, ki, theta)
    m = df.delay_margin(_pi(kp, ki) * PLANT, delay=theta)
    assert m.tau == pytest.approx(remaining, rel=1e-9, abs=1e-12)
    assert m.omega == pytest.approx(wc, rel=1e-9)
    # python-control's margin (degrees) of the delay-free loop, minus the dead time
    _, pm_deg, _, wgc = control.margin(_pi(kp, ki) * PLANT)
    assert m.tau == pytest.approx(math.radians(pm_deg) / wgc - theta, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize(("kp", "ki", "theta"), [(0.5, 0.8, 0.3), (2.0, 0.5, 0.2), (0.3, 1.5, 0.6)])
def test_fopdt_spectrum_crosses_at_the_margin(kp: float, ki: float, theta: float) -> None:
    # a second method: the rightmost root of s (s + 1) + (Kp s + Ki) e^{-tau s} (collocation + Newton)
    m = df.delay_margin(_pi(kp, ki) * PLANT, delay=theta)
    qp = df.loop_quasi_polynomial(_pi(kp, ki) * PLANT)
    assert df.rightmost_root(qp, theta, 0.0).real < 0.0  # stable with its dead time
    below = df.rightmost_root(qp, theta + m.tau * (1 - 1e-4), 0.0)
    above = df.rightmost_root(qp, theta + m.tau * (1 + 1e-4), 0.0)
    assert below.real < 0.0 < above.real
    on_axis = df.rightmost_root(qp, m.total, 0.0)
    assert abs(on_axis.real) < 1e-9 and abs(abs(on_axis.imag) - m.omega) < 1e-8 * m.omega


def test_dead_time_beyond_the_margin_is_refused() -> None:
    with pytest.raises(UnstableLoopError, match="not stable with its delay 2 s"):
        df.delay_margin(_pi(1.0, 1.0) * PLANT, delay=2.0)
    with pytest.raises(UnstableLoopError, match="marginally stable"):
        df.delay_margin(([1.0], [1.0, 0.0]), delay=math.pi / 2)  # e^{-pi/2 s} / s: a root at j
    with pytest.raises(DelayError, match="non-negative"):
        df.delay_margin(PLANT, delay=-0.1)


def test_dead_time_can_stabilize_a_loop() -> None:
    # positive delayed velocity feedback on an undamped oscillator, L = -0.2 s / (s^2 + 1): unstable
    # without delay (s^2 - 0.2 s + 1), stable in a window of delays around pi (the feedback turns over)
    loop = ([-0.2, 0.0], [1.0, 0.0, 1.0])
    with pytest.raises(UnstableLoopError, match="not stable without delay"):
        df.delay_margin(loop)
    m = df.delay_margin(loop, delay=3.0)
    assert m.certified and m.tau > 0.5
    # independent: the rightmost root, scanned from the loop's own delay on, first crosses at 3 + tau
    assert _first_unstable_delay(m.quasi_polynomial, 3.0, 6.0) == pytest.approx(m.total, rel=1e-7)
    with pytest.raises(UnstableLoopError, match="not stable with its delay 1"):
        df.delay_margin(loop, delay=1.0)


def test_neutral_loop_with_dead_time() -> None:
    # (0.5 s + 2) / (s + 1), neutral type: crossover omega^2 = 4, one crossing delay tau0 per period
    loop = control.tf([0.5, 2.0], [1.0, 1.0])
    wc = math.sqrt((4.0 - 1.0) / (1.0 - 0.25))
    tau0 = (math.pi + np.angle((0.5j * wc + 2.0) / (1j * wc + 1.0))) / wc
    m = df.delay_margin(loop, delay=0.4 * tau0)
    assert m.tau == pytest.approx(0.6 * tau0, rel=1e-10) and not m.certified
    with pytest.raises(UnstableLoopError, match="2 root"):  # the crossing at tau0 has root tendency +1
        df.delay_margin(loop, delay=1.2 * tau0)


def test_python_control_has_no_delay_object() -> None:
    # python-control 0.10 represents a delay only by control.pade; the day it ships a delay object,
    # delay_margin should read its dead time instead of refusing it
    assert not hasattr(control, "DelayLTI") and not hasattr(control.delay, "DelayLTI")


# ------------------------------------------------------------------ degrees, as python-control
@pytest.mark.parametrize(
    "loop",
    [control.tf([2.0], [1.0, 1.0]), control.tf([1.0], [1.0, 1.0, 0.0]), control.tf([15.0], [1.0, 6.0, 11.0, 6.0]),
     control.tf([7.5], np.polymul([1.0, 0.4, 0.0], [1.0, 0.05, 25.0]))],
)
def test_every_phase_margin_is_python_controls_in_degrees(loop: control.TransferFunction) -> None:
    _, pm, _, _, wc, _ = control.stability_margins(loop, returnall=True)
    m = df.delay_margin(loop)
    ours = sorted((c.omega, c.phase_margin, c.phase_margin_rad) for c in m.crossovers)
    assert len(ours) == len(wc)
    for (w, deg, rad), w_pc, pm_pc in zip(ours, np.sort(wc), pm[np.argsort(wc)], strict=True):
        assert w == pytest.approx(w_pc, rel=1e-8)
        assert deg == pytest.approx(pm_pc, rel=1e-8, abs=1e-8)
        assert rad == pytest.approx(math.radians(pm_pc), rel=1e-8, abs=1e-10)
    assert m.phase_margin_rad == pytest.approx(m.omega * m.tau - 2 * math.pi * (m.phase_margin < 0), rel=1e-12)


# ------------------------------------------------------------------ python-control's reading, wrong
#: a flexible mode above a PI-like loop: 7.5 / (s (s + 0.4) (s^2 + 0.05 s + 25)), three crossovers
FLEXIBLE = control.tf([7.5], np.polymul([1.0, 0.4, 0.0], [1.0, 0.05, 25.0]))


def test_python_control_margin_overstates_the_delay_margin_of_a_flexible_mode() -> None:
    _, pm, _, wgc = control.margin(FLEXIBLE)  # the crossover with the smallest |phase margin|
    m = df.delay_margin(FLEXIBLE)
    reading = math.radians(pm) / wgc
    assert pm > 0 and reading > 1.6 * m.tau  # 1.43 s read from the margin, against 0.842 s
    assert m.omega != pytest.approx(wgc, rel=0.1)  # the margin comes from another crossover
    # independent: the spectrum, scanned over tau, first crosses at the exact margin, not at pm / wgc
    assert _first_unstable_delay(m.quasi_polynomial, 0.0, 1.2 * reading) == pytest.approx(m.tau, rel=1e-7)
    # and python-control's own crossovers give it once every one is read with its phase wrapped to [0, 360)
    _, pms, _, _, wcs, _ = control.stability_margins(FLEXIBLE, returnall=True)
    assert min(np.radians(np.mod(pms, 360.0)) / wcs) == pytest.approx(m.tau, rel=1e-8)


# ------------------------------------------------------------------ ControlPlot
def test_plot_returns_python_controls_control_plot() -> None:
    m = df.delay_margin(FLEXIBLE)
    cplt = m.plot()
    try:
        assert isinstance(cplt, control.ControlPlot)
        ax = cplt.axes[0, 0]
        assert cplt.figure is ax.figure and cplt.legend is ax.get_legend() is not None
        assert cplt.lines.shape == (1, 1) and len(cplt.lines[0, 0]) == len(ax.get_lines())
        assert "delay margin" in ax.get_title()
    finally:
        plt.close(cplt.figure)


def test_plot_on_given_axes_counts_only_its_own_lines() -> None:
    fig, ax = plt.subplots()
    try:
        (before,) = ax.plot([0.0, 1.0], [0.0, 1.0])
        cplt = df.delay_margin(([2.0], [1.0, 1.0]), delay=0.2).plot(ax=ax)
        assert cplt.axes[0, 0] is ax and cplt.figure is fig
        assert before not in cplt.lines[0, 0] and all(line.axes is ax for line in cplt.lines[0, 0])
        design = design_loop_gains(control.tf([1.0], [1.0, 0.0, 0.0]), 0.3, 0.2,
                                   P_bounds=(0.1, 2.0), D_bounds=(0.1, 2.0), grid=3)  # fmt: skip
        assert isinstance(design.plot(ax=fig.add_subplot(2, 1, 2)), control.ControlPlot)
    finally:
        plt.close(fig)


def test_plot_without_python_control_has_the_same_attributes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "control", None)  # "import control" now fails
    cplt = df.delay_margin(([2.0], [1.0, 1.0])).plot()
    try:
        assert isinstance(cplt, LoopPlot) and not isinstance(cplt, control.ControlPlot)
        assert cplt.axes[0, 0].figure is cplt.figure and cplt.lines[0, 0] and cplt.legend is not None
        cplt.set_plot_title("a loop")
        assert cplt.figure.get_suptitle() == "a loop"
    finally:
        plt.close(cplt.figure)
