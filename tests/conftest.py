"""Test set-up: warnings are errors (pyproject), float64, seeded randomness, figures closed."""

from __future__ import annotations

import os

# One BLAS thread in each pytest-xdist worker: the workers already fill the cores, and OpenBLAS
# splitting every call over threads the other worker needs made a 1092-state eigensolve 12 times
# slower on 2 shared cores (13 s against 1.2 s). The variables act only before NumPy is imported.
if "PYTEST_XDIST_WORKER" in os.environ:
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

os.environ.setdefault("MPLBACKEND", "Agg")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "delayform", deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True
)
settings.load_profile("delayform")


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, so every run draws the same numbers."""
    return np.random.default_rng(20261123)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import sys

    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups set here
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The slow tests first, and the tests that share a module's fixture on one xdist worker.

    Slow first: the long tests (the wheel, the documentation site, whole reports) start at
    once, side by side, and the many short ones fill in around them, so that none of them
    starts last and runs alone. The order within each group, and so every module's own order,
    is unchanged.

    One worker per shared fixture: a module-scoped fixture (a stability map, a gain design, a
    running explorer, the team's certified margin) is built once in each worker that runs a
    test using it. Under ``--dist loadgroup`` (``make test``) the tests that use one are an
    ``xdist_group`` named after their module, so it is built once, not once per worker (a test
    given its own group, as the whole paper's run shared across modules, keeps it).
    """
    for item in items:
        if item.get_closest_marker("xdist_group") is None and _uses_a_module_fixture(item):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


def _uses_a_module_fixture(item: pytest.Item) -> bool:
    """Whether a test asks for a module-scoped fixture defined in its own module."""
    info = getattr(item, "_fixtureinfo", None)
    module = getattr(item, "module", None)
    if info is None or module is None:  # a doctest
        return False
    return any(
        d.scope == "module" and d.baseid == item.nodeid.split("::")[0]
        for defs in info.name2fixturedefs.values()
        for d in defs
    )
