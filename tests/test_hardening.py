"""Hardening (issue 9): malformed input of every kind, one meaning of stable, paths, resource guards.

The command line runs in-process here (``delayform.cli.main``) so that the
table of malformed inputs stays fast; ``tests/test_cli.py`` runs the same
entry point in a subprocess. Every CLI case asserts: the exit code, exactly
one line on stderr for an error, and no warning text.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.roots.dominant import dominant_root, dominant_root_map, roots_in
from delayform.characteristic import factors, format_number
from delayform.errors import (
    DelayError,
    GainError,
    NoSpanningTreeError,
    ResourceLimitError,
    TopologyError,
)
from delayform.topology import Topology, paper_six, random_digraph
from test_cli import assert_no_warning_text

P, D = 1.0, 0.5

BASE = """\
[topology]
name = "paper_six"
[gains]
P = 1.0
D = 0.5
[delays]
tau1 = 0.3
tau2 = 0.2
[formation]
shape = "hexagon"
"""


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """Run ``delayform ARGS`` in-process: (exit code, stdout, stderr), stderr free of warnings."""
    from delayform.cli import main

    with pytest.raises(SystemExit) as info:
        main(list(args))
    out, err = capsys.readouterr()
    assert_no_warning_text(err)
    assert "Traceback" not in err
    return int(info.value.code or 0), out, err


def one_line_error(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    code, out, err = cli(capsys, *args)
    lines = err.strip().splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1 and lines[0].startswith("delayform: error: "), err
    return lines[0]


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


# ================================================================ malformed inputs
#: (id, scenario text or None, extra arguments, text the one line must contain). Grown from
#: ~70 inputs tried by hand across every command and scenario key; each broke once.
SCENARIO_CASES: list[tuple[str, str | None, tuple[str, ...], str]] = [
    ("gain NaN", BASE.replace("P = 1.0", "P = nan"), ("chart",), "gains.P"),
    ("gain huge", BASE.replace("P = 1.0", "P = 1e300"), ("factors",), "gains.P"),
    ("gain tiny", BASE.replace("D = 0.5", "D = 1e-300"), ("roots",), "gains.D"),
    ("gain as string", BASE.replace("P = 1.0", 'P = "1"'), ("chart",), "gains.P"),
    ("delay inf", BASE.replace("tau1 = 0.3", "tau1 = inf"), ("chart",), "delays.tau1"),
    ("delay negative", BASE.replace("tau2 = 0.2", "tau2 = -0.1"), ("roots",), "delays.tau2"),
    ("delay huge", BASE.replace("tau1 = 0.3", "tau1 = 1e300"), ("roots",), "1e+300 s are too long"),
    ("empty topology name", BASE.replace('name = "paper_six"', 'name = ""'), ("chart",), "topology.name"),
    ("random_digraph p bool", BASE.replace('name = "paper_six"', 'name = "random_digraph"\nn = 5\np = true')
     .replace('"hexagon"', '"line"'), ("chart",), "topology.p"),
    ("edge index 1.5", BASE.replace('name = "paper_six"', "edges = [[0, 1.5], [1, 0]]")
     .replace('"hexagon"', '"line"'), ("chart",), "topology.edges"),
    ("no spanning tree", BASE.replace('name = "paper_six"', "adjacency = [[0,1,0,0],[1,0,0,0],[0,0,0,1],[0,0,1,0]]")
     .replace('"hexagon"', '"line"'), ("factors",), "spanning tree"),
    # a star (a ring's C is circulant: its eigenvalues come from an FFT, no dense problem to refuse)
    ("300000 agents", BASE.replace('name = "paper_six"', 'name = "star"\nn = 300000')
     .replace('"hexagon"', '"line"'), ("factors",), "memory"),
    ("dense random digraph", BASE.replace('name = "paper_six"', 'name = "random_digraph"\nn = 50000\np = 0.5')
     .replace('"hexagon"', '"line"'), ("factors",), "edges"),
    ("spacing huge", BASE.replace('shape = "hexagon"', 'shape = "hexagon"\nspacing = 1e308'), ("chart",), "spacing"),
    ("unknown shape", BASE.replace('"hexagon"', '"circle"'), ("roots",), "formation.shape"),
    ("map size 1e5 x 1e5", BASE + "[map]\nsize = [100000, 100000]\n", ("map",), "map.size"),
    ("map reaching 1e300", BASE + "[map]\ntau1 = [0.0, 1e300]\nsize = [2, 2]\n", ("map",), "too long"),
    ("map size float", BASE + "[map]\nsize = [2.5, 3]\n", ("map",), "map.size"),
    ("chart window 1e6", BASE + "[chart]\ntau1_max = 1e6\ntau2_max = 1e6\n", ("chart",), "window"),
    ("chart point with empty label", BASE + '[chart]\npoints = { a = "x" }\n', ("chart",), "chart.points.a"),
    ("schedule beyond reach", BASE + "[schedule]\ntau_max = [1e300, 1e300]\n", ("schedule",), "too long"),
    ("unknown key", BASE + "[delays2]\nx = 1\n", ("roots",), "delays2"),
    ("table as value", "topology = 1\n" + BASE.split("\n", 2)[2], ("chart",), "topology"),
    ("not TOML", "this is [not toml", ("chart",), "not valid TOML"),
    ("empty file", "", ("factors",), "[topology]"),
    ("name not a string", 'name = 3\n' + BASE, ("chart",), "name"),
]


@pytest.mark.parametrize(("text", "args", "needle"), [c[1:] for c in SCENARIO_CASES], ids=[c[0] for c in SCENARIO_CASES])
def test_malformed_scenario_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    text: str, args: tuple[str, ...], needle: str,
) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "case.toml"
    path.write_text(text)
    extra = () if args[0] == "factors" else ("--out", str(tmp_path / "out"))
    line = one_line_error(capsys, args[0], str(path), *args[1:], *extra)
    assert needle in line, line
    assert _files(tmp_path) <= {path, tmp_path / "out"}  # nothing but the (empty) output folder


OPTION_CASES: list[tuple[tuple[str, ...], str]] = [
    (("chart", "--tau1", "nan"), "delays.tau1"),
    (("chart", "--tau1", "inf"), "delays.tau1"),
    (("chart", "--tau1", "1e300"), "window"),
    (("chart", "--tau1-max", "1e6", "--tau2-max", "1e6"), "crossing curves"),
    (("chart", "--tau1-max", "nan"), "tau1_max"),
    (("chart", "--point", "=1,1"), "--point"),
    (("chart", "--point", "a=nan,1"), "tau1"),
    (("chart", "--point", "a=0.3,0.2", "--point", "a=1,1"), "twice"),
    (("chart", "--P", "nan"), "gains.P"),
    (("chart", "--topology", "paper_six", "--n", "7"), "6 agents"),
    (("chart", "--topology", "random_digraph", "--n", "5"), "--p"),
    (("chart", "--formation", "star"), "--formation"),
    (("chart", "--out", ""), "--out"),
    (("chart", "--out", "/sys"), "cannot write"),
    (("chart", "--out", "/sys/delayform"), "cannot write"),
    (("chart", ".", "--out", "o"), "directory"),
    (("chart", "missing.toml"), "missing.toml"),
    (("roots", "--tau2", "1e6"), "too long"),
    (("roots", "--P", "1e300"), "gains.P"),
    (("roots", "--region", "nan,1,0,1"), "region"),
    (("roots", "--region", "-1e300,1,0,1"), "rectangle"),
    (("roots", "--region", "-1000,1,0,10000"), "smaller rectangle"),
    (("map", "--size", "100000,100000"), "memory"),
    (("map", "--size", "2,2", "--tau1-range", "nan,1"), "tau1_values"),
    (("map", "--size", "2,2", "--tau1-range", "0,1e300"), "too long"),
    (("schedule", "--tau-min", "nan,1"), "tau_min"),
    (("schedule", "--tau-max", "1e300,1e300"), "too long"),
    (("schedule", "--tau1", "1e300"), "too long"),
    (("factors", "--P", "inf"), "gains.P"),
    (("factors", "--n", "5"), "--topology"),
    (("factors", "--topology", "ring", "--n", "1"), "--n"),
    (("factors", "--topology", "star", "--n", "100000"), "memory"),
    (("factors", "--topology", "complete", "--n", "100000"), "edges"),
    (("chart", "--topology", "random_digraph", "--n", "50000", "--p", "0.5"), "edges"),
    (("factors", "--topology", "random_digraph", "--n", "5", "--p", "2"), "--p"),
    (("factors", "--topology", "complete", "--n", "3", "--p", "0.5"), "--p"),
    (("factors", "--tau1", "1"), "--tau1"),
    (("report", "--topology", "ring", "--n", "12"), "--formation"),
    (("paper", "--out", ""), "--out"),
]


@pytest.mark.parametrize(("args", "needle"), OPTION_CASES, ids=lambda v: " ".join(v) if isinstance(v, tuple) else None)
def test_malformed_option_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    args: tuple[str, ...], needle: str,
) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    line = one_line_error(capsys, *args)
    assert needle in line, line
    assert not any(p.is_file() for p in tmp_path.rglob("*"))  # refused before anything was written


def test_non_utf8_and_directory_scenarios(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00 name")
    assert "UTF-8" in one_line_error(capsys, "roots", "bin.toml")
    (tmp_path / "dir.toml").mkdir()
    assert "directory" in one_line_error(capsys, "factors", "dir.toml")
    assert "not a regular file" in one_line_error(capsys, "factors", "/dev/zero")  # would never end
    (tmp_path / "big.toml").write_bytes(b"#" * (17 * 2**20))
    assert "too large" in one_line_error(capsys, "factors", "big.toml")


def test_output_file_taken_by_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "roots.csv").mkdir()  # the file roots writes cannot be created
    line = one_line_error(capsys, "roots", "--out", str(tmp_path))
    assert "roots.csv" in line


# ================================================================ resource guard
@pytest.mark.parametrize(
    "args",
    [("map", "--size", "100000,100000"), ("chart", "--tau1-max", "1000000", "--tau2-max", "1000000")],
    ids=["map 1e5 x 1e5", "chart tau_max 1e6"],
)
def test_resource_guard_refuses_fast(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str], args: tuple[str, ...]) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    start = time.perf_counter()
    line = one_line_error(capsys, *args)
    assert time.perf_counter() - start < 5.0
    assert "would need about" in line and "reduce" in line


def test_resource_guard_in_the_library() -> None:
    with pytest.raises(ResourceLimitError, match="map.size"):
        dominant_root_map(paper_six(), P, D, np.linspace(0, 8, 100_000), np.linspace(0, 8, 100_000))
    with pytest.raises(ResourceLimitError, match="window"):
        stability_map(paper_six(), P, D, 1e6, 1e6)


# ================================================================ files and paths
@pytest.mark.parametrize(
    ("name", "folder"),
    [("../../evil", "evil"), ("/tmp/absolute/evil", "tmp_absolute_evil"), ("", "scenario"), ("a b/c", "a_b_c")],
)
def test_scenario_name_stays_inside_the_output_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], name: str, folder: str
) -> None:
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    (work / "s.toml").write_text(f'name = "{name}"\n' + BASE + "[map]\nsize = [2, 2]\ntau1 = [0.0, 1.0]\ntau2 = [0.0, 1.0]\n")
    before = _files(tmp_path)
    code, _, err = cli(capsys, "roots", "s.toml")
    assert code == 0, err
    new = _files(tmp_path) - before
    assert new and all(p.is_relative_to(work / "out" / folder) or p == work / "out" for p in new), new
    assert not Path("/tmp/absolute").exists()


def test_operating_point_out_of_window_extends_the_chart(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    code, out, err = cli(capsys, "chart", "--json", "--tau1", "1", "--tau2", "2", "--tau1-max", "0.5",
                         "--tau2-max", "0.5", "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    summary = json.loads(out)
    operating = [p for p in summary["points"] if p["label"] == "operating"]
    assert len(operating) == 1 and (operating[0]["tau1"], operating[0]["tau2"]) == (1.0, 2.0)
    assert summary["window"] == [1.0, 2.0]
    # classified, and the root finder (an independent method) agrees: point c of the paper
    assert not operating[0]["stable"] and operating[0]["unstable_roots"] > 0
    assert not dominant_root(paper_six(), P, D, 1.0, 2.0).is_stable


# ================================================================ silently wrong or ignored
def test_schedule_starts_from_the_given_delays(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from delayform.scenario import paper_scenario

    sc = paper_scenario().with_changes(tau1=1.0, tau2=2.0)
    assert sc.schedule.tau_min == (1.0, 2.0)  # the report schedules from this scenario too
    code, out, err = cli(capsys, "schedule", "--json", "--tau1", "1", "--tau2", "2",
                         "--tau-max", "2,6", "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    result = json.loads(out)
    assert result["tau1"] >= 1.0 and result["tau2"] >= 2.0
    assert result["tau_min"] == [1.0, 2.0]


def test_roots_and_chart_label_the_operating_delays(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    ring12 = Path(__file__).resolve().parents[1] / "examples" / "ring12.toml"
    code, out, err = cli(capsys, "roots", str(ring12), "--json", "--tau1", "1", "--tau2", "0.5",
                         "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    labels = {p["label"]: (p["tau1"], p["tau2"]) for p in json.loads(out)["points"]}
    assert labels == {"operating": (1.0, 0.5)}


def test_chart_of_another_team_needs_no_formation(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = cli(capsys, "chart", "--topology", "ring", "--n", "12", "--P", "0.25", "--D", "2",
                         "--tau1-max", "1", "--tau2-max", "1", "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    assert "point operating" in out or "point a" in out


def test_formation_option_and_random_digraph(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from delayform.scenario import paper_scenario

    sc = paper_scenario().with_changes(topology=random_digraph(7, 0.3, seed=2), formation="polygon")
    assert sc.desired_positions().shape == (7, 2)
    code, out, err = cli(capsys, "factors", "--json", "--topology", "random_digraph", "--n", "7",
                         "--p", "0.3", "--seed", "2")  # fmt: skip
    assert code == 0, err
    listed = [complex(v["re"], v["im"]) for v in json.loads(out)["eigenvalues"]]
    np.testing.assert_allclose(listed, random_digraph(7, 0.3, seed=2).eigenvalues, atol=1e-12)


def test_factors_takes_a_scenario_file_and_summarises_large_teams(capsys: pytest.CaptureFixture[str]) -> None:
    ring12 = Path(__file__).resolve().parents[1] / "examples" / "ring12.toml"
    code, out, err = cli(capsys, "factors", str(ring12))
    assert code == 0, err
    assert "12 agents" in out and "P = 0.25, D = 2" in out
    code, out, err = cli(capsys, "factors", "--topology", "ring", "--n", "200")
    assert code == 0, err
    assert "Compressed" not in out and "200 x 200, 200 non-zero entries" in out
    assert "more factors" in out


# ================================================================ one meaning of stable
@pytest.mark.parametrize("tau2", [0.0, 0.5, 1.0, 3.0, 6.0])
def test_dominant_root_agrees_with_the_ctcr_map_on_tau1_zero(tau2: float) -> None:
    smap = stability_map(paper_six(), P, D, 8.0, 8.0)
    got = dominant_root(paper_six(), P, D, 0.0, tau2)
    assert got.is_stable == bool(smap.is_stable(0.0, tau2))
    # the drift's zero is reported (continuity as tau1 -> 0) without making the team unstable
    assert got.is_drift and got.root == 0 and got.time_constant == math.inf
    assert got.formation_root.real < 0 and got.formation_time_constant < math.inf
    # what decides stability beside the drift: the shape's root, or the centroid factor's next one
    assert got.stability_root.real < 0 and got.stability_root.real >= got.formation_root.real


def test_dominant_root_agrees_with_the_ctcr_map(rng: np.random.Generator) -> None:
    smap = stability_map(paper_six(), P, D, 8.0, 8.0)
    for tau1, tau2 in rng.uniform(0.0, 8.0, size=(12, 2)):
        got = dominant_root(paper_six(), P, D, tau1, tau2)
        if abs(got.root.real) > 1e-3:  # off the boundary, the two methods must agree
            assert got.is_stable == bool(smap.is_stable(tau1, tau2)), (tau1, tau2)


def test_map_agrees_with_dominant_root_on_tau1_zero() -> None:
    m = dominant_root_map(paper_six(), P, D, [0.0, 0.3], [0.0, 0.2, 3.0])
    assert m.stable.all()
    assert m.roots[0, 1] == dominant_root(paper_six(), P, D, 0.0, 0.2).root == 0


@pytest.mark.parametrize("tau1", [1e-12, 1e-9, 1e-6, 1e-5])
def test_tiny_delay_gives_the_centroid_root_beside_zero(tau1: float) -> None:
    # first order in tau1: s^2 + D s (1 - e^{-tau2 s}) + P (1 - e^{-tau1 s}) = 0 near 0
    # gives s (1 + D tau2) + P tau1 = 0 (closed form, independent of the root finder)
    tau2 = 0.2
    got = dominant_root(paper_six(), P, D, tau1, tau2)
    assert got.is_stable and got.is_centroid_drift
    assert got.root.real == pytest.approx(-P * tau1 / (1 + D * tau2), rel=1e-4)
    assert got.formation_root.real == pytest.approx(-0.1296, abs=1e-3)
    assert got.formation_time_constant == pytest.approx(1 / -got.formation_root.real)
    assert got.centroid_time_constant == pytest.approx(1 / -got.root.real)


def test_time_constant_of_an_unstable_root_is_infinite() -> None:
    got = dominant_root(paper_six(), P, D, 1.0, 2.0)  # point c, unstable
    assert not got.is_stable
    assert got.time_constant == math.inf and got.growth_rate == pytest.approx(got.root.real)


def test_root_on_the_region_boundary_is_reported() -> None:
    centroid = factors(paper_six(), P, D)[0]
    roots = roots_in(centroid, 0.3, 0.2, (-3.0, 1.0, 0.0, 10.0))  # s = 0 lies on Im s = 0
    assert np.any(roots == 0.0)
    wider = roots_in(centroid, 0.3, 0.2, (-3.0, 1.0, -0.5, 10.0))
    assert sorted(roots, key=abs) == pytest.approx(sorted(wider[wider.imag >= 0], key=abs))


def test_tiny_delay_roots_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = cli(capsys, "roots", "--tau1", "1e-6", "--out", str(tmp_path))
    assert code == 0, err
    assert "centroid time constant" in out and "formation time constant" in out


# ================================================================ API
@pytest.mark.parametrize(
    ("call", "error"),
    [
        (lambda: Topology.from_edges([(0, 1.5), (1, 0)]), TopologyError),
        (lambda: Topology.from_edges([(0, True), (1, 0)]), TopologyError),
        (lambda: random_digraph(5, True), TopologyError),
        (lambda: factors(Topology.from_adjacency(np.kron(np.eye(2), [[0, 1], [1, 0]])), P, D), NoSpanningTreeError),
        (lambda: dominant_root(paper_six(), 1e300, D, 0.3, 0.2), GainError),
        (lambda: dominant_root(paper_six(), P, D, 0.3, 1e6), DelayError),
    ],
    ids=["edge 1.5", "edge True", "p True", "no spanning tree", "huge gain", "delay 1e6"],
)
def test_api_refuses(call: object, error: type[Exception]) -> None:
    with pytest.raises(error):
        call()  # type: ignore[operator]


# ================================================================ messages and figures
@pytest.mark.parametrize(
    ("value", "text"),
    [(complex(-1.3878e-16, 1.0), "1j"), (complex(1.0, 1e-17), "1"), (complex(-0.5, -0.25), "-0.5 - 0.25j"), (0j, "0")],
)
def test_numbers_zero_to_working_precision_print_as_zero(value: complex, text: str) -> None:
    assert format_number(value) == text


def test_describe_drops_rounding_noise() -> None:
    from delayform.characteristic import TwoDelayQuasiPolynomial

    q = TwoDelayQuasiPolynomial([1.0, 0.5, 1.0], [complex(-1.66533e-16, -8.32667e-17)], [0, -0.5])
    assert "e-1" not in q.describe()
    from delayform.topology import ring

    texts = [f.describe() for f in factors(ring(12), P, D)]  # the eigenvalues +-1j carry -1.4e-16 real parts
    assert "lam = +- 1j: order 4, disagreement" in texts and not any("e-1" in t for t in texts)


def test_jargon_free_messages() -> None:
    from delayform.characteristic import TwoDelayQuasiPolynomial
    from delayform.errors import QuasiPolynomialError

    with pytest.raises(QuasiPolynomialError) as info:
        TwoDelayQuasiPolynomial([1.0, math.inf])
    assert "non-finite" not in str(info.value) and "finite numbers" in str(info.value)


def test_chart_legend_lists_what_is_drawn() -> None:
    import matplotlib.pyplot as plt

    smap = stability_map(paper_six(), P, D, 1.0, 1.0)  # a small window: kernel curves only or none
    ax = smap.plot()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "stable (NU = 0)"
    has_offspring = any(not c.is_kernel for c in smap.curves)
    assert any("offspring" in t for t in labels) == has_offspring
    plt.close("all")


def test_contour_colour_bar_has_units() -> None:
    import matplotlib.pyplot as plt

    m = dominant_root_map(paper_six(), P, D, [0.1, 0.5, 1.0], [0.1, 0.5, 1.0])
    ax = m.plot_contour()
    labels = [a.get_ylabel() for a in ax.figure.axes]
    assert any("1/s" in label for label in labels)
    plt.close("all")


def test_schedule_names_the_centroid_and_formation_settling(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    code, out, err = cli(capsys, "schedule", "--json", "--tau-min", "0.001,0", "--tau-max", "0.01,0.01",
                         "--out", str(tmp_path))  # fmt: skip
    assert code == 0, err
    result = json.loads(out)
    # tiny tau1: the centroid's root -P tau1 / (1 + D tau2) is the slowest, the shape settles much faster
    assert result["dominant_is_centroid"]
    assert result["root"]["re"] == pytest.approx(-P * result["tau1"] / (1 + D * result["tau2"]), rel=1e-3)
    assert result["formation_settling_time"] < result["settling_time"]


def test_chart_with_many_curves_still_shows_the_stable_region() -> None:
    """A large team's chart (thousands of curves) must not hide the stable region under red ink."""
    from types import SimpleNamespace

    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from delayform.plots import stability_chart

    t = np.linspace(0.0, 4.0, 50)
    curves = [SimpleNamespace(tau1=t, tau2=np.full_like(t, y), is_kernel=True) for y in np.linspace(0, 4, 2000)]
    smap = SimpleNamespace(curves=curves, tau1_max=4.0, tau2_max=4.0,
                           is_stable=lambda a, b: np.broadcast_to(a + 0 * b < 2.0, np.broadcast_shapes(np.shape(a), np.shape(b))))  # fmt: skip
    ax = stability_chart(smap)
    lines = [c for c in ax.collections if isinstance(c, LineCollection) and len(c.get_segments()) == 2000]
    assert lines and lines[0].get_linewidth()[0] < 0.3 and lines[0].get_alpha() < 1.0
    shaded = [c for c in ax.collections if c not in lines and c.get_zorder() > lines[0].get_zorder()]
    assert shaded  # the stable region and its outline are drawn over the curves
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["stable (NU = 0)", "kernel curves (2000)"]
    plt.close("all")


