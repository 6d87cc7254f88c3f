"""The problem's nouns passed whole: the entry points' shape, checks made once, the loose calls of the docs.

Every call of ``simulate``, ``monte_carlo`` and ``dominant_root`` in the Python
blocks of README.md and docs/*.md and in the notebooks is listed in
:data:`DOC_CALLS` beside the same call written with the nouns; the listing is
checked against the files (a call added to the docs must be listed) and each
call is run both ways and must give the same arrays.
"""

from __future__ import annotations

import inspect
import json
import re
import traceback
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import delayform
from delayform import paper_six, ring
from delayform.analysis.roots.dominant import dominant_root
from delayform.errors import DelayError, GainError, InputError, NetworkError, SimulationInputError
from delayform.model import (
    IROBOT_CREATE,
    MODELS,
    BernoulliLoss,
    Delays,
    GilbertElliott,
    Jitter,
    Network,
    Robot,
    Start,
    Team,
    robot_profile,
)
from delayform.simulation import RunOptions, monte_carlo, simulate
from delayform.simulation.runs.compat import MONTE_CARLO_KEYWORDS, SIMULATE_KEYWORDS
from delayform.simulation.runs.integrators import INTEGRATORS, DoubleIntegratorModel

ROOT = Path(__file__).resolve().parents[1]
ENTRY_POINTS = ("simulate", "monte_carlo", "dominant_root")

#: each call in the docs (whitespace collapsed) -> the same call with the nouns
DOC_CALLS = {
    'simulate(team, 1.0, 0.5, 0.3, 0.2, "hexagon", duration=20.0, dt=0.05, limits=IROBOT_CREATE)':
        'simulate(Team(team, 1.0, 0.5), Delays(0.3, 0.2), "hexagon", robot=Robot(limits=IROBOT_CREATE), duration=20.0, dt=0.05)',
    'simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", limits=robot_profile("create3").limits, duration=60.0, dt=0.01)':
        'simulate(Team(paper_six(), 1.0, 0.5), Delays(0.3, 0.2), "hexagon", robot=Robot(profile="create3"), duration=60.0, dt=0.01)',
    "dominant_root(team, 1.0, 0.5, 0.3, 0.2)": "dominant_root(Team(team, 1.0, 0.5), Delays(0.3, 0.2))",
    "dominant_root(team, P, D, t1, t2)": "dominant_root(Team(team, P, D), Delays(t1, t2))",
    'simulate(team, P, D, 0.3, 0.2, "hexagon", duration=40.0, dt=0.05, seed=0)':
        'simulate(Team(team, P, D), Delays(0.3, 0.2), "hexagon", start=Start(seed=0), duration=40.0, dt=0.05)',
    'simulate(team, P, D, 1.0, 2.0, "hexagon", model="double_integrator", duration=40.0, dt=0.05, seed=0)':
        'simulate(Team(team, P, D), Delays(1.0, 2.0), "hexagon", robot=Robot("double_integrator"), duration=40.0, dt=0.05)',
    "dominant_root(team, P, D, tau1, tau2)": "dominant_root(Team(team, P, D), Delays(tau1, tau2))",
    'monte_carlo(team, P, D, tau1, tau2, "hexagon", network=network, runs=6, seed=0, duration=40.0, dt=0.05)':
        'monte_carlo(Team(team, P, D), Delays(tau1, tau2), "hexagon", robot=Robot("double_integrator"), network=network, runs=6, duration=40.0, dt=0.05)',
    "dominant_root(team, scenario.P, scenario.D, scenario.tau1, scenario.tau2)":
        "dominant_root(Team(team, scenario.P, scenario.D), Delays(scenario.tau1, scenario.tau2))",
    'simulate(team, design.P, design.D, scenario.tau1, scenario.tau2, "polygon", duration=40.0, dt=0.05, seed=1)':
        'simulate(Team(team, design.P, design.D), Delays(scenario.tau1, scenario.tau2), "polygon", start=Start(seed=1), duration=40.0, dt=0.05)',
}  # fmt: skip

