"""The documentation site builds with warnings as errors, tutorials executed.

A broken docstring (bad numpydoc section, an unknown reference) or a tutorial
cell that raises fails this test, as it fails ``make docs``. The build runs
without a network here, as on CI: the intersphinx inventories cannot be
fetched, and the build must pass all the same.
"""

from __future__ import annotations

import contextlib
import io
import logging
import re
import subprocess
import sys
from pathlib import Path

import pytest

import delayform

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted(p.stem for p in (ROOT / "docs" / "tutorials").glob("*.ipynb"))


@pytest.mark.slow
def test_documentation_site_builds_with_every_public_name_and_tutorial(tmp_path: Path) -> None:
    out = tmp_path / "html"
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q",
         "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(out)],
        capture_output=True, text=True, timeout=900, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-4000:]
    for name in delayform.__all__:
        if name == "__version__":
            continue
        page = out / "_generated" / f"{name}.html"
        assert page.is_file(), f"no reference page for {name}"
        assert f"delayform.{name}" in page.read_text(encoding="utf-8")
    assert len(TUTORIALS) >= 4
    for stem in TUTORIALS:
        html = (out / "tutorials" / f"{stem}.html").read_text(encoding="utf-8")
        assert "<img" in html, f"tutorial {stem} shows no figure: was it executed?"
    for page in ("cli", "theory", "glossary", "api", "loops", "benchmarks", "benchmarks-history"):
        assert (out / f"{page}.html").is_file()
    landing = (out / "index.html").read_text(encoding="utf-8")
    assert re.search(r'<img[^>]*src="_images/stability_chart\.png"', landing), "the landing page shows no chart"
    text = re.sub(r"<[^>]+>", "", landing)  # inline code is split into spans
    for piece in ("pip install delayform", "Quick start", "stability_map(team"):
        assert piece in text, f"the landing page has no {piece!r}"
    # formulas reach MathJax as math, not as code
    theory = (out / "theory.html").read_text(encoding="utf-8")
    assert theory.count('class="math') >= 10 and "e^{-tau1 s}" not in theory
    # the reference is grouped: every name page is reached from one group page
    groups = sorted((out / "_generated").glob("group-*.html"))
    assert len(groups) >= 10
    linked = set()
    for group in groups:
        linked |= set(re.findall(r'href="([A-Za-z_]\w*)\.html"', group.read_text(encoding="utf-8")))
    assert {n for n in delayform.__all__ if n != "__version__"} <= linked


# ================================================================ the landing page's quick start
def _quick_start() -> str:
    text = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    section = text.split("## Quick start", 1)[1]
    return re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)


def test_landing_page_quick_start_is_five_lines_and_prints_what_it_says() -> None:
    code = _quick_start()
    assert len(code.strip().splitlines()) == 5
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/index.md", "exec"), {})
    first, second = out.getvalue().splitlines()
    # the paper's stability figure: point a (0.3, 0.2) in the stable region, point c (1, 2) outside
    assert first == "True False"
    root = complex(second)
    assert root.real < 0 and 1.0 < root.imag < 1.2
    assert f"{root.real:.3f}" in code and f"{root.imag:.3f}" in code  # the comment states the root printed


def test_landing_page_install_lists_every_extra_of_the_readme() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    landing = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    extras = set(re.findall(r"pip install 'delayform\[(\w+)\]'", readme))
    assert extras >= {"explore", "cluster", "ros", "safety", "control", "certificates", "all"}
    assert not [e for e in extras if f"| `{e}` |" not in landing], "an extra of README.md is missing from docs/index.md"


# ================================================================ offline builds
def _offline_filter():
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        import offline_inventories
    finally:
        sys.path.pop(0)
    return offline_inventories


def _record(cause: str) -> logging.LogRecord:
    msg = "failed to reach any of the inventories with the following issues:\n%s"
    return logging.LogRecord("sphinx.sphinx.ext.intersphinx", logging.WARNING, __file__, 1, msg, (cause,), None)


def test_unreachable_inventories_are_an_info_line_only_when_there_is_no_network() -> None:
    ext = _offline_filter()
    offline = _record("intersphinx inventory 'x' not fetchable due to <class 'requests.exceptions.ConnectionError'>")
    assert ext.OfflineInventories().filter(offline) and offline.levelno == logging.INFO
    wrong = _record("intersphinx inventory 'x' not fetchable due to <class 'requests.exceptions.HTTPError'>: 404")
    assert ext.OfflineInventories().filter(wrong) and wrong.levelno == logging.WARNING
    other = logging.LogRecord("sphinx.sphinx.ext.intersphinx", logging.WARNING, __file__, 1, "ConnectionError", (), None)
    assert ext.OfflineInventories().filter(other) and other.levelno == logging.WARNING
