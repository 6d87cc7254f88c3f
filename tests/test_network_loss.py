"""Packet loss exactly in the mean square (issue 20, part 4).

The exact second moment of the lifted jump-linear model against the simulator
(delayform.simulation with Sampling and BernoulliLoss): without loss the two agree
up to the simulator's first-order error at packet arrivals (halving with dt); with
loss the Monte Carlo mean lies within its confidence interval.
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.network import mean_square_stability
from delayform.errors import DelayError, InputError
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.model.network import BernoulliLoss, Network, Sampling
from delayform.topology import paper_six

SHAPE = named_formation("hexagon", 6, spacing=2.0)
X0 = np.array([[-4.0, 1.0], [3.0, 4.0], [0.5, -3.0], [4.0, -1.0], [-2.0, -4.0], [1.0, 2.5]])


def _disagreement(p: float, seed: int, dt: float, duration: float) -> np.ndarray:
    tr = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, SHAPE, model="double_integrator", initial_positions=X0,
                  initial_speed=0.0, duration=duration, dt=dt, save_every=int(round(0.1 / dt)),
                  network=Network(sampling=Sampling(10.0), loss=BernoulliLoss(p), seed=seed))  # fmt: skip
    y = tr.positions - SHAPE[None]
    return ((y - y.mean(axis=1, keepdims=True)) ** 2).sum(axis=(1, 2))


def test_without_loss_the_exact_model_is_the_simulation():
    exact = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=0.0).disagreement(X0 - SHAPE, steps=40)
    diffs = [np.max(np.abs(_disagreement(0.0, 0, dt, 4.0) - exact)) for dt in (0.01, 0.005)]
    assert diffs[1] < 0.6 * diffs[0]  # the simulator's first-order error at arrivals, and nothing else
    assert diffs[1] < 2e-3 * exact[0]


@pytest.mark.slow
def test_monte_carlo_second_moment_within_its_confidence_interval():
    p = 0.5
    r = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=p)
    exact = r.disagreement(X0 - SHAPE, steps=80)
    runs = np.array([_disagreement(p, s, 0.01, 8.0) for s in range(40)])
    mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / np.sqrt(runs.shape[0])
    k = [10, 20, 40, 80]
    bias = 2e-3 * exact[0]  # the simulator's step error (test above)
    assert np.all(np.abs(mean[k] - exact[k]) <= 3.0 * se[k] + bias), (mean[k], exact[k], se[k])
    assert r.stable and 0.0 < r.decay_rate < 0.2


def test_loss_slows_the_decay():
    rates = [mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=p) for p in (0.0, 0.5)]
    assert rates[0].decay_rate > rates[1].decay_rate > 0
    # without loss the recursion is deterministic: rho is the squared spectral radius of the lifted matrix
    m = rates[0]._model
    e = m.consensus / np.linalg.norm(m.consensus)
    V = np.linalg.svd(np.eye(e.size) - np.outer(e, e))[0][:, : e.size - 1]
    assert rates[0].rho == pytest.approx(np.max(np.abs(np.linalg.eigvals(V.T @ m.A @ V))) ** 2, rel=1e-8)


def test_bad_loss_inputs():
    with pytest.raises(DelayError, match="whole multiple"):
        mean_square_stability(paper_six(), 1.0, 0.5, 0.33, 0.2, rate=10.0, loss=0.1)
    with pytest.raises(InputError, match=r"\[0, 1\)"):
        mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=1.0)
    with pytest.raises(InputError, match="rate"):
        mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=0.0, loss=0.1)
    with pytest.raises(InputError, match="6 x 6"):
        mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=np.zeros((2, 2)))


def test_plot():
    ax = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=0.2).plot(steps=20)
    assert ax.get_xlabel() == "t (s)"