#: the names the calls above use (the docs define them in the lines before)
NAMESPACE = {
    "simulate": simulate, "monte_carlo": monte_carlo, "dominant_root": dominant_root, "paper_six": paper_six,
    "IROBOT_CREATE": IROBOT_CREATE, "robot_profile": robot_profile, "Team": Team, "Delays": Delays, "Robot": Robot,
    "Start": Start, "team": paper_six(), "P": 1.0, "D": 0.5, "t1": 0.3, "t2": 0.2, "tau1": 0.3, "tau2": 0.2,
    "network": Network(loss=BernoulliLoss(0.2), jitter=Jitter(0.05, 0.02), seed=0),
    "scenario": SimpleNamespace(P=1.0, D=0.5, tau1=0.3, tau2=0.2), "design": SimpleNamespace(P=1.2, D=0.9),
}  # fmt: skip


def _calls_in(code: str) -> list[str]:
    """Every call of an entry point in ``code``, parentheses balanced, whitespace collapsed."""
    found = []
    for m in re.finditer(r"(?<![\w.])(?:(?:df|delayform)\.)?(%s)\(" % "|".join(ENTRY_POINTS), code):
        depth, i = 0, m.end() - 1
        while True:
            depth += {"(": 1, ")": -1}.get(code[i], 0)
            if depth == 0:
                break
            i += 1
        found.append(re.sub(r"\s+", " ", code[m.start(1) : i + 1]).replace("( ", "(").replace(" )", ")"))
    return found


def _doc_code() -> dict[str, str]:
    """Python blocks of README.md and docs/*.md, and the notebooks' code cells, by file."""
    out = {}
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        blocks = re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)
        out[path.name] = "\n".join(blocks)
    for path in sorted((ROOT / "docs" / "tutorials").glob("*.ipynb")):
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        out[path.name] = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    return out


def test_every_call_in_the_docs_is_listed() -> None:
    found = {call for code in _doc_code().values() for call in _calls_in(code)}
    assert found == set(DOC_CALLS), f"new: {sorted(found - set(DOC_CALLS))}; gone: {sorted(set(DOC_CALLS) - found)}"


def _same(a: object, b: object) -> None:
    """Two results of the same computation: every array equal, bit for bit."""
    assert type(a) is type(b)
    names = [n for n in ("root", "times", "positions", "velocities", "headings", "inputs", "errors",
                         "settling_times", "peak_commands") if hasattr(a, n)]  # fmt: skip
    assert names
    for name in names:
        np.testing.assert_array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name)), err_msg=name)


def _marked(call: str) -> object:
    # a minute of robots with limits at dt = 0.01, twice: past the ~10 s of an ordinary test
    return pytest.param(call, marks=pytest.mark.slow) if "dt=0.01" in call else call


@pytest.mark.parametrize("call", [_marked(c) for c in sorted(DOC_CALLS)])
def test_each_loose_call_in_the_docs_runs_and_equals_the_noun_form(call: str) -> None:
    _same(eval(call, dict(NAMESPACE)), eval(DOC_CALLS[call], dict(NAMESPACE)))


def _top_keywords(args: str) -> list[str]:
    """The keywords of a call's own arguments, not of the calls inside them."""
    depth, flat = 0, []
    for ch in args:
        depth += {"(": 1, ")": -1}.get(ch, 0)
        flat.append(ch if depth == 0 else " ")
    return re.findall(r"(\w+)=", "".join(flat))


def test_every_keyword_the_docs_show_is_taken() -> None:
    """Prose shows calls as ``simulate(..., network=..., limits=...)``: each keyword is an old one or a new one."""
    text = "\n".join(p.read_text(encoding="utf-8") for p in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
    for name, table in (("simulate", SIMULATE_KEYWORDS), ("monte_carlo", MONTE_CARLO_KEYWORDS)):
        params = inspect.signature(getattr(delayform, name)).parameters
        shown = {kw for m in re.finditer(rf"`{name}\(\.\.\.,([^`]*)\)`", text) for kw in _top_keywords(m.group(1))}
        assert shown, name
        unknown = shown - set(table) - set(params)
        assert not unknown, f"{name}: the docs show keywords it does not take: {unknown}"


# ----------------------------------------------------------------- the entry points' shape
def test_simulate_and_monte_carlo_take_the_same_nouns_with_the_same_defaults() -> None:
    sim, mc = (inspect.signature(f).parameters for f in (simulate, monte_carlo))
    assert len(sim) <= 10 and len(mc) <= 10
    assert list(sim)[:3] == list(mc)[:3] == ["team", "delays", "formation"]
    shared = set(sim) & set(mc)
    assert {"robot", "network", "start", "duration", "dt", "options"} <= shared
    assert all(sim[n].default == mc[n].default for n in shared)
    assert not any(p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL) for p in [*sim.values(), *mc.values()])


