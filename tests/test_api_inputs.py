"""Issue 24, item 7: every public name refuses wrong arguments with one delayform.errors exception.

The targets are enumerated from ``delayform.__all__`` at collection time, so a
name another engineer exports later is driven too. For each target,
hypothesis picks one parameter and gives it a value wrong for any parameter
of this library (an arbitrary object, a set, bytes, a string where no string
is taken, NaN where a scalar is taken), the other required parameters random
values; the call must raise an :class:`~delayform.errors.InputError` (a
``ValueError``), never a TypeError, AttributeError or numpy's own error.
"""

from __future__ import annotations

import inspect
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import delayform
from delayform.errors import DelayformError, InputError

ROOT = Path(__file__).resolve().parents[1]

#: names of __all__ that are not called: not callables, or callables that take any argument on purpose
SKIP = {
    "errors": "a module",
    "__version__": "a string",
    "IROBOT_CREATE": "a RobotLimits value, not a callable",
    "PAPER_POINTS": "a dict of delay pairs, not a callable",
    "PROFILES": "a read-only mapping of RobotProfile values, not a callable",
    # a NamedTuple built for every message on the robot (100 Hz x neighbours, next to the tick's
    # 50 us budget); FormationController.receive refuses a wrong one with ControllerInputError
    # (test_neighbour_message_of_wrong_types_is_refused_on_receipt below)
    "NeighbourMessage": "a NamedTuple on the controller's hot path, checked by FormationController.receive",
}


def _is_exception(obj: object) -> bool:
    # exception classes take any message, as every exception does
    return isinstance(obj, type) and issubclass(obj, BaseException)


def _targets() -> list[str]:
    return [n for n in delayform.__all__ if n not in SKIP and not _is_exception(getattr(delayform, n))]


def _parameters(obj: Any) -> list[inspect.Parameter]:
    params = list(inspect.signature(obj).parameters.values())
    return [p for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and not p.name.startswith("_")]


def _annotation_text(param: inspect.Parameter) -> str:
    ann = param.annotation
    return ann if isinstance(ann, str) else getattr(ann, "__name__", str(ann))


def _corruptible(param: inspect.Parameter) -> bool:
    # a parameter annotated object/Any takes anything: nothing is wrong for it
    return param.annotation is not inspect.Parameter.empty and _annotation_text(param) not in ("object", "Any")


#: a scalar annotation: NaN and a numeric string are wrong for it
_SCALAR = re.compile(r"^(float|int|complex|bool)( \| None)?$")


def wrong_values(param: inspect.Parameter) -> list[object]:
    """Values wrong for this parameter whatever it means: the test's own notion, not the checker's."""
    text = _annotation_text(param)
    values: list[object] = [object(), frozenset({1, 2}), {"key": object()}]
    if "str" not in text and "Path" not in text and "ArrayLike" not in text:
        values.append("x")
    if "ArrayLike" not in text and "NDArray" not in text and "_Arr" not in text and "Sequence" not in text:
        values.append(b"\xff\x00")
    if _SCALAR.match(text):
        values += [math.nan, "1"]
    return values


#: values for the other parameters: right or wrong, they must never turn the wrong one into a crash
OTHER = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 12), st.floats(-10, 10, allow_nan=False), st.text(max_size=3),
    st.lists(st.floats(-1, 1), max_size=3),
)


def _call(obj: Any, params: list[inspect.Parameter], k: int, bad: object, others: list[object]) -> None:
    args: list[object] = []
    kwargs: dict[str, object] = {}
    for i, p in enumerate(params):
        if i == k:
            value = bad
        elif p.default is not inspect.Parameter.empty:
            continue
        else:
            value = others[i]
        if p.kind == p.KEYWORD_ONLY:
            kwargs[p.name] = value
        elif kwargs or i > len(args):  # a skipped default before it: pass by name
            kwargs[p.name] = value
        else:
            args.append(value)
    result = obj(*args, **kwargs)
    if hasattr(result, "__enter__"):  # a context manager (executor_for) checks on entry at the latest
        with result:
            pass


