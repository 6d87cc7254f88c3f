"""The package's data flows one way: topology -> factors -> analysis -> design -> simulation -> outputs.

Every ``import`` of a delayform module, at the top of a file or inside a
function, must point to the same stage or an earlier one; no two modules may
import each other (directly or through a cycle), nor may two packages (each
subpackage of ``analysis/`` counts as a package of its own); and no package
takes another's private (underscored) names.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

import delayform

PACKAGE = Path(delayform.__file__).parent

#: stage of each module or subpackage (first match of the dotted prefix, longest first)
STAGES: dict[str, float] = {
    "errors": 0,
    "_extras": 0,  # a leaf: the check that names the extra to install, imports only errors
    "_validation": 0,
    "resources": 0,  # a leaf: memory and time budget guard
    "_files": 0,  # a leaf: complete-or-absent output files
    "_lazy": 0,  # a leaf: a package's names imported on first use, imports no delayform module
    "plots": 0,  # a leaf: draws results by their attributes, imports only the file helper _files
    "_display": 0,  # a leaf: Jupyter's _repr_png_ mixin, imports no delayform module
    "packaged": 0,  # a leaf: paths of the shipped example scenarios
    "topology": 1,
    "model": 1,  # the nouns: Team, Delays (built on the topology; every layer above takes them whole)
    "characteristic": 2,
    "quasipolynomial": 2,  # after characteristic (converts its TwoDelayQuasiPolynomial)
    "formation": 2,
    # analysis: each subpackage is a stage of its own
    "analysis.roots": 3,  # the bottom: roots of quasi-polynomials and of the team's factors, certified counts
    # neutral counts roots with roots' argument principle (so above it) and ctcr uses its difference
    # operator for general quasi-polynomials (so below ctcr)
    "analysis.neutral": 4,
    # the team's certificates check the nominal roots with roots (so above it); network's jitter
    # margin builds on them (so below network); they need neither ctcr nor neutral
    "analysis.certificates": 4,
    "analysis.ctcr": 5,  # the CTCR map: counts at degenerate crossings with roots, neutral's difference operator
    "loops": 5,  # python-control loops: builds quasi-polynomials, counts their roots with roots
    "analysis.network": 6,  # per-link delays, boxes, jitter, loss: on the CTCR map, the certificates and roots
    "analysis.plane": 6,  # the eigenvalue plane: a CTCR map for each eigenvalue
    "analysis": 7,  # the package's __init__: lends neutral's and network's solvers to roots (roots.delegated)
    "design": 8,
    # simulation: each subpackage is a stage of its own
    "simulation.models": 8.1,  # agent models and the commands robots execute: on the nouns only
    "simulation.delayed": 8.2,  # RK4 on a bounded history, the actuation buffer, reception over a network
    # the safety filter's step for small teams (delayed.filtered) steps the filter's active set, so
    # bodies sits below delayed's top; bodies needs neither models nor delayed
    "simulation.bodies": 8.15,
    # the MuJoCo engine steps the agent models and hears over the network (above models, delayed) and is
    # an entry of the integrator table (below runs); the comparison with a kinematic run calls simulate
    "simulation.physics.mjcf": 8.3,
    "simulation.physics.engine": 8.3,
    "simulation.physics.identify": 8.3,
    "simulation.physics": 8.5,  # the comparison with a kinematic run and the package's __init__
    "simulation.runs": 8.4,  # one run: simulate, the integrator table, options, loose calls, Trajectory
    "simulation.experiments": 8.6,  # many runs: Monte Carlo and the sweeps (on Dask)
    "simulation": 8.7,  # the package's __init__: re-exports of the subpackages' public names
    "deploy": 9,  # robot profiles, the on-robot controller, MCAP recordings: after simulation, beside it
    "fleet": 10,  # the team as processes over Zenoh: runs the deploy controller, measures against simulation and analysis
    "scenario": 11,
    "report": 12,
    # the explorer is served by a CLI command (cli/explore.py), so it comes before the CLI
    "app": 13,
    "cli": 14,
    "__main__": 15,
    "": 15,  # delayform/__init__.py: lazy re-exports of everything
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _stage(name: str) -> float:
    for prefix in sorted(STAGES, key=len, reverse=True):
        if name == prefix or name.startswith(prefix + ".") or prefix == "":
            return STAGES[prefix]
    raise AssertionError(name)


def _imports(path: Path, module: str) -> set[tuple[str, str]]:
    """``(target, name)`` of every delayform import: the module (or package) and the name taken from it.

    ``from a.b import c`` gives ``("a.b.c", "")`` when ``c`` is a module of its own
    (importing a submodule is not taking a name of the package), else ``("a.b", "c")``;
    ``import a.b`` gives ``("a.b", "")``.
    """
    tree = ast.parse(path.read_text(), filename=str(path))
    found: set[tuple[str, str]] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            pairs = [(a.name, "") for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import
                base = module.split(".")[: len(module.split(".")) - node.level + (path.name == "__init__.py")]
                source = ".".join(base + ([node.module] if node.module else []))
                source = "delayform." + source if source else "delayform"
            else:
                source = node.module or ""
            pairs = [(f"{source}.{a.name}", "") if _is_module(f"{source}.{a.name}") else (source, a.name)
                     for a in node.names]  # fmt: skip
        else:
            continue
        for target, name in pairs:
            if target == "delayform" or target.startswith("delayform."):
                found.add((target.removeprefix("delayform").removeprefix("."), name))
    return found


def _is_module(dotted: str) -> bool:
    parts = dotted.split(".")
    if parts[0] != "delayform":
        return False
    where = PACKAGE.joinpath(*parts[1:])
    return where.with_suffix(".py").is_file() or (where / "__init__.py").is_file()


def _files() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _graph() -> nx.DiGraph:
    files = _files()
    g = nx.DiGraph()
    for module, path in files.items():
        g.add_node(module)
        for target, _ in _imports(path, module):
            # "analysis.roots.dominant.dominant_root" -> the module "analysis.roots.dominant"
            while target and target not in files:
                target = target.rpartition(".")[0]
            if target != module:
                g.add_edge(module, target)
    return g


#: packages whose subpackages are stages (and units) of their own
SPLIT = ("analysis", "simulation")


def _unit(module: str) -> str:
    """The package a module belongs to: a subpackage of analysis or simulation, else its top-level package or module.

    Each module of ``simulation.physics`` is a unit of its own: the comparison with a kinematic run
    calls ``simulate``, which steps the engine through the integrator table, so the physics package
    stands partly below the runs (the engine) and partly above them (the comparison).
    """
    parts = module.split(".")
    if module.startswith("simulation.physics."):
        return module
    return ".".join(parts[:2]) if parts[0] in SPLIT and len(parts) > 1 else parts[0]


def test_no_module_imports_a_later_stage() -> None:
    g = _graph()
    late = [(a, b) for a, b in g.edges if _stage(b) > _stage(a) and a != ""]
    assert not late, f"imports against the data flow: {late}"


def test_no_import_cycles() -> None:
    g = _graph()
    g.remove_node("")  # the package root re-exports lazily from every module
    cycles = list(nx.simple_cycles(g))
    assert not cycles, f"import cycles: {cycles}"


def test_no_cycles_between_packages() -> None:
    """Modules without a cycle can still make one between their packages (roots -> network -> roots)."""
    units = nx.DiGraph()
    for a, b in _graph().edges:
        if a != "" and _unit(a) != _unit(b):
            units.add_edge(_unit(a), _unit(b))
    cycles = list(nx.simple_cycles(units))
    assert not cycles, f"import cycles between packages: {cycles}"


def _private(module: str, unit: str, name: str) -> bool:
    """An underscored name, or an underscored module inside its package (``loops._read``, not ``_validation``)."""
    inside = module.split(".")[len(unit.split(".")):]
    return any(p.startswith("_") and not p.startswith("__") for p in inside + ([name] if name else []))


def test_no_private_name_is_imported_across_packages() -> None:
    """What two packages share is a public, documented name of the module that defines it."""
    files = _files()
    found = []
    for module, path in files.items():
        for target, name in _imports(path, module):
            while target and target not in files:
                target = target.rpartition(".")[0]
            if module != "" and _unit(target) != _unit(module) and _private(target, _unit(target), name):
                found.append(f"{module} imports {name or '(module)'} from {target}")
    assert not found, "private names imported across packages:\n" + "\n".join(sorted(found))


@pytest.mark.parametrize("name", sorted(delayform.__all__))
def test_public_names_import_from_the_package_root(name: str) -> None:
    assert getattr(delayform, name) is not None


@pytest.mark.parametrize("package", SPLIT)
def test_each_subpackage_of_a_split_package_has_its_stage(package: str) -> None:
    """A new subpackage of analysis/ or simulation/ says where it stands, rather than taking its parent's stage."""
    subpackages = {p.parent.name for p in (PACKAGE / package).glob("*/__init__.py")}
    assert subpackages, package
    missing = sorted(s for s in subpackages if f"{package}.{s}" not in STAGES and not any(
        key.startswith(f"{package}.{s}.") for key in STAGES))
    assert not missing, f"subpackages of {package} without a stage: {missing}"


def test_experiments_stand_on_runs_and_runs_on_models_delayed_and_bodies() -> None:
    runs = _stage("simulation.runs.runner")
    assert _stage("simulation.experiments.montecarlo") > runs
    for below in ("simulation.models.robots", "simulation.delayed.integrator", "simulation.bodies.safety"):
        assert _stage(below) < runs, below
