"""The wheel installs into a bare virtual environment and every command runs from it.

Slow: it builds the wheel, makes one venv without the project and installs
the wheel there (dependencies from the configured index or pip's cache), in
the order a user adds to it. This run's pip installs into the venv (``pip
--python``): the venv's own copy of pip would be installed, and its modules
compiled on each call, for nothing the checks look at (pip is not counted). Without extras (``pip install delayform``), the
core stays small, its commands run, and a command that needs an extra says
which in one line. Then with every extra (``pip install delayform[all]`` in
the same venv, as the one-line message tells the user), each ``delayform``
command runs on a shipped example, the explorer included (its page, script
and Plotly served from the installed package).

One venv for both rather than one each: the core's packages (numpy, SciPy,
matplotlib: most of its 380 MiB) are installed once instead of twice, and
pip resolves ``[all]`` over them exactly as it would in an empty venv (the
same requirements, none of them pinned by the core), so the extras' check is
the same.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import urllib.request
import zipfile
from pathlib import Path

import pytest

import delayform
from delayform.cli import cli

ROOT = Path(__file__).resolve().parents[1]


def _call(args: list[str], *, timeout: float = 600, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    # without PYTHONPATH: the bare venv must import the installed wheel, never a source tree
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, cwd=cwd, check=False, env=env)


def _run(args: list[str], *, timeout: float = 600, cwd: Path | None = None) -> str:
    done = _call(args, timeout=timeout, cwd=cwd)
    assert done.returncode == 0, f"{' '.join(args)}\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


#: a quick real run of every command (``paper`` is the whole paper, ~40 s: its --help only here;
#: tests/test_cli.py runs it from the source tree)
def _invocations(example: str, out: str) -> dict[str, list[str]]:
    return {
        "factors": [example],
        "chart": [example, "--out", out, "--tau1-max", "2", "--tau2-max", "2", "--jitter-margin", "--jitter-grid", "4"],
        "roots": [example, "--out", out],
        "map": [example, "--out", out, "--size", "5,5", "--actuation-delay", "0.1"],
        "schedule": [example, "--out", out, "--actuation-delay", "0"],
        "gains": [example, "--out", out, "--grid", "5"],
        "simulate": [example, "--out", out, "--duration", "5", "--dt", "0.05"],
        "report": [example, "--out", out, "--actuation-delay", "0", "--jitter-grid", "3"],
        "region": [example, "--out", out],
        "safe-delays": [example, "--out", out, "--tau1-max", "2", "--tau2-max", "2"],
        "montecarlo": [example, "--out", out, "--runs", "2", "--duration", "5"],
        "sweep": [example, "--out", out, "--tau1-values", "0.2:0.4:2", "--tau2-values", "0.2:0.4:2",
                  "--runs", "1", "--duration", "5"],  # fmt: skip
        "links": [example],
        "box": [example, "--tau1-box", "0.1,0.2", "--tau2-box", "0.1,0.2"],
        "jitter": [example],
        "check": [example.replace("ring12", "create3_hexagon")],  # a design that fits: exit 0
        # four processes from the installed package (python -m delayform.fleet.agents), 2 s of wall clock:
        # three robots are enough to start every kind of process (tests/test_fleet.py runs the six)
        "fleet": [example, "--topology", "ring", "--n", "3", "--out", out, "--duration", "2",
                  "--endpoint", f"tcp/127.0.0.1:{_free_port()}"],
        "paper": ["--help"],
    }


def _check_explorer(exe: Path, out: Path) -> None:
    with subprocess.Popen([str(exe), "explore", "--port", "0", "--no-browser", "--out", str(out)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as proc:  # fmt: skip
        try:
            line = proc.stdout.readline() if proc.stdout else ""
            url = re.search(r"http://[0-9.]+:\d+/", line)
            assert url, f"explorer did not start: {line!r}"
            for path in ("", "static/explorer.js", "static/explorer.css", "static/plotly.min.js"):
                with urllib.request.urlopen(url.group(0) + path, timeout=30) as response:
                    assert response.status == 200 and len(response.read()) > 100, path
        finally:
            proc.terminate()
            proc.wait(timeout=30)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The project's wheel, built once for this module's tests, with what it must ship checked."""
    dist = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(ROOT)], timeout=600)
    (built,) = dist.glob("delayform-*.whl")
    assert built.name.startswith(f"delayform-{delayform.__version__}-")
    names = set(zipfile.ZipFile(built).namelist())
    shipped = {"delayform/py.typed"} | {f"delayform/app/static/{p.name}" for p in (ROOT / "src/delayform/app/static").iterdir()}
    shipped |= {f"delayform/examples/{p.name}" for p in (ROOT / "examples").glob("*.toml")}
    shipped |= {f"delayform-{delayform.__version__}.dist-info/licenses/LICENSE"}
    assert shipped <= names, f"missing from the wheel: {sorted(shipped - names)}"
    return built


