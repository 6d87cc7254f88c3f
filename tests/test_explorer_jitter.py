"""The explorer's jitter-margin layer (/api/jitter_map): values, caching, refusals.

The served margins are compared with independent calls of jitter_margin at the
same delays (each with its own nominal root, not the map's chart classification)
and with the exact CTCR map where nothing is certified.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.network import jitter_margin
from delayform.app import Explorer, start
from delayform.app.jitter_layer import JitterLayer
from delayform.errors import InputError
from delayform.scenario import paper_scenario, parse_scenario
from delayform.topology import paper_six
from test_explorer import get, get_json


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with start(Explorer(paper_scenario(), out_dir=tmp_path_factory.mktemp("jitter") / "out")) as running:
        yield running


def test_layer_values_are_the_point_certificates(server):
    m = get_json(server, "/api/jitter_map?tau1_max=3&tau2_max=3&grid=4")
    assert m["tau1"] == pytest.approx([0.375, 1.125, 1.875, 2.625])  # cell centres, as the shading
    smap = stability_map(paper_six(), 1.0, 0.5, 3.0, 3.0)
    for j, b in enumerate(m["tau2"]):
        for i, a in enumerate(m["tau1"]):
            if smap.is_stable(a, b):
                assert m["delta"][j][i] == pytest.approx(jitter_margin(paper_six(), 1.0, 0.5, a, b).delta, rel=1e-12)
            else:
                assert m["delta"][j][i] is None  # nothing certified where the exact chart is unstable
    assert m["largest"] == max(v for row in m["delta"] for v in row if v is not None)
    assert m["levels"] and m["levels"][-1] <= m["largest"]


def test_gains_change_the_layer(server):
    one = get_json(server, "/api/jitter_map?tau1_max=1&tau2_max=1&grid=4")
    two = get_json(server, "/api/jitter_map?tau1_max=1&tau2_max=1&grid=4&P=2&D=1.5")
    a, b = two["tau1"][0], two["tau2"][0]
    assert two["delta"][0][0] == pytest.approx(jitter_margin(paper_six(), 2.0, 1.5, a, b).delta, rel=1e-12)
    assert two["delta"][0][0] != one["delta"][0][0]


def test_cached_like_the_stability_map(tmp_path):
    layer = JitterLayer(Explorer(paper_scenario(), out_dir=tmp_path / "out"))
    first = layer.compute(1.0, 0.5, 1.0, 1.0, 4)
    assert layer.compute(1.0, 0.5, 1.0, 1.0, 4) is first
    assert layer.compute(1.0, 0.5, 1.0, 1.0, 5) is not first


@pytest.mark.parametrize("query", ["grid=3", "grid=25", "grid=abc", "grid=4.5", "tau1_max=0", "tau2_max=nan",
                                   "P=0", "tau1_max=18", "foo=1", "grid=4&grid=5"])  # fmt: skip
def test_malformed_requests_get_400_and_one_line(server, query):
    status, kind, body = get(server, f"/api/jitter_map?{query}")
    assert status == 400 and kind.startswith("application/json"), body
    assert "\n" not in body.decode().strip() and 0 < len(json.loads(body)["error"]) < 200


def test_refused_up_front_where_it_cannot_certify(tmp_path):
    lagged = Explorer(replace(paper_scenario(), actuation_delay=0.05), out_dir=tmp_path / "a")
    with pytest.raises(InputError, match="tau_a = 0"):
        JitterLayer(lagged).compute(1.0, 0.5, 1.0, 1.0, 4)
    big = parse_scenario({"topology": {"name": "ring", "n": 40}, "gains": {"P": 1, "D": 0.5},
                          "delays": {"tau1": 0.1, "tau2": 0.1}, "formation": {"shape": "polygon"}})  # fmt: skip
    with pytest.raises(InputError, match="GUARANTEE_AGENTS"):
        JitterLayer(Explorer(big, out_dir=tmp_path / "b")).compute(1.0, 0.5, 1.0, 1.0, 4)


def test_the_page_loads_the_layer_script(server):
    status, _, page = get(server, "/")
    assert status == 200 and b'src="/static/jitter_layer.js"' in page
    status, kind, js = get(server, "/static/jitter_layer.js")
    assert status == 200 and kind.startswith("text/javascript") and b"/api/jitter_map" in js


def test_a_map_too_long_for_one_request_is_refused(tmp_path):
    ring = parse_scenario({"topology": {"name": "ring", "n": 30}, "gains": {"P": 1, "D": 0.5},
                           "delays": {"tau1": 0.1, "tau2": 0.1}, "formation": {"shape": "polygon"}})  # fmt: skip
    with pytest.raises(InputError, match="MAX_SECONDS"):
        JitterLayer(Explorer(ring, out_dir=tmp_path / "r")).compute(1.0, 0.5, 1.0, 1.0, 24)


# ---------------------------------------------------------------- guaranteed beside observed
def test_guarantees_beside_the_page_run(server):
    from delayform.analysis.network import link_dominant_root

    ideal = get_json(server, "/api/guarantees?tau1=0.3&tau2=0.2&duration=20")
    (exact,) = ideal["guarantees"]
    root = link_dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2).root
    assert exact["holds"] is True and f"{root.real:.4g}" in exact["detail"]
    run = get_json(server, "/api/simulate?tau1=0.3&tau2=0.2&duration=20")
    assert ideal["observed"]["status"] == run["status"] and ideal["contradictions"] == []
    jit = get_json(server, "/api/guarantees?tau1=0.3&tau2=0.2&duration=20&network=1&loss=0&jitter=0.05")
    margin = [g for g in jit["guarantees"] if "jitter margin" in g["name"]]
    assert margin and margin[0]["holds"] is True  # 0.05 s within the certified 0.107 s
    h = get_json(server, "/api/simulate?tau1=0.3&tau2=0.2&duration=20&network=1&loss=0&jitter=0.05")["dt"]
    # packets every step: the held age reaches tau + jitter + dt, so the margin is asked about tau + dt / 2
    assert f"{jitter_margin(paper_six(), 1.0, 0.5, 0.3 + h / 2, 0.2 + h / 2).delta:.4g}" in margin[0]["detail"]


def test_guarantees_at_c_prove_instability(server):
    r = get_json(server, "/api/guarantees?tau1=1&tau2=2&duration=20")
    assert r["guarantees"][0]["holds"] is False and r["contradictions"] == []


@pytest.mark.parametrize("query", ["tau1=0.3", "tau1=0.3&tau2=0.2&duration=0", "tau1=0.3&tau2=0.2&loss=0.5",
                                   "tau1=0.3&tau2=0.2&foo=1"])  # fmt: skip
def test_guarantees_refuse_malformed_requests(server, query):
    status, _, body = get(server, f"/api/guarantees?{query}")
    assert status == 400 and 0 < len(json.loads(body)["error"]) < 300


def test_the_caches_belong_to_the_explorer_not_to_the_layer_object(tmp_path):
    from delayform.app.side_by_side import SideBySide

    ex = Explorer(paper_scenario(), out_dir=tmp_path / "out")
    first = JitterLayer(ex).compute(1.0, 0.5, 1.0, 1.0, 4)
    assert JitterLayer(ex).compute(1.0, 0.5, 1.0, 1.0, 4) is first  # a new layer object, the same cache
    other = Explorer(paper_scenario(), out_dir=tmp_path / "other")
    assert JitterLayer(other).compute(1.0, 0.5, 1.0, 1.0, 4) is not first
    a = SideBySide(ex).compute(1.0, 0.5, 0.3, 0.2, 5.0, 10)
    assert SideBySide(ex).compute(1.0, 0.5, 0.3, 0.2, 5.0, 10).guarantees is a.guarantees
