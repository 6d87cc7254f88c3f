"""Sphinx configuration of the delayform documentation site (``make docs``).

Why Sphinx rather than MkDocs: our docstrings are numpydoc, which Sphinx
reads natively (numpydoc, autodoc) and checks with ``-W`` (warnings as
errors), so a broken docstring fails the build; MyST lets the existing
Markdown pages in docs/ stay as they are, and MyST-NB executes the tutorial
notebooks during the build, so they can never go stale.

The API reference is generated at build time from ``delayform.__all__``,
one page per name, grouped by concept as ``delayform._GROUPS`` groups them
(the groups of docs/api.md), so a name another engineer adds to a group is
documented without touching this file; a name in no group lands in "Other
names" rather than disappearing.
"""

from __future__ import annotations

import inspect
import re
import sys
from pathlib import Path

import delayform

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "delayform"
author = "the delayform authors"
release = delayform.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",
    "offline_inventories",  # docs/_ext: the build passes without a network (below)
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "_generated/.keep", "**.ipynb_checkpoints"]
html_theme = "pydata_sphinx_theme"
html_static_path = ["_static"]
html_css_files = ["delayform.css"]  # wide tables scroll sideways instead of running off the page
html_title = f"delayform {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "secondary_sidebar_items": ["page-toc", "sourcelink"],
}
html_sidebars = {"index": []}  # the landing page is wide: it has its own table of contents

# intersphinx: numpy, scipy, matplotlib and python-control names in the reference and the
# pages link to their documentation. The inventories are fetched over the network at each
# build; a machine without one (CI reaches only package registries) must still build with
# warnings as errors, so the single "failed to reach any of the inventories" warning is
# demoted to an info line by the ``offline_inventories`` extension (Sphinx gives it no warning type,
# so ``suppress_warnings`` cannot name it; docs/_ext/offline_inventories.py). Offline, those
# names are plain text; every other warning still fails the build.
intersphinx_mapping = {
    "python": ("https://docs.python.org/3", None),
    "numpy": ("https://numpy.org/doc/stable/", None),
    "scipy": ("https://docs.scipy.org/doc/scipy/", None),
    "matplotlib": ("https://matplotlib.org/stable/", None),
    "control": ("https://python-control.readthedocs.io/en/stable/", None),
}
intersphinx_timeout = 10  # seconds: a blocked network fails fast instead of stalling the build

# numpydoc: no autosummary tables of members (each class's members are documented in place);
# See Also entries to names outside the reference are not turned into links that would warn
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()
autodoc_default_options = {"members": True, "inherited-members": False, "undoc-members": False}
autodoc_typehints = "signature"  # numpy, matplotlib and python-control types link to their docs (intersphinx)
autodoc_typehints_format = "short"
autodoc_member_order = "bysource"

# MyST: formulas are LaTeX, ``$...$`` inline and ``$$...$$`` (or amsmath environments) displayed,
# rendered by MathJax; the pages link to repository files outside docs/ (../src/...,
# ../examples/...), left as plain links rather than warnings.
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_dmath_double_inline = True
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


#: What each group of the reference answers, by its title. The groups themselves, their order and
#: their members are ``delayform._GROUPS`` (the same groups as docs/api.md), so a name another
#: engineer adds to a group there is documented without touching this file.
GROUP_SUMMARY: dict[str, str] = {
    "Topologies and the problem's nouns":
        "Who listens to whom, the team and its delays, the shape the team takes and where it ends up.",
    "Characteristic equations":
        "The characteristic factors of a team and quasi-polynomials in any number of delays.",
    "Analysis: stability maps":
        "Exact maps of the stable delay pairs: crossing curves, root tendencies, unstable-root counts.",
    "Analysis: roots":
        "Rightmost and dominant roots with their certificates, every root in a rectangle, neutral spectra.",
    "Analysis: regions and spectrum sets":
        "The eigenvalue plane: one answer for every graph, delays safe for a class of teams, large teams.",
    "Analysis: certificates":
        "Lyapunov-Krasovskii certificates for linear systems with time-varying delays.",
    "Analysis: networks":
        "Per-link delays, delay boxes, jitter margins and packet loss in the mean square, certified.",
    "Analysis: python-control loops":
        "Exact delay margins of python-control loops and their quasi-polynomials.",
    "Design": "Delays and gains chosen for the fastest certified decay, for teams and for loops.",
    "Simulation":
        "Robots and their limits, bodies and contacts, slot assignment, the safety filter, trajectories.",
    "Simulation: imperfect networks":
        "Imperfect networks in a simulation: per-link delays, variation, jitter, loss, sampling, noise.",
    "Simulation: Monte Carlo and sweeps":
        "Many runs at once, in one process or on Dask workers, and their quantiles.",
    "Deployment": "From a design to robots: profiles, the on-robot controller, recordings, the fit check.",
    "Outputs: scenarios, reports and the explorer":
        "A problem written down once (TOML), its report page, the interactive explorer and the shipped examples.",
    "Errors": "The exception tree: every refusal is one of these, a subclass of a built-in; and the warnings.",
}
#: constants carry no docstring of their own (theirs would be their type's)
CONSTANT_SUMMARY = {
    "PAPER_POINTS": "The delay pairs a-e of the paper's stability figure: a, b, d, e stable, c not.",
    "PROFILES": "Every robot profile by name (``delayform.robot_profile(name)`` returns one).",
    "IROBOT_CREATE": "The iRobot Create's limits (wheel speeds, turn rate; an assumed acceleration).",
    "errors": "The exception tree (module).",
}
#: names of ``__all__`` in no group of ``delayform._GROUPS``
OTHER_GROUP = "Other names"


