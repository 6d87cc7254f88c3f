"""Shared pieces of the report sections: figures, sections, number formats, files."""

from __future__ import annotations

import csv
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from delayform._files import atomic_path


#: Called with a short description before each step of a long computation.
Progress = Callable[[str], None]

#: Called with (grid points done, grid points in all) while a map is computed.
MapProgress = Callable[[int, int], None]


@dataclass(frozen=True)
class Figure:
    """A figure written as ``<stem>.png`` and ``<stem>.svg`` (or an animation ``<stem>.gif``), with its caption."""

    stem: str
    title: str
    text: str
    animated: bool = False


@dataclass(frozen=True)
class Section:
    """One analysis as the report shows it.

    Attributes
    ----------
    key
        Short identifier, the key of this section in ``summary.json``.
    title, text
        Heading and a paragraph saying what was computed.
    figures
        Figures written into the output directory.
    table
        Rows ``(quantity, value)`` shown as the table of numbers.
    summary
        JSON-ready numbers (what ``--json`` prints).
    files
        Every file written, relative to the output directory.
    """

    key: str
    title: str
    text: str
    figures: tuple[Figure, ...] = ()
    table: tuple[tuple[str, str], ...] = ()
    summary: Mapping[str, Any] = field(default_factory=dict)
    files: tuple[str, ...] = ()


# ------------------------------------------------------------------ helpers
def jsonable(value: Any) -> Any:
    """``value`` with NumPy scalars and arrays, complex numbers and tuples made JSON-ready.

    Complex numbers become ``{"re": ..., "im": ...}``; non-finite floats
    become ``None`` (JSON has no infinity).

    >>> jsonable({"s": 1 - 2j, "v": np.arange(2)})
    {'s': {'re': 1.0, 'im': -2.0}, 'v': [0, 1]}
    """
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (complex, np.complexfloating)):
        return {"re": jsonable(float(value.real)), "im": jsonable(float(value.imag))}
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value


def _fmt(value: float, digits: int = 4) -> str:
    if value is None or not np.isfinite(value):
        return "n/a"
    return f"{value:.{digits}g}"


def _fmt_complex(value: complex) -> str:
    from delayform.characteristic import format_number

    # a real root polished in complex arithmetic keeps an imaginary part of rounding size
    return format_number(value, digits=5)


def _save(fig: Any, out: Path, stem: str) -> tuple[str, str]:
    """Write ``fig`` as PNG and SVG and close it; return the two file names."""
    import matplotlib.pyplot as plt

    from delayform.plots import save_figure

    paths = save_figure(fig, out / stem, formats=("png", "svg"), dpi=110)
    plt.close(fig)
    return paths[0].name, paths[1].name


def _pyplot() -> Any:
    """pyplot on the Agg backend (reports are written, never shown)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows)
    return path.name


def _step(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress(text)


