"""``pip install delayform`` without extras: the core works, and what needs an extra says which.

The checks run in one fresh interpreter whose import system refuses the
optional packages (a meta-path finder that raises ModuleNotFoundError for
them, as a core install would), so nothing this test process has imported
can leak in. That interpreter runs every check of this module in turn, each
in its own empty folder with its own output captured (as
``tests/cli_runner.py`` runs the command line in this process); the code
checks come first, so that "no optional package was even tried" covers every
import they make. One start-up and one import of delayform instead of
sixteen: an optional package stays refused for the whole run, so no check
can pass on what an earlier one imported. tests/test_wheel.py installs the
wheel without extras into a bare virtual environment and checks the same
from there.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

import delayform
from delayform._extras import EXTRAS, require_extra
from delayform.errors import DelayformError, MissingExtraError

ROOT = Path(__file__).resolve().parents[1]
#: the top-level modules of every extra: what a core install does not have
BLOCKED = sorted({m for _, modules in EXTRAS.values() for m in modules} | {"anyio"})

#: a fresh interpreter without the extras that runs every check (argv: the checks as JSON, the
#: results file); a check is ``["code", SOURCE]`` (Python) or ``["cli", ARGS...]`` (the command line)
_RUNNER = f"""
import json
import sys
import traceback

BLOCKED = {set(BLOCKED)!r}


REFUSED = []  # every import of an optional package that was tried (and refused)


class _Blocker:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.partition(".")[0] in BLOCKED:
            REFUSED.append(name)
            raise ModuleNotFoundError(f"No module named {{name!r}} (blocked: not in the core)", name=name)
        return None


assert not [m for m in sys.modules if m.partition(".")[0] in BLOCKED], "imported before the blocker"
sys.meta_path.insert(0, _Blocker())
sys.path.insert(0, {str(Path(__file__).parent)!r})
from cli_runner import _as_a_process, _text, run_in_process

checks, results = json.loads(sys.argv[1]), {{}}
for name, (cwd, mode, *args) in checks.items():
    try:
        if mode == "code":
            code = 0
            with _as_a_process(cwd) as (out, err):
                try:
                    exec(compile(args[0], "<core>", "exec"), {{"REFUSED": REFUSED}})
                except SystemExit as exc:
                    code = exc.code
            done = [int(code or 0), _text(out), _text(err)]
        else:
            proc = run_in_process(*args, cwd=cwd, timeout=300)
            done = [proc.returncode, proc.stdout, proc.stderr]
    except BaseException:  # a fresh interpreter would print the traceback and exit 1
        done = [1, "", traceback.format_exc()]
    results[name] = done
with open(sys.argv[2], "w", encoding="utf-8") as f:
    json.dump(results, f)
