"""The package's data flows one way: topology -> factors -> analysis -> design -> simulation -> outputs.

Every ``import`` of a delayform module, at the top of a file or inside a
function, must point to the same stage or an earlier one, and no two modules
may import each other (directly or through a cycle).
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

import delayform

PACKAGE = Path(delayform.__file__).parent

#: stage of each module or subpackage (first match of the dotted prefix, longest first)
STAGES: dict[str, int] = {
    "errors": 0,
    "_extras": 0,  # a leaf: the check that names the extra to install, imports only errors
    "_validation": 0,
    "resources": 0,  # a leaf: memory and time budget guard
    "_files": 0,  # a leaf: complete-or-absent output files
    "plots": 0,  # a leaf: draws results by their attributes, imports only the file helper _files
    "_display": 0,  # a leaf: Jupyter's _repr_png_ mixin, imports no delayform module
    "packaged": 0,  # a leaf: paths of the shipped example scenarios
    "topology": 1,
    "model": 1,  # the nouns: Team, Delays (built on the topology; every layer above takes them whole)
    "characteristic": 2,
    "quasipolynomial": 2,  # after characteristic (converts its TwoDelayQuasiPolynomial)
    "formation": 2,
    "analysis": 3,
    "analysis.certificates": 3,  # LMIs of linear DDEs: imports only errors (no quasi-polynomials needed)
    "design": 4,
    "loops": 4,  # python-control loops: builds quasi-polynomials, counts their roots (issue 23)
    "simulation": 5,
    "deploy": 5,  # robot profiles, the on-robot controller, MCAP recordings: after simulation, beside it
    "fleet": 6,  # the team as processes over Zenoh: runs the deploy controller, measures against simulation and analysis
    "sweeps": 6,
    "scenario": 7,
    "report": 8,
    # the explorer is served by a CLI command (cli/explore.py), so it comes before the CLI
    "app": 9,
    "cli": 10,
    "__main__": 11,
    "": 11,  # delayform/__init__.py: lazy re-exports of everything
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _stage(name: str) -> int:
    for prefix in sorted(STAGES, key=len, reverse=True):
        if name == prefix or name.startswith(prefix + ".") or prefix == "":
            return STAGES[prefix]
    raise AssertionError(name)


def _imports(path: Path, module: str) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import
                base = module.split(".")[: len(module.split(".")) - node.level + (path.name == "__init__.py")]
                names = [".".join(base + ([node.module] if node.module else []))]
            else:
                names = [node.module or ""]
                names += [f"{node.module}.{a.name}" for a in node.names if node.module == "delayform"]
        else:
            continue
        for name in names:
            if name.startswith("delayform."):
                found.add(name.removeprefix("delayform."))
    return found


def _graph() -> nx.DiGraph:
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    g = nx.DiGraph()
    for module, path in files.items():
        g.add_node(module)
        for target in _imports(path, module):
            # "analysis.roots.dominant.dominant_root" -> the module "analysis.roots.dominant"
            while target and target not in files:
                target = target.rpartition(".")[0]
            if target and target != module:
                g.add_edge(module, target)
    return g


def test_no_module_imports_a_later_stage() -> None:
    g = _graph()
    late = [(a, b) for a, b in g.edges if _stage(b) > _stage(a) and a != ""]
    assert not late, f"imports against the data flow: {late}"


def test_no_import_cycles() -> None:
    g = _graph()
    g.remove_node("")  # the package root re-exports lazily from every module
    cycles = list(nx.simple_cycles(g))
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("name", sorted(delayform.__all__))
def test_public_names_import_from_the_package_root(name: str) -> None:
    assert getattr(delayform, name) is not None
