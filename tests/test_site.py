"""The documentation site builds with warnings as errors, tutorials executed (issue 23).

A broken docstring (bad numpydoc section, an unknown reference) or a tutorial
cell that raises fails this test, as it fails ``make docs``.
"""

from __future__ import annotations

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
    for page in ("cli", "theory", "glossary", "api", "loops"):
        assert (out / f"{page}.html").is_file()
