"""The paper's report in a real browser: headless Chromium loads the page and every image in it.

Chromium is installed by the test set-up (``make test`` runs ``make browser``);
without it these tests skip and say why.
"""

from __future__ import annotations

import json
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from test_cli import paper_output

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")

#: Appended to a copy of the page: after the load event, write what every <img> did into the DOM.
CHECK_SCRIPT = """
<script>
window.addEventListener("load", () => {
  const imgs = Array.from(document.images);
  const broken = imgs.filter((img) => !(img.complete && img.naturalWidth > 0));
  const out = document.createElement("pre");
  out.id = "image-check";
  out.textContent = JSON.stringify({
    total: imgs.length,
    loaded: imgs.length - broken.length,
    broken: broken.map((img) => img.alt),
    widths: imgs.map((img) => img.naturalWidth),
  });
  document.body.appendChild(out);
});
</script>
"""


def chromium(*args: str, profile: Path) -> subprocess.CompletedProcess[str]:
    """Headless Chromium with nothing that reaches the network or keeps state."""
    assert CHROMIUM is not None
    flags = [
        "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--disable-dev-shm-usage", f"--user-data-dir={profile}",
    ]  # fmt: skip
    return subprocess.run([CHROMIUM, *flags, *args], capture_output=True, text=True, timeout=180)


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (make test installs it as root where apt-get exists)")
    out, _ = paper_output(tmp_path_factory)
    return out / "index.html"


def test_every_image_loads_in_chromium(report: Path, tmp_path: Path) -> None:
    page = report.read_text(encoding="utf-8")
    expected = page.count("<img ")
    assert expected >= 6  # chart, x/y at a and b, traces at a, surface, contour
    probe = tmp_path / "probe.html"
    probe.write_text(page.replace("</body>", CHECK_SCRIPT + "</body>"), encoding="utf-8")
    proc = chromium("--virtual-time-budget=10000", "--dump-dom", probe.as_uri(), profile=tmp_path / "profile")
    match = re.search(r'<pre id="image-check">(.*?)</pre>', proc.stdout, re.S)
    assert match, f"no image check in the dumped DOM (exit {proc.returncode}): {proc.stderr[-500:]}"
    result = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert result["total"] == expected
    assert result["broken"] == []
    assert result["loaded"] == expected
    assert min(result["widths"]) > 100


def _png_size(path: Path) -> tuple[int, int]:
    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", header[16:24])


def test_screenshot_of_the_report(report: Path, tmp_path: Path) -> None:
    shot = report.parent / "screenshot.png"  # kept next to the report for a human to look at
    proc = chromium("--window-size=1200,2400", "--hide-scrollbars", f"--screenshot={shot}", report.as_uri(),
                    profile=tmp_path / "profile")  # fmt: skip
    assert shot.exists(), proc.stderr[-500:]
    assert _png_size(shot) == (1200, 2400)
    # a blank page compresses to a few kilobytes; the report's figures do not
    assert shot.stat().st_size > 50_000
