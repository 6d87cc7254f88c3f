"""A package's public names imported on first use (PEP 562), for packages a light process imports.

A robot's process of the fleet imports the nouns' package and the fleet's for one or two names;
with every name imported up front each would bring SciPy and the simulator along.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any


def lazy_names(package: str, where: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` whose name ``n`` lives in module ``where[n]``.

    A name is imported at its first use and then kept in the package's namespace (so the next use
    does not come here).
    """
    namespace = vars(import_module(package))

    def __getattr__(name: str) -> Any:
        if name in where:
            value = getattr(import_module(where[name]), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__