@pytest.mark.parametrize("name", _targets())
def test_public_name_refuses_wrong_arguments(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # whatever a call might write stays here, and must not happen
    obj = getattr(delayform, name)
    params = [p for p in _parameters(obj)]
    corruptible = [i for i, p in enumerate(params) if _corruptible(p)]
    if not corruptible:
        assert not params or all(not _corruptible(p) for p in params)
        return  # takes no arguments (paper_six, SerialExecutor): nothing can be wrong

    @settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(k=st.sampled_from(corruptible), data=st.data(), others=st.lists(OTHER, min_size=len(params), max_size=len(params)))
    def check(k: int, data: st.DataObject, others: list[object]) -> None:
        bad = data.draw(st.sampled_from(wrong_values(params[k])), label=params[k].name)
        with pytest.raises(InputError) as info:
            _call(obj, params, k, bad, others)
        assert isinstance(info.value, DelayformError) and isinstance(info.value, ValueError)
        assert "\n" not in str(info.value)

    check()
    assert not any(tmp_path.iterdir()), "a refused call left a file behind"


def test_every_public_callable_goes_through_the_checking_layer() -> None:
    unchecked = [n for n in _targets() if not getattr(getattr(delayform, n), "__delayform_checked__", False)]
    assert not unchecked, f"add @validated(...) (delayform._validation) to {unchecked}"


# ================================================================ docs/api.md agrees with the package
def _api_table() -> list[tuple[str, str]]:
    """(module, names cell) of every row of the table in docs/api.md."""
    rows = []
    for line in (ROOT / "docs" / "api.md").read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| `delayform") and len(cells) >= 3:
            rows.append((cells[0].strip("`"), cells[2]))
    return rows


def _top_level_spans(cell: str) -> list[tuple[str, bool]]:
    """The backticked names of a cell outside any parentheses, each with whether it is in bold."""
    out: list[tuple[str, bool]] = []
    depth = 0
    for match in re.finditer(r"\*\*`([^`]+)`\*\*|`([^`]+)`|[()]", cell):
        token = match.group(0)
        if token == "(":
            depth += 1
        elif token == ")":
            depth = max(0, depth - 1)
        elif depth == 0:
            text = match.group(1) or match.group(2)
            name = re.match(r"([A-Za-z_]\w*)(\(|$)", text)  # `name` or `name(args)`, not `ax=None`
            if name:
                out.append((name.group(1), match.group(1) is not None))
    return out


def test_api_md_names_exist_and_bold_ones_are_importable_from_delayform() -> None:
    import importlib

    bold: set[str] = set()
    for module, cell in _api_table():
        mod = importlib.import_module(module)
        for name, is_bold in _top_level_spans(cell):
            assert hasattr(mod, name) or hasattr(delayform, name), f"docs/api.md: {module} has no {name}"
            if is_bold:
                bold.add(name)
                assert name in delayform.__all__, f"docs/api.md shows {name} in bold, but delayform does not export it"
    exported = set(delayform.__all__) - {"errors", "__version__"}
    assert exported - bold == set(), f"exported from delayform but not in bold in docs/api.md: {sorted(exported - bold)}"


def test_api_md_states_the_rule_it_follows() -> None:
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    assert "in **bold** are importable from `delayform`" in text


def test_api_md_has_the_package_groups_in_their_order() -> None:
    """docs/api.md, the reference and ``delayform._GROUPS`` group the public names the same way."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    headings = [h for h in re.findall(r"^## (.+)$", text, flags=re.M) if h != "Conventions"]
    assert headings == list(delayform._GROUPS)


def test_every_public_name_is_in_one_group_and_every_exception_is_exported() -> None:
    sizes = sum(len(names) for names in delayform._GROUPS.values())
    assert sizes == len(delayform._EXPORTS), "a name is in two groups of delayform._GROUPS"
    import delayform.errors as errors

    raised = {n for n, obj in vars(errors).items() if isinstance(obj, type) and issubclass(obj, BaseException)
              and obj.__module__ == errors.__name__}  # fmt: skip
    assert raised <= set(delayform._GROUPS["Errors"]), sorted(raised - set(delayform._GROUPS["Errors"]))


# ================================================================ the issue's examples (item 7)
@pytest.mark.parametrize(
    "call",
    [
        lambda: delayform.simulate(delayform.paper_six(), 1, 0.5, 0.3, 0.2, "hexagon", duration=1, dt=0.01, seed=1.5),
        lambda: delayform.simulate(delayform.paper_six(), 1, 0.5, 0.3, 0.2, "hexagon", duration=1, dt=0.01, seed="a"),
        lambda: delayform.simulate(delayform.paper_six(), 1, 0.5, 0.3, 0.2, "hexagon", duration=1, dt=0.01, seed=-1),
        lambda: delayform.monte_carlo(delayform.paper_six(), 1, 0.5, 0.3, 0.2, "hexagon", runs=2, duration=1,
                                      dt=0.01, executor="dask"),  # fmt: skip
        lambda: delayform.Explorer(None, out_dir="x"),
        lambda: delayform.load_scenario(None),
        lambda: delayform.load_scenario(3),
        lambda: delayform.load_scenario(b"[topology]"),
        lambda: delayform.lambda_region(1.0, 0.5, 0.3, 0.2).is_stable("0.5"),
        lambda: delayform.lambda_region(1.0, 0.5, 0.3, 0.2).unstable_count(None),
        lambda: delayform.ExplorerLimits(max_delay=-1),
        lambda: delayform.ExplorerLimits(max_grid=0),
        lambda: delayform.ExplorerLimits(max_gain=math.inf),
    ],
)
def test_issue_examples_raise_one_of_ours(call: Any) -> None:
    with pytest.raises(InputError):
        call()


def test_executor_for_with_a_malformed_address_is_one_of_ours() -> None:
    # harden-runtime parses addresses; here only that no raw ValueError of the URL parser escapes
    with pytest.raises(InputError):
        with delayform.executor_for(scheduler=3):  # type: ignore[arg-type]
            pass


def test_valid_calls_still_work_through_the_layer() -> None:
    # numpy scalars, ints for floats, lists for tuples: what users pass must still pass
    region = delayform.lambda_region(np.float64(1.0), 1, np.float32(0.3), 0.2)
    assert bool(region.is_stable(0.5)) and region.is_stable([0.5, 1.0]).shape == (2,)
    assert delayform.ring(np.int64(4)).n == 4
    assert delayform.schedule_delays(delayform.paper_six(), 1.0, 0.5, tau_min=[0.3, 0.2], tau_max=[0.6, 0.4]).tau1 >= 0.3


def test_every_import_from_delayform_in_the_docs_works() -> None:
    """``from delayform import X`` in README.md, docs/ and examples/ names only what delayform exports."""
    files = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "examples").rglob("*.py")]
    names = set()
    for path in files:
        for match in re.finditer(r"from delayform import ([A-Za-z_][\w, ]*)", path.read_text(encoding="utf-8")):
            names |= {n.strip() for n in match.group(1).split(",") if n.strip()}
    assert names, "no imports found: the pattern is stale"
    assert not [n for n in names if not hasattr(delayform, n)], sorted(n for n in names if not hasattr(delayform, n))


# ================================================================ neighbours: the methods of results
@pytest.fixture(scope="module")
def results() -> dict[str, Any]:
    t = delayform.paper_six()
    return {
        "map": delayform.stability_map(t, 1.0, 0.5, 2.0, 2.0),
        "safe": delayform.safe_delays(1.0, 0.5, 2.0, 2.0),
        "traj": delayform.simulate(t, 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.01),
        "region": delayform.lambda_region(1.0, 0.5, 0.3, 0.2),
    }


@pytest.mark.parametrize(
    "call",
    [
        lambda r: delayform.Topology.from_edges([(0, 1), (1, 0)], "x"),
        lambda r: r["map"].stable_fraction("a"),  # one argument too many
        lambda r: r["safe"].grid("x"),
        lambda r: r["traj"].to_csv(3),
        lambda r: r["traj"].to_npz(None),
        lambda r: r["traj"].save_gif(3),
        lambda r: r["region"].boundary("x"),
        lambda r: r["region"].is_stable(object()),
    ],
)
def test_methods_of_results_refuse_wrong_arguments(results: dict[str, Any], call: Any, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError):
        call(results)
    assert not any(tmp_path.iterdir())


# ================================================================ the controller's hot path
@pytest.mark.parametrize(
    "call",
    [
        lambda c: c.receive(delayform.NeighbourMessage(object(), 0.0, 0.0, 0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        lambda c: c.receive(delayform.NeighbourMessage(2, "0", 0.0, 0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        lambda c: c.receive(delayform.NeighbourMessage({}, 0.0, 0.0, 0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        lambda c: c.receive(object()),  # type: ignore[arg-type]
        lambda c: c.tick(0.0, "x", 0.0, 0.0, 0.0),  # type: ignore[arg-type]
        lambda c: c.speed_command(None, "0.1"),  # type: ignore[arg-type]
    ],
)
def test_neighbour_message_of_wrong_types_is_refused_on_receipt(call: Any) -> None:
    # NeighbourMessage and the tick are not wrapped by the checking layer (hot path): they refuse here
    ctrl = delayform.FormationController.from_design(delayform.paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=1)
    with pytest.raises(InputError):
        call(ctrl)


# ================================================================ the layer itself
def test_a_missing_argument_is_one_of_ours() -> None:
    # Python's own TypeError ("missing 1 required positional argument") names no error of ours
    with pytest.raises(InputError, match="tau2 is required"):
        delayform.lambda_region(1.0, 0.5, 0.3)  # type: ignore[call-arg]
    with pytest.raises(InputError, match="rate is required"):
        delayform.mean_square_stability(delayform.paper_six(), 1.0, 0.5, 0.3, 0.2, loss=0.1)  # type: ignore[call-arg]


def test_a_not_computed_field_takes_nan_but_no_other_non_number() -> None:
    # JitterMargin.peak_frequency is NaN at an unstable point (FloatOrNaN), never a string
    assert math.isnan(delayform.JitterMargin(0.0, math.inf, math.nan, False, 0j).peak_frequency)
    with pytest.raises(InputError, match="peak_frequency"):
        delayform.JitterMargin(0.0, math.inf, "x", False, 0j)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="delta"):
        delayform.JitterMargin(math.nan, math.inf, 1.0, False, 0j)
