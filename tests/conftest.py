"""Test set-up: warnings are errors (pyproject), float64, seeded randomness, figures closed."""

from __future__ import annotations

import os
import re
from pathlib import Path

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

    The long tests (the wheel, the documentation site, whole reports) start at once, side by
    side, then the modules that share a fixture (under ``make test`` each is one unit of work of
    up to a minute or two: the team's certified margin at b was handed out near the end, in
    alphabetical order, and ran alone), and the many short ones fill in around them. The order
    within each group, and so every module's own order there, is unchanged.
    """

    def rank(item: pytest.Item) -> int:
        if item.get_closest_marker("slow") is not None:
            return 0
        shared = item.nodeid.split("::", 1)[0] in SHARED_FIXTURE_MODULES or item.nodeid in SHARED_RUN_TESTS
        return 1 if shared else 2

    items.sort(key=rank)


#: the test modules that define a module-scoped fixture (a stability map, a gain design, a running
#: explorer, the team's certified margin, the wheel): read from their source, so a new one counts
_SHARED_FIXTURE = re.compile(r"@pytest\.fixture\(\s*scope=[\"']module[\"']")
SHARED_FIXTURE_MODULES = frozenset(
    f"tests/{p.name}" for p in Path(__file__).parent.glob("test_*.py") if _SHARED_FIXTURE.search(p.read_text("utf-8"))
)


#: tests that read a run another module's tests share (tests/test_cli.py's ``paper_output``), with the
#: unit of work they join so that the run is made once, on one worker, and nobody waits for it
SHARED_RUN_TESTS = {"tests/test_cli.py::test_paper_writes_every_file_it_lists": "tests/test_report_browser.py"}


@pytest.hookimpl(optionalhook=True)  # a pytest-xdist hook: no error where it is not installed
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """Under ``--dist loadgroup`` (``make test``): a module with a shared fixture runs on one worker.

    A module-scoped fixture is built once in each worker that runs a test of its module; with
    pytest-xdist's per-test scheduling both workers built the slow ones (the team's certified
    margin, three gain designs, a 100 x 100 dominant-root map, three running explorers). Here
    such a module is one unit of work, every other test its own unit, handed out one at a time
    in collection order (slow tests first; ``--no-loadscope-reorder`` keeps that order), a test of
    ``SHARED_RUN_TESTS`` joins the unit it names, and an explicit ``xdist_group`` mark still groups
    as pytest-xdist documents it.
    """
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SharedFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            if "@" in nodeid:  # an xdist_group mark
                return nodeid.rsplit("@", 1)[-1]
            if nodeid in SHARED_RUN_TESTS:
                return SHARED_RUN_TESTS[nodeid]
            module = nodeid.split("::", 1)[0]
            return module if module in SHARED_FIXTURE_MODULES else nodeid

    return SharedFixtureScheduling(config, log)
