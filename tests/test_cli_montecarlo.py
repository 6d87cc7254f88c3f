"""``delayform montecarlo``: JSON equal to the library, one-line errors with exit code 2."""

from __future__ import annotations

import json
from dataclasses import replace
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_in_process


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``delayform montecarlo ARGS`` in-process (``tests/test_cli.py`` runs the entry point in a subprocess)."""
    return run_in_process("montecarlo", *args, cwd=cwd)


SMALL = """\
[topology]
name = "ring"
n = 3
[gains]
P = 1.0
D = 0.5
[delays]
tau1 = 0.3
tau2 = 0.2
[formation]
shape = "polygon"
[simulation]
model = "double_integrator"
duration = 4.0
dt = 0.05
"""


def test_json_equals_the_library(tmp_path: Path) -> None:
    from delayform.simulation import BernoulliLoss, Jitter, Network, monte_carlo
    from delayform.topology import ring

    path = tmp_path / "small.toml"
    path.write_text(SMALL + "[network]\nloss = 0.3\nseed = 9\n")
    proc = run(str(path), "--runs", "5", "--seed", "3", "--jitter", "0.1,0.05", "--out", "mc", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    lib = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", network=Network(loss=BernoulliLoss(0.3), jitter=Jitter(0.1, 0.05)),
                      runs=5, seed=3, duration=4.0, dt=0.05).summary()  # fmt: skip
    assert printed["runs"] == 5 and printed["setup"]["network"] == "jitter +-(0.1, 0.05) s, loss 0.3"
    assert printed["final_error"]["median"] == pytest.approx(lib["final_error"]["median"], rel=1e-12)
    assert printed["peak_command_1"]["max"] == pytest.approx(lib["peak_command_1"]["max"], rel=1e-12)
    rows = np.loadtxt(tmp_path / "mc" / "montecarlo_runs.csv", delimiter=",", skiprows=1)
    assert rows.shape == (5, 7)
    assert {f.rsplit("/", 1)[-1] for f in printed["files"]} >= {"montecarlo_bands.png", "montecarlo_histograms.svg"}


def test_robots_with_limits_from_the_robot_table_and_the_options(tmp_path: Path) -> None:
    from delayform.simulation import IROBOT_CREATE, BernoulliLoss, Network, monte_carlo
    from delayform.topology import ring

    path = tmp_path / "robots.toml"
    path.write_text(SMALL.replace('"double_integrator"', '"unicycle"') + "[robot]\nmax_acceleration = 0.3\n[network]\nloss = 0.3\n")
    proc = run(str(path), "--runs", "3", "--seed", "2", "--max-turn-rate", "1.5", "--out", "mc", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    lim = replace(IROBOT_CREATE, max_acceleration=0.3, max_turn_rate=1.5)
    lib = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", model="unicycle", network=Network(loss=BernoulliLoss(0.3)),
                      runs=3, seed=2, duration=4.0, dt=0.05, limits=lim).summary()  # fmt: skip
    assert printed["setup"]["robots"] == lim.describe()
    assert printed["peak_command_1"]["max"] == pytest.approx(lib["peak_command_1"]["max"], rel=1e-12)
    assert printed["peak_command_1"]["max"] <= 0.3 * (1 + 1e-6) and printed["peak_command_2"]["max"] <= 1.5 * (1 + 1e-6)
    ideal = run(str(path), "--runs", "3", "--seed", "2", "--no-limits", "--out", "mc2", "--json", cwd=tmp_path)
    assert json.loads(ideal.stdout)["setup"]["robots"] == "ideal"


@pytest.mark.parametrize(
    ("table", "args", "needle"),
    [
        ("loss = { p_good_to_bad = 0.1 }", (), "network.loss.p_bad_to_good"),
        ("", ("--jitter", "0.28,0.0"), "below the step"),
        ("", ("--loss", "0.1", "--burst", "0.1,0.3"), "--burst"),
        ("", ("--scheduler", "tcp://127.0.0.1:1"), "cannot reach a Dask scheduler"),
        ("", ("--limits",), "use --model unicycle"),
        ("", ("--no-limits", "--max-speed", "0.3"), "--no-limits cannot be combined with --max-speed"),
        ("", ("--runs", "100000", "--duration", "1000", "--dt", "0.01"), "would take about"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, tuple) else None,
)
def test_malformed_network_settings_exit_2_with_one_line(tmp_path: Path, table: str, args: tuple[str, ...], needle: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(SMALL + (f"[network]\n{table}\n" if table else ""))
    proc = run(str(path), *(args if "--runs" in args else ("--runs", "2", *args)), "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("delayform: error: "), proc.stderr
    assert needle in lines[0], lines[0]
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        ("loss = 1.5", "network.loss.probability"),
        ("jitter = [0.1]", "network.jitter"),
        ("rate = -2.0", "network.rate"),
        ("colour = 1", "network.colour"),
        ("tau1 = [[0.3, 0.3], [0.3, 0.3]]", "network.tau1"),
        ("delay_spread = 1.5", "network.delays.spread"),
        ("variation = { amplitude = [1.0, 0.0], period = 2.0 }", "network.variation"),
        ("noise = [-0.1, 0.0]", "network.noise.position"),
        ("seed = -3", "network.seed"),
        ("loss = { p_good_to_bad = 0.1, p_bad_to_good = 0.2, burst = 3 }", "network.loss.burst"),
    ],
)
def test_malformed_network_tables_name_the_key(table: str, needle: str) -> None:
    import tomllib

    from delayform.errors import ScenarioError
    from delayform.scenario import parse_scenario

    with pytest.raises(ScenarioError, match="x.toml: " + needle.replace(".", r"\.")) as info:
        parse_scenario(tomllib.loads(SMALL + f"[network]\n{table}\n"), source="x.toml")
    assert "\n" not in str(info.value)


def test_the_shipped_lossy_example_loads() -> None:
    from delayform.scenario import load_scenario
    from delayform.model.network import GilbertElliott

    sc = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "lossy.toml")
    assert isinstance(sc.network.loss, GilbertElliott) and sc.network.sampling.rate == 10.0
    assert sc.network.packets and not sc.network.is_ideal
