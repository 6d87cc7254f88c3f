"""The periodic switching adversary: Floquet multipliers, the maximum principle, an independent replay.

Checked against what the adversary does not compute: the exact spectrum of the
constant-delay factor (rightmost roots, certified by the argument principle), a
second integrator (classical Runge-Kutta at a quarter of the step, linear
interpolation of the history), and the team's certified margin at point b
(no growth may be found inside it).
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.certificates.adversary import (
    SwitchingSignal,
    floquet_multiplier,
    periodic_switching_adversary,
    replay_growth_rate,
)
from delayform.analysis.roots.single import rightmost_root
from delayform.characteristic import factors
from delayform.errors import InputError
from delayform.topology import paper_six

LAM, P, D, T1, T2 = -0.637, 1.0, 0.5, 2.0, 1.0


@pytest.fixture(scope="module")
def hard_mode():
    """The limiting mode of the paper's team at point b (lam = -0.637)."""
    return next(f for f in factors(paper_six(), P, D) if abs(f.lam + 0.637) < 1e-3)


@pytest.mark.parametrize(("h1", "h2"), [(2.0, 1.0), (1.7, 1.3), (2.3, 0.7)])
def test_constant_delays_give_the_rightmost_root(hard_mode, h1, h2):
    # a constant signal is periodic with any period: ln|mu| over 1 s is the rightmost root's real part
    mu = floquet_multiplier(hard_mode.lam.real, P, D, np.full(100, h1), np.full(100, h2), 0.01)
    assert np.log(abs(mu)) == pytest.approx(rightmost_root(hard_mode, h1, h2).real, abs=5e-4)


def test_finds_growth_where_a_constant_offset_is_already_unstable(hard_mode):
    # (2 - 0.3, 1 + 0.3) is unstable by the exact spectrum: the adversary must do at least as well
    exact = rightmost_root(hard_mode, 1.7, 1.3).real
    assert exact > 0
    s = periodic_switching_adversary(hard_mode.lam.real, P, D, T1, T2, 0.3, dt=0.01, members=1, iterations=2)
    assert s.grows and s.rate >= exact - 5e-4


def test_destabilizing_signal_replays_with_growth():
    s = periodic_switching_adversary(LAM, P, D, T1, T2, 0.16, dt=0.01, members=1, iterations=3)
    assert s.grows
    assert np.all(np.abs(s.h1 - T1) <= 0.16 + 1e-12) and np.all(np.abs(s.h2 - T2) <= 0.16 + 1e-12)
    replay = replay_growth_rate(s, periods=30)
    assert replay > 0 and replay == pytest.approx(s.rate, rel=0.25)
    ax = s.plot()  # the two delays over one period, inside their bands
    assert len(ax.lines) == 2 and ax.lines[0].get_xdata()[-1] < s.period
    import matplotlib.pyplot as plt

    plt.close(ax.figure)


def test_no_growth_inside_the_certified_margin():
    # the team's margin at b is certified at 0.0982 s (0.0995 s with upper cuts): nothing may grow at 0.0995
    s = periodic_switching_adversary(LAM, P, D, T1, T2, 0.0995, dt=0.005, members=2, iterations=3)
    assert not s.grows and s.rate < -0.005
    assert replay_growth_rate(s, periods=12, refine=2) < 0


def test_rejects_bad_input():
    with pytest.raises(InputError):
        periodic_switching_adversary(LAM, P, D, T1, T2, 0.1, dt=0.0)
    with pytest.raises(InputError):
        periodic_switching_adversary(1.0, P, D, T1, T2, 0.1)
    with pytest.raises(InputError):
        floquet_multiplier(LAM, P, D, np.full(10, 2.0), np.full(9, 1.0), 0.01)
    with pytest.raises(InputError):
        floquet_multiplier(LAM, P, D, np.full(10, -2.0), np.full(10, 1.0), 0.01)
    s = SwitchingSignal(LAM, P, D, T1, T2, 0.1, 0.01, np.full(10, 2.0), np.full(10, 1.0), 0.9 + 0j)
    with pytest.raises(InputError):
        replay_growth_rate(s, periods=2)


def test_refined_signal_is_a_local_maximum():
    # the maximum principle stops at an extremal: flipping the delay at any single step lowers |mu|
    s = periodic_switching_adversary(LAM, P, D, T1, T2, 0.14, dt=0.01, members=1, iterations=4)
    rng = np.random.default_rng(7)
    for k in rng.integers(0, s.h1.size, 3):
        for h, other, tau in ((s.h1.copy(), s.h2, T1), (s.h2.copy(), s.h1, T2)):
            h[k] = tau - 0.14 if h[k] > tau else tau + 0.14
            pair = (h, other) if tau == T1 else (other, h)
            assert abs(floquet_multiplier(LAM, P, D, *pair, 0.01)) < abs(s.multiplier)


def test_deterministic_and_inside_the_interval_off_the_grid():
    # 0.153 is not a multiple of dt: the delays are rounded into [tau - 0.153, tau + 0.153], never out
    a = periodic_switching_adversary(LAM, P, D, T1, T2, 0.153, dt=0.01, members=1, iterations=2)
    b = periodic_switching_adversary(LAM, P, D, T1, T2, 0.153, dt=0.01, members=1, iterations=2)
    assert a.multiplier == b.multiplier and np.array_equal(a.h1, b.h1)
    assert a.h1.min() >= T1 - 0.153 and a.h1.max() <= T1 + 0.153
    assert a.h2.min() >= T2 - 0.153 and a.h2.max() <= T2 + 0.153