def _group_stem(title: str) -> str:
    """The file stem of a group's page: ``"Analysis: roots"`` -> ``"analysis-roots"``."""
    return re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-")


def _group_of(name: str) -> str:
    for title, members in delayform._GROUPS.items():
        if name in members:
            return title
    return "Errors" if name == "errors" else OTHER_GROUP


def _order(name: str) -> tuple[int, int]:
    """Functions first (where a user starts), then classes (what they return), then constants."""
    obj = getattr(delayform, name)
    kind = 0 if inspect.isroutine(obj) else 1 if inspect.isclass(obj) else 2
    return kind, delayform.__all__.index(name)


def _summary(obj: object) -> str:
    """The first sentence of a docstring, as one line of rST (bars escaped, as in the pages)."""
    doc = inspect.getdoc(obj) if inspect.isclass(obj) or inspect.isroutine(obj) else None
    if not doc:
        return ""
    first = doc.split("\n\n")[0].replace("\n", " ").strip()
    return _escape_bars(first)


def _heading(title: str, mark: str = "=") -> str:
    return f"{title}\n{mark * len(title)}\n"


def write_api_reference() -> None:
    """One page per public name of ``delayform.__all__``, one page per group, and their index."""
    GENERATED.mkdir(exist_ok=True)
    for old in GENERATED.glob("*.rst"):
        old.unlink()
    names = [n for n in delayform.__all__ if n != "__version__"]
    members: dict[str, list[str]] = {}
    for name in names:
        obj = getattr(delayform, name)
        (GENERATED / f"{name}.rst").write_text(f"{_heading(f'``delayform.{name}``')}\n{_directive(name, obj)}")
        members.setdefault(_group_of(name), []).append(name)
    titles = [t for t in [*delayform._GROUPS, OTHER_GROUP] if t in members]
    for title in titles:
        rows = "".join(
            f"   * - :doc:`delayform.{n} <{n}>`\n     - {CONSTANT_SUMMARY.get(n) or _summary(getattr(delayform, n))}\n"
            for n in sorted(members[title], key=_order)
        )
        toc = "".join(f"   {n}\n" for n in sorted(members[title], key=_order))
        what = GROUP_SUMMARY.get(title, "Names not yet placed in a group of ``delayform._GROUPS``.")
        (GENERATED / f"group-{_group_stem(title)}.rst").write_text(
            f"{_heading(title)}\n{what}\n\n.. list-table::\n   :widths: 30 70\n\n{rows}\n"
            f".. toctree::\n   :hidden:\n\n{toc}"
        )
    toc = "".join(f"   group-{_group_stem(title)}\n" for title in titles)
    (GENERATED / "index.rst").write_text(
        f"{_heading('API reference')}\n"
        "Every name in ``delayform.__all__``, from its docstring (generated at build time), grouped\n"
        "as the problem is built up: the team, its quasi-polynomials, the maps and roots that\n"
        "answer stability, guarantees over real networks, design, simulation and deployment.\n"
        "Where each name lives in the package, and the conventions every name follows: :doc:`the API overview <../api>`.\n\n"
        f".. toctree::\n   :maxdepth: 2\n\n{toc}"
    )



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


write_api_reference()


def _top_level_split(params: str) -> list[str]:
    """Split a signature's parameter list at the commas outside brackets and quotes."""
    parts, depth, quote, start = [], 0, "", 0
    for k, ch in enumerate(params):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(params[start:k])
            start = k + 1
    parts.append(params[start:])
    return [part.strip() for part in parts if part.strip()]


#: type names as written in the source, kept unexpanded and linked (``ArrayLike`` would
#: otherwise print as a union of a dozen private numpy types); see ``tidy_signature``
autodoc_type_aliases = {
    "ArrayLike": "numpy.typing.ArrayLike",
    "NDArray": "numpy.typing.NDArray",
    "Axes": "matplotlib.axes.Axes",  # imported only for type checking: matplotlib loads lazily
}
_ANNOTATION_FIXES = (
    # an alias inside a union prints as its repr in this Sphinx; ``~`` shows the short name, linked
    (re.compile(r"TypeAliasForwardRef\('([\w.]+)'\)"), r"~\1"),
    (re.compile(r"(?<![\w.~])(NDArray|ArrayLike)\b"), r"~numpy.typing.\1"),
    (re.compile(r"(?<![\w.~])Axes\b"), "~matplotlib.axes.Axes"),
    (re.compile(r"(?<![\w.~])np\."), "~numpy."),
    (re.compile(r"(?<![\w.~])(numpy|matplotlib)\."), r"~\1."),  # full names shown short
)


def _tidy(text: str | None) -> str | None:
    if not text:
        return text
    for pattern, replacement in _ANNOTATION_FIXES:
        text = pattern.sub(replacement, text)
    return text


def tidy_signature(app, what, name, obj, options, signature, return_annotation):  # noqa: ARG001
    """Signatures as a user reads them: numpy aliases short and linked, no private fields.

    A result dataclass's private fields (``_axis1``, ...) are not arguments a user passes.
    """
    signature, return_annotation = _tidy(signature), _tidy(return_annotation)
    if what == "class" and signature and signature.startswith("("):
        kept = [p for p in _top_level_split(signature[1:-1]) if not p.lstrip("*").startswith("_")]
        if kept and kept[-1] == "*":  # a bare * with no keyword left after it is not a signature
            kept.pop()
        signature = f"({', '.join(kept)})"
    return signature, return_annotation


def setup(app):  # noqa: ANN001, ANN201
    app.connect("autodoc-process-signature", tidy_signature)
    # before numpydoc (priority 500), so it sees the docstring as written
    app.connect("autodoc-process-docstring", escape_absolute_values, priority=400)
    return {"parallel_read_safe": True}