"""


def _readme_first_python_example() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## In Python", 1)[1]
    return re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)


#: the README's example: not even tried, no core path falls back quietly when an optional package is
#: missing (REFUSED counts from the interpreter's start: the delay margin below runs second)
README = "import delayform\n" + _readme_first_python_example() + "\nprint('tried:', REFUSED)"

#: L = 2 / (s + 1): |L(jw)| = 1 at w = sqrt(3), phase margin pi - atan(sqrt 3) = 2 pi / 3, tau = PM / w
DELAY_MARGIN = ("import math\nfrom delayform import delay_margin\n"
                "m = delay_margin(([2.0], [1.0, 1.0]))\n"
                "print(abs(m.tau - (2 * math.pi / 3) / math.sqrt(3)) < 1e-12, REFUSED)")  # fmt: skip

#: each call must raise MissingExtraError (an ImportError too) naming its extra, before any work
LIBRARY_EXTRAS = """
from delayform.errors import MissingExtraError
from delayform.simulation.bodies.safety import BarrierFilter
from delayform.simulation.experiments.sweeps import check_workers, parse_scheduler
from delayform.deploy.recording import check_mcap_path
from delayform.loops import delay_margin
from delayform.app import create_app
from delayform import time_varying_delay_margin
from delayform import simulate
from delayform.topology import paper_six
calls = {
    "cluster": [lambda: check_workers(1), lambda: parse_scheduler("tcp://127.0.0.1:8786")],
    "ros": [lambda: check_mcap_path("run.mcap")],
    "safety": [lambda: BarrierFilter()],
    "control": [lambda: delay_margin(object())],
    "explore": [lambda: create_app(None)],
    "certificates": [lambda: time_varying_delay_margin([[-2.0, 0.0], [0.0, -0.9]], [[-1.0, 0.0], [-1.0, -1.0]])],
    "physics": [lambda: simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", model="physics", duration=1.0, dt=0.01)],
}
for extra, fns in calls.items():
    for fn in fns:
        try:
            fn()
        except ImportError as exc:
            assert isinstance(exc, MissingExtraError) and exc.extra == extra, (extra, exc)
            print(exc)
        else:
            raise AssertionError(f"no error for {extra}")
"""

#: core commands, each a real (short) run of the paper's team; montecarlo without workers runs here
CORE_COMMANDS = {
    "chart": ["chart", "--out", "out", "--tau1-max", "2", "--tau2-max", "2"],
    "roots": ["roots", "--out", "out"],
    "simulate": ["simulate", "--out", "out", "--duration", "5", "--dt", "0.05"],
    "montecarlo": ["montecarlo", "--out", "out", "--runs", "2", "--duration", "5"],
}

#: commands that need an extra, with the extra they must name
NEEDS_AN_EXTRA = {
    "explore": (["explore", "--no-browser", "--port", "0", "--out", "out"], "explore"),
    "montecarlo --workers": (["montecarlo", "--out", "out", "--runs", "2", "--workers", "2"], "cluster"),
    "montecarlo --scheduler": (["montecarlo", "--out", "out", "--scheduler", "tcp://127.0.0.1:8786"], "cluster"),
    "sweep --workers": (["sweep", "--out", "out", "--tau1-values", "0.2:0.4:2", "--tau2-values", "0.2:0.4:2",
                         "--workers", "1"], "cluster"),  # fmt: skip
    "simulate --mcap": (["simulate", "--out", "out", "--mcap", "run.mcap"], "ros"),
    "simulate --safety": (["simulate", "--out", "out", "--safety", "barrier"], "safety"),
    "fleet": (["fleet", "--out", "out", "--duration", "2"], "fleet"),
    "simulate --model physics": (["simulate", "--out", "out", "--model", "physics"], "physics"),
    "montecarlo --model physics": (["montecarlo", "--out", "out", "--runs", "2", "--model", "physics"], "physics"),
}


@pytest.fixture(scope="module")
def core(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[subprocess.CompletedProcess[str], Path]]:
    """Every check of this module run in one fresh interpreter without the extras, in order.

    Returns each check's exit code and output, and the folder it ran in (empty before it ran).
    """
    checks: dict[str, list[str]] = {
        "readme": ["code", README], "delay margin": ["code", DELAY_MARGIN], "library": ["code", LIBRARY_EXTRAS],
    }  # fmt: skip
    checks |= {f"core {name}": ["cli", *args] for name, args in CORE_COMMANDS.items()}
    checks |= {f"extra {name}": ["cli", *args] for name, (args, _) in NEEDS_AN_EXTRA.items()}
    base = tmp_path_factory.mktemp("core")
    folders = {name: base / f"check{i}" for i, name in enumerate(checks)}
    for folder in folders.values():
        folder.mkdir()
    results = base / "results.json"
    # this checkout's delayform, before any other on the path
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(delayform.__file__).parents[1]),
                                                        os.environ.get("PYTHONPATH", "")]))  # fmt: skip
    argv = json.dumps({name: [str(folders[name]), *check] for name, check in checks.items()})
    done = subprocess.run([sys.executable, "-c", _RUNNER, argv, str(results)], capture_output=True, text=True,
                          timeout=900, cwd=base, env=env, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return {name: (subprocess.CompletedProcess([name], code, out, err), folders[name])
            for name, (code, out, err) in json.loads(results.read_text(encoding="utf-8")).items()}  # fmt: skip


def test_import_and_the_readme_example_need_no_extra(core: dict) -> None:
    done, _ = core["readme"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines()[-1] == "tried: []"


def test_a_delay_margin_of_coefficients_needs_no_extra(core: dict) -> None:
    done, _ = core["delay margin"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines()[-1] == "True []"


def test_the_library_names_the_extra_it_needs(core: dict) -> None:
    done, folder = core["library"]
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert len(lines) == 8
    extras = ["cluster", "cluster", "ros", "safety", "control", "explore", "certificates", "physics"]
    for line, extra in zip(lines, extras, strict=True):
        assert line.endswith(f"pip install 'delayform[{extra}]'"), line
    assert not list(folder.iterdir()), "a refused call wrote a file"


@pytest.mark.parametrize("command", sorted(CORE_COMMANDS))
def test_core_commands_run_without_extras(command: str, core: dict) -> None:
    done, folder = core[f"core {command}"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert any((folder / "out").iterdir()), "nothing written"


@pytest.mark.parametrize("case", sorted(NEEDS_AN_EXTRA))
def test_a_command_that_needs_an_extra_says_which_in_one_line(case: str, core: dict) -> None:
    done, folder = core[f"extra {case}"]
    extra = NEEDS_AN_EXTRA[case][1]
    assert done.returncode == 2, done.stderr[-3000:]
    assert done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith("delayform: error: ") and line.endswith(f"pip install 'delayform[{extra}]'"), line
    assert not (folder / "out").exists(), "refused after writing"


# -------------------------------------------------------- the table against pyproject.toml
def _extras_in_pyproject() -> dict[str, list[str]]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]


def _distributions(requirements: list[str], extras: dict[str, list[str]]) -> set[str]:
    """The distributions a list of requirements installs directly (its own extras followed)."""
    names: set[str] = set()
    for text in requirements:
        req = Requirement(text)
        if canonicalize_name(req.name) == "delayform":
            for own in req.extras:
                names |= _distributions(extras[own], extras)
            continue
        names.add(canonicalize_name(req.name))
        for extra in req.extras:  # e.g. dask[distributed]: what that extra of dask requires
            for dep in map(Requirement, importlib.metadata.requires(req.name) or []):
                if dep.marker is not None and dep.marker.evaluate({"extra": extra}):
                    names.add(canonicalize_name(dep.name))
    return names


def test_every_module_of_an_extra_comes_with_that_extra() -> None:
    # the modules require_extra checks are installed by the extra its message names (this venv has all)
    extras = _extras_in_pyproject()
    providers = importlib.metadata.packages_distributions()
    for extra, (_, modules) in EXTRAS.items():
        installed = _distributions(extras[extra], extras)
        for module in modules:
            dists = {canonicalize_name(d) for d in providers.get(module, [])}
            assert dists & installed, f"{module} is not installed by delayform[{extra}] ({sorted(installed)})"


def test_all_brings_every_extra_and_test_brings_all() -> None:
    extras = _extras_in_pyproject()
    assert {Requirement(r).name for r in extras["all"]} == {"delayform"}
    assert _distributions(extras["all"], extras) == _distributions(
        [f"delayform[{','.join(EXTRAS)}]"], extras
    )
    assert any("all" in Requirement(r).extras for r in extras["test"] if Requirement(r).name == "delayform")
    core = {canonicalize_name(Requirement(r).name) for r in
            tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]}  # fmt: skip
    assert not core & _distributions(extras["all"], extras), "an extra repeats a core dependency"


def test_require_extra_passes_when_installed_and_its_error_is_an_import_error() -> None:
    for extra in EXTRAS:
        require_extra(extra)  # this venv has every extra: no error
    assert issubclass(MissingExtraError, ImportError) and issubclass(MissingExtraError, DelayformError)
    with pytest.raises(KeyError):
        require_extra("nonexistent")


def test_citation_and_licence_match_the_package() -> None:
    citation = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    assert re.search(r"^cff-version: 1\.2\.0$", citation, flags=re.M)
    assert re.search(r"^version: (.+)$", citation, flags=re.M).group(1) == delayform.__version__
    assert "Formation Control of Non-holonomic Vehicles under Time Delayed Communications" in citation
    licence = (ROOT / "LICENSE").read_text(encoding="utf-8")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert licence.startswith("MIT License") and project["license"] == "MIT" and "LICENSE" in project["license-files"]
