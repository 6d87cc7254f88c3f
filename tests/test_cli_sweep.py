"""``delayform sweep``: every grid cell equals a Monte Carlo run at that delay pair; one-line errors, exit 2."""

from __future__ import annotations

import csv
import statistics
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_in_process


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``delayform sweep ARGS`` in-process (``tests/test_cli.py`` runs the entry point in a subprocess)."""
    return run_in_process("sweep", *args, cwd=cwd)


def test_grid_cells_equal_monte_carlo_at_each_delay_pair(tmp_path: Path) -> None:
    from delayform.formation import named_formation
    from delayform.simulation import BernoulliLoss, Network, monte_carlo
    from delayform.topology import paper_six

    args = ("--tau1-values", "0.1:2.0:3", "--tau2-values", "0.1,1.5", "--runs", "2", "--model", "double_integrator",
            "--duration", "40", "--dt", "0.05", "--seed", "4", "--out", "sw", "--json")  # fmt: skip
    path = tmp_path / "lossy.toml"
    path.write_text((Path(__file__).parents[1] / "examples" / "paper.toml").read_text() + "\n[network]\nloss = 0.2\n")
    proc = run(str(path), *args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    assert printed["tau1"] == pytest.approx([0.1, 1.05, 2.0]) and printed["tau2"] == [0.1, 1.5]
    with (tmp_path / "sw" / "sweep.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6
    with np.load(tmp_path / "sw" / "sweep.npz") as npz:
        grid = dict(npz)
    assert grid["settling_median"].shape == (3, 2)
    # an independent call per cell: the library Monte Carlo at that delay pair, same seed
    topo = paper_six()
    for i, j in ((0, 0), (2, 1)):
        t1, t2 = printed["tau1"][i], printed["tau2"][j]
        mc = monte_carlo(topo, 1.0, 0.5, t1, t2, named_formation("hexagon", 6, spacing=2.0), model="double_integrator",
                         network=Network(loss=BernoulliLoss(0.2)), runs=2, seed=4, duration=40.0, dt=0.05)  # fmt: skip
        want = statistics.median(mc.settling_times.tolist())  # the ordinary median (issue 24)
        assert grid["settling_median"][i, j] == pytest.approx(want, rel=1e-12) or (
            np.isinf(want) and np.isinf(grid["settling_median"][i, j]))
        assert float(rows[2 * i + j]["settled_fraction"]) == mc.settled_fraction
    # the small delays settle; the paper's unstable corner does not
    assert grid["settled_fraction"][0, 0] == 1.0 and grid["settled_fraction"][2, 1] == 0.0
    assert (tmp_path / "sw" / "sweep_settling.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--tau1-values", "1:0.5:3", "--tau2-values", "0.2"), "delays must increase"),
        (("--tau1-values", "0.1:1", "--tau2-values", "0.2"), "START:STOP:COUNT"),
        (("--tau1-values", "0.1:1:0", "--tau2-values", "0.2"), "COUNT must be between 1 and 200"),
        (("--tau1-values", "-1,0.5", "--tau2-values", "0.2"), "finite and >= 0"),
        (("--tau1-values", "0.3", "--tau2-values", "0.2", "--tau1", "0.3"), "--tau1-values"),
        (("--tau1-values", "0.3", "--tau2-values", "0.2", "--workers", "2", "--scheduler", "tcp://x:1"), "not both"),
        (("--tau1-values", "0.3", "--tau2-values", "0.2", "--scheduler", "tcp://127.0.0.1:1"), "cannot reach"),
        (("--tau1-values", "0:5:200", "--tau2-values", "0:5:200", "--runs", "1000"), "would take about"),
        (("--tau1-values", "0.3", "--tau2-values", "0.001"), "dt"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, tuple) else None,
)
def test_malformed_sweeps_exit_2_with_one_line(tmp_path: Path, args: tuple[str, ...], needle: str) -> None:
    proc = run(*args, "--duration", "2", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("delayform: error: "), proc.stderr
    assert needle in lines[0], lines[0]
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert not (tmp_path / "out").exists()
