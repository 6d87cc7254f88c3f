"""``delayform region`` and ``delayform safe-delays`` (issue 11), run in-process as a subprocess would see them."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_in_process
from test_cli import assert_one_line_error

from delayform.analysis.plane.spectrum_sets import safe_delays
from delayform.analysis.plane.region import lambda_region
from delayform.topology import paper_six


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``delayform ARGS`` on this checkout's sources, in-process (``tests/test_cli.py`` runs the entry point)."""
    return run_in_process(*args, cwd=cwd)


def test_region_json_equals_the_library(tmp_path: Path) -> None:
    proc = run("region", "--tau1", "1", "--tau2", "2", "--out", str(tmp_path / "o"), "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    region = lambda_region(1.0, 0.5, 1.0, 2.0)
    lam = paper_six().eigenvalues
    assert out["unstable_roots"] == region.unstable_count(lam).tolist()
    assert out["team_stable"] is False and out["safe_for_every_team"] is False
    for name in ("lambda_region.png", "lambda_region.svg", "eigenvalue_region.csv"):
        assert (tmp_path / "o" / name).is_file()


def test_safe_delays_text_and_json(tmp_path: Path) -> None:
    proc = run("safe-delays", "--spectrum", "undirected", "--tau1-max", "4", "--tau2-max", "4",
               "--point", "a=0.3,0.2", "--point", "c=1,2", "--out", str(tmp_path / "o"), "--json", cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="undirected")
    assert out["safe_fraction"] == pytest.approx(m.safe_fraction(resolution=200))
    assert [p["safe"] for p in out["points"]] == [True, False]
    with np.load(tmp_path / "o" / "safe_delays.npz") as npz:
        data = dict(npz)
    assert data["safe"].shape == (200, 200)
    proc = run("safe-delays", "--spectrum", "any", "--tau1-max", "4", "--tau2-max", "4", "--out", str(tmp_path / "p"),
               cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "safe fraction of the window  0.000" in proc.stdout


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("safe-delays", "--spectrum", "ball:1,2"), "ball:1,2"),
        (("safe-delays", "--spectrum", "disc:0,-1"), "radius"),
        (("safe-delays", "--point", "z=9,1", "--tau1-max", "4"), "outside the window"),
        (("region", "--tau1", "-1"), "--tau1"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, tuple) else None,
)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, args: tuple[str, ...], needle: str) -> None:
    assert_one_line_error(run(*args, cwd=tmp_path), needle)