def test_the_integrator_table_has_one_entry_per_agent_model() -> None:
    assert sorted(INTEGRATORS) == sorted(MODELS)
    for name, entry in INTEGRATORS.items():
        assert entry.name == name
        assert all(callable(getattr(entry, m)) for m in ("check", "generic", "integrate", "motion"))


def test_a_new_agent_model_is_one_entry_in_the_table(monkeypatch: pytest.MonkeyPatch) -> None:
    """A model added by name to MODELS and to the table is run by simulate with nothing else changed."""
    import delayform.model.robot as robot_module
    import delayform.simulation.runs.runner as runner

    class Toy(DoubleIntegratorModel):
        name = "toy"

    monkeypatch.setattr(robot_module, "MODELS", (*MODELS, "toy"))
    monkeypatch.setattr(runner, "INTEGRATORS", {**INTEGRATORS, "toy": Toy()})
    team, delays = Team(ring(3), 1.0, 0.5), Delays(0.3, 0.2)
    toy = simulate(team, delays, "polygon", robot=Robot("toy"), duration=5.0, dt=0.05)
    point = simulate(team, delays, "polygon", robot=Robot("double_integrator"), duration=5.0, dt=0.05)
    assert toy.model == "toy"
    np.testing.assert_array_equal(toy.positions, point.positions)


# ----------------------------------------------------------------- checked once, where made
def _raised_in(call: object) -> tuple[InputError, list[str]]:
    with pytest.raises(InputError) as info:
        call()  # type: ignore[operator]
    return info.value, [f.filename for f in traceback.extract_tb(info.tb)]


