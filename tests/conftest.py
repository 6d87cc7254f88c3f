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
# A long run of the properties draws fresh examples, seeded by --hypothesis-seed so that shards
# differ: DELAYFORM_HYPOTHESIS_PROFILE=long (the number of examples: DELAYFORM_PROPERTY_EXAMPLES).
settings.register_profile("long", parent=settings.get_profile("delayform"), derandomize=False, database=None)
settings.load_profile(os.environ.get("DELAYFORM_HYPOTHESIS_PROFILE", "delayform"))


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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The slow tests first, so that across xdist workers none of them starts last and runs alone.

    pytest-xdist deals the first quarter of the collection out one test at a time to its
    workers: the long tests (the wheel, the documentation site, whole reports) start at once,
    side by side, and the many short ones fill in around them. The order within each group,
    and so every module's own order, is unchanged.
    """
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
