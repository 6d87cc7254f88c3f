"""Sphinx configuration of the delayform documentation site (``make docs``).

Why Sphinx rather than MkDocs: our docstrings are numpydoc, which Sphinx
reads natively (numpydoc, autodoc) and checks with ``-W`` (warnings as
errors), so a broken docstring fails the build; MyST lets the existing
Markdown pages in docs/ stay as they are, and MyST-NB executes the tutorial
notebooks during the build, so they can never go stale.

The API reference is generated at build time from ``delayform.__all__``:
a name another engineer adds to ``_EXPORTS`` is documented without touching
this file.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import delayform

project = "delayform"
author = "the delayform authors"
release = delayform.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "_generated/.keep", "**.ipynb_checkpoints"]
html_theme = "alabaster"
html_static_path: list[str] = []
html_title = f"delayform {release}"

# numpydoc: no autosummary tables of members (each class's members are documented in place);
# See Also entries to names outside the reference are not turned into links that would warn
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()
autodoc_default_options = {"members": True, "inherited-members": False, "undoc-members": False}
autodoc_typehints = "none"  # the signatures carry them; numpydoc's Parameters say what they mean
autodoc_member_order = "bysource"

# MyST: the existing pages use ``$...$`` nowhere and link to repository files outside docs/;
# those links (to ../src/..., ../examples/...) are left as plain links rather than warnings.
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
suppress_warnings = ["myst.xref_missing", "myst.header"]

# MyST-NB: execute every tutorial on every build, fail the build on any cell error
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 300
nb_execution_show_tb = True
nb_merge_streams = True

HERE = Path(__file__).parent
GENERATED = HERE / "_generated"


def _directive(name: str, obj: object) -> str:
    if inspect.isclass(obj):
        return f".. autoclass:: delayform.{name}\n   :members:\n"
    if callable(obj):
        return f".. autofunction:: delayform.{name}\n"
    if inspect.ismodule(obj):
        return f".. automodule:: {obj.__name__}\n   :no-members:\n"
    return f".. autodata:: delayform.{name}\n   :annotation:\n"


def write_api_reference() -> None:
    """One page per public name of ``delayform.__all__`` and an index of them."""
    GENERATED.mkdir(exist_ok=True)
    for old in GENERATED.glob("*.rst"):
        old.unlink()
    names = [n for n in delayform.__all__ if n != "__version__"]
    for name in names:
        obj = getattr(delayform, name)
        title = f"``delayform.{name}``"
        (GENERATED / f"{name}.rst").write_text(f"{title}\n{'=' * len(title)}\n\n{_directive(name, obj)}")
    toc = "\n".join(f"   {n}" for n in names)
    (GENERATED / "index.rst").write_text(
        "API reference\n=============\n\n"
        "Every name in ``delayform.__all__``, from its docstring (generated at build time).\n\n"
        f".. toctree::\n   :maxdepth: 1\n\n{toc}\n"
    )


write_api_reference()


def _escape_bars(line: str) -> str:
    """``|x|`` outside inline literals, read as text (absolute values), not an rST substitution."""
    parts = line.split("``")
    for i in range(0, len(parts), 2):  # even parts lie outside ``...``
        parts[i] = parts[i].replace("|", r"\|")
    return "``".join(parts)


def escape_absolute_values(app, what, name, obj, options, lines: list[str]) -> None:  # noqa: ARG001
    """Our docstrings write |L(j omega)| for absolute values (plain text reads best in a terminal).

    reStructuredText would take ``|...|`` for a substitution and warn, so bars
    are escaped, except in literal and doctest blocks, where they are shown as
    written.
    """
    literal_indent: int | None = None
    in_doctest = False
    for k, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal_indent is not None:
            if not stripped or indent > literal_indent:
                continue
            literal_indent = None
        if stripped.startswith(">>>"):
            in_doctest = True
        elif not stripped:
            in_doctest = False
        if in_doctest:
            continue
        lines[k] = _escape_bars(line)
        if stripped.endswith("::"):
            literal_indent = indent


def setup(app):  # noqa: ANN001, ANN201
    # before numpydoc (priority 500), so it sees the docstring as written
    app.connect("autodoc-process-docstring", escape_absolute_values, priority=400)
    return {"parallel_read_safe": True}