@pytest.mark.parametrize(
    "call, error, where",
    [
        (lambda: simulate(paper_six(), -1.0, 0.5, 0.3, 0.2, "hexagon", duration=1, dt=0.1), GainError, "model/team.py"),
        (lambda: monte_carlo(paper_six(), 1.0, 0.0, 0.3, 0.2, "hexagon", runs=2, duration=1, dt=0.1), GainError, "model/team.py"),
        (lambda: simulate(paper_six(), 1.0, 0.5, -0.3, 0.2, "hexagon", duration=1, dt=0.1), DelayError, "model/delays.py"),
        (lambda: simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", model="tank", duration=1, dt=0.1), SimulationInputError, "model/robot.py"),
        (lambda: simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", initial_speed=np.nan, duration=1, dt=0.1), SimulationInputError, "model/start.py"),
        (lambda: dominant_root(paper_six(), 1.0, -2.0, 0.3, 0.2), GainError, "model/team.py"),
    ],
)  # fmt: skip
def test_a_bad_noun_fails_where_it_is_made_not_deep_inside(call: object, error: type, where: str) -> None:
    exc, files = _raised_in(call)
    assert isinstance(exc, error)
    assert files[-1].endswith(where) or any(f.endswith(where) for f in files[-3:]), files
    deep = [f for f in files if re.search(r"simulation/(runner|models|integrator|reception)\.py$|analysis/roots/", f)]
    assert not deep, f"raised after the computation started: {deep}"


def test_a_noun_built_once_is_not_checked_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """The gains are checked in Team() and nowhere on the way through simulate."""
    import delayform._validation as validation
    import delayform.model.team as team_module

    calls = []
    real = validation.check_gains
    monkeypatch.setattr(team_module, "check_gains", lambda P, D: calls.append(1) or real(P, D))
    team = Team(ring(3), 1.0, 0.5)
    assert calls == [1]
    simulate(team, Delays(0.3, 0.2), "polygon", duration=1.0, dt=0.05)
    assert calls == [1]


def test_network_parts_are_checked_when_made() -> None:
    with pytest.raises(NetworkError, match="loss.probability"):
        BernoulliLoss(1.5)
    with pytest.raises(NetworkError, match="loss.p_bad_to_good"):
        GilbertElliott(0.1, -0.2)


# ----------------------------------------------------------------- the compatibility path
def test_an_unknown_keyword_is_refused_by_name() -> None:
    with pytest.raises(SimulationInputError, match="'colour'"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.1, colour="red")
    with pytest.raises(SimulationInputError, match="'save_every'"):  # never a keyword of monte_carlo
        monte_carlo(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", runs=2, duration=1.0, dt=0.1, save_every=2)


def test_an_old_keyword_beside_its_noun_is_refused() -> None:
    team, delays = Team(paper_six(), 1.0, 0.5), Delays(0.3, 0.2)
    with pytest.raises(SimulationInputError, match="seed in start"):
        simulate(team, delays, "hexagon", start=Start(), seed=3, duration=1.0, dt=0.1)
    with pytest.raises(SimulationInputError, match="either in robot or as keywords"):
        simulate(team, delays, "hexagon", robot=Robot(), limits=IROBOT_CREATE, duration=1.0, dt=0.1)


def test_old_keywords_beside_the_nouns_go_to_their_noun() -> None:
    team, delays = Team(ring(3), 1.0, 0.5), Delays(0.3, 0.2)
    loose = simulate(team, delays, "polygon", seed=4, save_every=2, duration=2.0, dt=0.05)
    nouns = simulate(team, delays, "polygon", start=Start(seed=4), options=RunOptions(save_every=2), duration=2.0, dt=0.05)
    np.testing.assert_array_equal(loose.positions, nouns.positions)


def test_monte_carlo_keeps_its_old_default_model_and_seed() -> None:
    """The loose monte_carlo integrated double integrators unless told; its seed is the start's."""
    loose = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", runs=2, seed=5, duration=2.0, dt=0.05)
    assert loose.setup.model == "double_integrator" and loose.seed == 5
    nouns = monte_carlo(Team(ring(3), 1.0, 0.5), Delays(0.3, 0.2), "polygon", robot=Robot("double_integrator"),
                        start=Start(seed=5), runs=2, duration=2.0, dt=0.05)  # fmt: skip
    np.testing.assert_array_equal(loose.errors, nouns.errors)
    assert monte_carlo(Team(ring(3), 1.0, 0.5), Delays(0.3, 0.2), "polygon", runs=1, duration=1.0,
                       dt=0.05, start=Start(speed=0.1)).setup.model == "unicycle"  # fmt: skip


def test_dominant_root_says_per_link_by_the_delays_kind() -> None:
    team = Team(paper_six(), 1.0, 0.5)
    uniform = dominant_root(team, Delays(0.3, 0.2))
    per_link = dominant_root(team, Delays(np.full((6, 6), 0.3), np.full((6, 6), 0.2)))
    assert type(uniform).__name__ == "DominantRoot" and type(per_link).__name__ == "LinkDominantRoot"
    assert abs(uniform.root - per_link.root) < 1e-8  # two methods, one root
    C = paper_six().C_sparse.toarray()
    t1 = np.where(C > 0, 0.3, np.nan)  # the loose form ignores entries off the links, as before
    assert abs(dominant_root(paper_six(), 1.0, 0.5, t1, 0.2).root - per_link.root) < 1e-12
    with pytest.raises(DelayError, match="6 agents"):
        dominant_root(team, Delays(np.full((5, 5), 0.3), np.full((5, 5), 0.2)))


def test_per_link_delays_in_simulate_point_to_the_network() -> None:
    with pytest.raises(DelayError, match="LinkDelays"):
        simulate(Team(ring(3), 1.0, 0.5), Delays(np.full((3, 3), 0.3), np.full((3, 3), 0.2)), "polygon",
                 duration=1.0, dt=0.05)  # fmt: skip


def test_old_import_paths_give_the_same_objects() -> None:
    import delayform.deploy.profiles as profiles
    import delayform.model as model
    import delayform.model.network as network
    import delayform.simulation.models.robots as robots
    import delayform.simulation.bodies.safety as safety

    assert network.Network is model.Network and network.GilbertElliott is model.GilbertElliott
    assert robots.Robot is model.Robot and robots.RobotLimits is model.RobotLimits
    assert profiles.RobotProfile is model.RobotProfile and safety.BarrierFilter is model.BarrierFilter
    assert delayform.Network is model.Network and delayform.Robot is model.Robot


def test_a_robot_takes_its_profile_limits() -> None:
    robot = Robot(profile="create3")
    assert robot.limits == robot_profile("create3").limits and robot.profile.name == "create3"
    with pytest.raises(SimulationInputError, match="not both"):
        Robot(profile="create3", limits=IROBOT_CREATE)