def _venv(where: Path, requirement: str) -> tuple[Path, Path]:
    """A fresh venv at ``where`` with ``requirement`` installed: its python and its delayform."""
    _run([sys.executable, "-m", "venv", "--without-pip", str(where)])
    python, exe = where / "bin" / "python", where / "bin" / "delayform"
    _pip_install(python, requirement)
    return python, exe


def _pip_install(python: Path, *args: str) -> None:
    """``pip install ARGS`` into the venv of ``python`` by this run's pip."""
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet", *args], timeout=1200)


#: what `pip install delayform` may bring at most (delayform and its dependencies; pip and
#: setuptools come with the venv): the core's numbers are in docs/benchmarks.md
CORE_PACKAGES = 20
CORE_MIB = 400

#: the size (bytes) of every installed distribution's files but the venv's own pip and setuptools
_INSTALLED = """
import importlib.metadata as md, json
dists = [d for d in md.distributions() if d.metadata["Name"].lower() not in ("pip", "setuptools")]
size = sum(f.locate().stat().st_size for d in dists for f in d.files or [] if f.locate().is_file())
print(json.dumps({"names": sorted(d.metadata["Name"] for d in dists), "bytes": size}))
"""


def _check_core(python: Path, exe: Path, cwd: Path) -> None:
    """The bare ``pip install delayform``: small, its commands run, the explorer names its extra."""
    found = json.loads(_run([str(python), "-c", _INSTALLED], cwd=cwd))
    assert len(found["names"]) <= CORE_PACKAGES, f"{len(found['names'])} packages: {found['names']}"
    assert found["bytes"] < CORE_MIB * 2**20, f"{found['bytes'] / 2**20:.0f} MiB"
    assert not {"plotly", "dask", "distributed", "starlette", "uvicorn", "mcap", "rosbags", "clarabel"} & {
        n.lower() for n in found["names"]}  # fmt: skip

    out = cwd / "out-core"
    _run([str(exe), "chart", "--out", str(out), "--tau1-max", "2", "--tau2-max", "2"], cwd=cwd)
    _run([str(exe), "roots", "--out", str(out)], cwd=cwd)
    refused = _call([str(exe), "explore", "--no-browser", "--port", "0"], timeout=300, cwd=cwd)
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr.strip().endswith("pip install 'delayform[explore]'"), refused.stderr


#: every command through the installed package's CLI in one interpreter (the console script itself
#: is run by the other checks): each must exit 0; one start-up and import instead of sixteen
_EVERY_COMMAND = """
import json, sys
from delayform.cli import main
for command, args in json.loads(sys.argv[1]).items():
    try:
        main([command, *args])
        code = 0
    except SystemExit as exc:
        code = exc.code
    if code not in (0, None):
        sys.exit(f"delayform {command} exited with {code!r}")
"""


def _check_every_command(python: Path, exe: Path, env: Path, cwd: Path) -> None:
    """With ``[all]``: every command runs from the installed package, the explorer serves its page."""
    version, example = _run(
        [str(python), "-c", "import delayform; print(delayform.__version__); print(delayform.example_path('ring12'))"],
        cwd=cwd,
    ).split()
    assert version == delayform.__version__ and str(env) in example  # from the installed package, not the checkout

    out = cwd / "out"
    calls = _invocations(example, str(out))
    assert set(calls) | {"explore"} == set(cli.commands), "a command is not exercised from the wheel"
    _run([str(python), "-c", _EVERY_COMMAND, json.dumps(calls)], cwd=cwd)
    assert _run([str(exe), "--version"]).strip().endswith(delayform.__version__)
    _check_explorer(exe, out)


@pytest.mark.slow
def test_the_core_install_is_small_then_every_extra_runs_every_command(wheel: Path, tmp_path: Path) -> None:
    env = tmp_path / "venv"
    python, exe = _venv(env, str(wheel))
    _check_core(python, exe, tmp_path)
    # --no-compile: the extras' thousands of modules (Plotly's validators) are not byte-compiled ahead;
    # Python compiles what a command imports, and the size measured above is the core's, compiled
    _pip_install(python, "--no-compile", f"{wheel}[all]")
    _check_every_command(python, exe, env, tmp_path)