@pytest.mark.parametrize("n", [1, 2, 6, 23, 101])
def test_nearest_coarse_point_without_a_distance_table(n: int) -> None:
    """A 100000 x 2 map once built a 100000 x 20000 distance table (16 GB, killed); same answer in O(n)."""
    from delayform.analysis.roots.family.solve import _nearest

    axis = np.linspace(0.0, 8.0, n)
    coarse = np.unique(np.append(np.arange(0, n, 5), n - 1))
    brute = coarse[np.abs(axis[:, None] - axis[coarse][None, :]).argmin(axis=1)]
    np.testing.assert_array_equal(_nearest(np.arange(n), coarse, axis), brute)


# ================================================================ every size a user gives is budgeted
BIG_RING = '[topology]\nname = "ring"\nn = 1000000000\n[gains]\nP = 1.0\nD = 0.5\n[delays]\ntau1 = 0.3\ntau2 = 0.2\n'


@pytest.mark.parametrize(
    ("args", "needle", "absent"),
    [
        (("factors", "big.toml"), "topology.n", None),
        (("box", "--tau1-box", "0,100", "--tau2-box", "0,100"), "--tau1-box", None),
        (("simulate", "--topology", "ring", "--n", "100000", "--formation", "polygon"), "100,000 agents", None),
        (("jitter", "--topology", "ring", "--n", "100000"), "--n", None),
        (("links", "--topology", "ring", "--n", "5000"), "would take about", None),
        (("check", "--robot", "create3", "--tau1", "1e6", "--tau2", "1e6"), "--tau1", "chart."),
    ],
    ids=["scenario ring 1e9", "box 0-100 s", "simulate ring 1e5", "jitter ring 1e5", "links ring 5000", "check 1e6 s"],
)
def test_cli_budget_refuses_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                        args: tuple[str, ...], needle: str, absent: str | None) -> None:  # fmt: skip
    from test_resources import alarm

    monkeypatch.chdir(tmp_path)
    (tmp_path / "big.toml").write_text(BIG_RING)
    with alarm(20):  # the command line's imports under load, then a refusal before any work
        line = one_line_error(capsys, *args)
    assert ("would need about" in line or "would take about" in line) and "reduce" in line and needle in line
    assert absent is None or absent not in line
    assert "--tau1-max" not in line  # no option of another command
    assert not list(tmp_path.glob("out/**/*.png"))  # refused before anything was written
