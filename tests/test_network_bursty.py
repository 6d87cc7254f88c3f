"""Gilbert-Elliott (bursty) loss exactly in the mean square: the Markov jump-linear recursion.

Independent checks: a memoryless chain (p_good_to_bad + p_bad_to_good = 1) is Bernoulli
loss at its stationary rate, computed by the other module's recursion (no modes); a chain
that never moves is Bernoulli loss in its state; and the simulator's Monte Carlo mean of
the disagreement (GilbertElliott with Sampling) lies within its confidence interval,
while the Bernoulli prediction at the same loss rate does not.
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.network import bursty_mean_square_stability, mean_square_stability
from delayform.errors import InputError, ResourceLimitError
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.model.network import GilbertElliott, Network, Sampling
from delayform.topology import paper_six, ring

TEAM = (ring(3), 1.0, 1.0, 0.2, 0.1)
SHAPE = named_formation("polygon", 3, spacing=2.0)
X0 = np.array([[-3.0, 1.0], [2.0, 3.0], [0.5, -2.5]])


def test_a_memoryless_chain_is_bernoulli_loss_at_its_rate():
    a, lg, lb = 0.3, 0.1, 0.8
    r = bursty_mean_square_stability(*TEAM, rate=10.0, p_good_to_bad=a, p_bad_to_good=1 - a, loss_good=lg, loss_bad=lb)
    ref = mean_square_stability(*TEAM, rate=10.0, loss=(1 - a) * lg + a * lb)
    assert r.rho == pytest.approx(ref.rho, rel=1e-10)
    assert np.allclose(r.disagreement(X0 - SHAPE, steps=30), ref.disagreement(X0 - SHAPE, steps=30), rtol=1e-10)


def test_chains_that_never_move_are_bernoulli_in_their_state():
    frozen = bursty_mean_square_stability(*TEAM, rate=10.0, p_good_to_bad=0.0, p_bad_to_good=0.0, loss_good=0.3)
    assert frozen.rho == pytest.approx(mean_square_stability(*TEAM, rate=10.0, loss=0.3).rho, rel=1e-12)
    absorbed = bursty_mean_square_stability(*TEAM, rate=10.0, p_good_to_bad=0.2, p_bad_to_good=0.0, loss_bad=0.4)
    assert absorbed.rho == pytest.approx(mean_square_stability(*TEAM, rate=10.0, loss=0.4).rho, rel=1e-12)


def _disagreement(seed: int) -> np.ndarray:
    tr = simulate(*TEAM, SHAPE, model="double_integrator", initial_positions=X0, initial_speed=0.0, duration=10.0,
                  dt=0.01, save_every=10, network=Network(sampling=Sampling(10.0), loss=GilbertElliott(0.1, 0.3), seed=seed))  # fmt: skip
    y = tr.positions - SHAPE[None]
    return ((y - y.mean(axis=1, keepdims=True)) ** 2).sum(axis=(1, 2))


@pytest.mark.slow
def test_monte_carlo_second_moment_within_its_confidence_interval():
    r = bursty_mean_square_stability(*TEAM, rate=10.0, p_good_to_bad=0.1, p_bad_to_good=0.3)
    exact = r.disagreement(X0 - SHAPE, steps=100)
    runs = np.array([_disagreement(s) for s in range(40)])
    mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / np.sqrt(runs.shape[0])
    k = [10, 20, 40, 60, 100]
    # the simulator's first-order step error at arrivals: 2.5e-4 exact[0] at most for this team without loss
    # (dt = 0.01, measured as in tests/test_network_loss.py); twice that
    bias = 5e-4 * exact[0]
    assert np.all(np.abs(mean[k] - exact[k]) <= 3.0 * se[k] + bias), (mean[k], exact[k], se[k])
    # the test can tell: independent loss at the same long-run rate (0.25) predicts other moments
    bern = mean_square_stability(*TEAM, rate=10.0, loss=0.25).disagreement(X0 - SHAPE, steps=100)
    assert np.any(np.abs(mean[k] - bern[k]) > 4.0 * se[k] + bias), (mean[k], bern[k], se[k])
    assert r.stable and r.rho != pytest.approx(mean_square_stability(*TEAM, rate=10.0, loss=0.25).rho, rel=1e-3)


def test_too_many_chains_are_refused_up_front():
    with pytest.raises(ResourceLimitError, match=r"2\^26 = 6.71e\+07 modes"):
        bursty_mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, p_good_to_bad=0.1, p_bad_to_good=0.3)


@pytest.mark.parametrize("kw, needle", [
    ({"p_good_to_bad": 1.5, "p_bad_to_good": 0.3}, "p_good_to_bad"),
    ({"p_good_to_bad": 0.1, "p_bad_to_good": float("nan")}, "p_bad_to_good"),
    ({"p_good_to_bad": 0.1, "p_bad_to_good": 0.3, "loss_good": 1.0}, "every packet"),
    ({"p_good_to_bad": 0.1, "p_bad_to_good": 0.0}, "every packet"),  # absorbing bad state, loss_bad = 1
])  # fmt: skip
def test_bad_inputs(kw, needle):
    with pytest.raises(InputError, match=needle):
        bursty_mean_square_stability(*TEAM, rate=10.0, **kw)
