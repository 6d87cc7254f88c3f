"""Results that can be drawn display themselves in Jupyter (``_repr_png_``, issue 23)."""

from __future__ import annotations

import matplotlib.pyplot as plt
import pytest

import delayform as df


def _results():
    team = df.paper_six()
    yield "stability map", lambda: df.crossing_map(df.TwoDelayQuasiPolynomial([1, 0.5, 1], [-0.5], [0, -0.25]), 6, 6)
    yield "eigenvalue region", lambda: df.lambda_region(1.0, 0.5, 1.0, 2.0)
    yield "trajectory", lambda: df.simulate(team, 1.0, 0.5, 0.3, 0.2, "hexagon", duration=2.0, dt=0.05)
    yield "delay margin", lambda: df.delay_margin(([2.0], [1.0, 1.0]))


@pytest.mark.parametrize(("what", "make"), list(_results()), ids=[w for w, _ in _results()])
def test_result_shows_a_png_without_leaving_a_figure_open(what, make) -> None:
    result = make()
    before = plt.get_fignums()
    png = result._repr_png_()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 5000, what
    assert plt.get_fignums() == before  # drawn on its own Figure, not through pyplot
