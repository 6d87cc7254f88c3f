"""The example scenario files shipped inside the package (``delayform/examples/*.toml``).

In a source checkout they are the files of ``examples/``; in an installed
wheel they are package data, so ``delayform chart "$(python -c 'import
delayform; print(delayform.example_path("ring12"))')"`` works anywhere. A
leaf: imports no delayform module but the errors.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from delayform._validation import validated
from delayform.errors import InputError

__all__ = ["example_names", "example_path"]


def _folder() -> Path:
    return Path(str(files("delayform") / "examples"))


@validated()
def example_names() -> tuple[str, ...]:
    """The names of the shipped example scenarios, sorted (``"paper"``, ``"ring12"``, ...).

    >>> "ring12" in example_names()
    True
    """
    return tuple(sorted(p.stem for p in _folder().glob("*.toml")))


@validated()
def example_path(name: str) -> Path:
    """The path of a shipped example scenario file.

    Parameters
    ----------
    name
        One of :func:`example_names`, with or without ``.toml``.

    Returns
    -------
    Path
        The TOML file, readable by :func:`delayform.load_scenario` and every command.

    Raises
    ------
    InputError
        For a name that is not shipped.

    Examples
    --------
    >>> example_path("ring12").name
    'ring12.toml'
    """
    stem = str(name).removesuffix(".toml")
    path = _folder() / f"{stem}.toml"
    if not path.is_file():
        raise InputError(f"no example scenario {name!r}; the examples are {', '.join(example_names())}")
    return path
