"""`delayform links`, `box` and `jitter` (issue 20): answers, and one line + exit 2 on bad input, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from test_cli import assert_one_line_error, run


def test_links_with_a_per_link_file(tmp_path):
    t1 = np.full((6, 6), 0.3)
    t1[0, 1] = 0.5
    np.savetxt(tmp_path / "t1.csv", t1, delimiter=",")
    proc = run("links", "--tau1-file", str(tmp_path / "t1.csv"), "--tau2", "0.2", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["stable"] and out["dominant_root"][0] < 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t1.csv"]


def test_box_and_jitter_answers(tmp_path):
    box = run("box", "--tau1-box", "0.25,0.35", "--tau2-box", "0.15,0.25", "--json", cwd=tmp_path)
    assert box.returncode == 0 and json.loads(box.stdout)["status"] == "certified"
    jit = run("jitter", "--json", cwd=tmp_path)
    assert jit.returncode == 0 and 0 < json.loads(jit.stdout)["delta_s"] < 0.3


@pytest.mark.parametrize(
    "args, needle",
    [
        (("jitter", "--tau1", "1", "--tau2", "2"), "unstable"),
        (("box", "--tau1-box", "0.35,0.25", "--tau2-box", "0.1,0.2"), "LO = 0.35 > HI"),
        (("links", "--tau1-file", "missing.csv"), "not a file"),
        (("links", "--tau1-file", "wrong.csv"), "6 x 6"),
        (("links", "--tau1-file", "negative.csv"), "non-negative"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, args, needle):
    np.savetxt(tmp_path / "wrong.csv", np.ones((5, 5)), delimiter=",")
    np.savetxt(tmp_path / "negative.csv", -np.ones((6, 6)), delimiter=",")
    np.savetxt(tmp_path / "nan.csv", np.full((6, 6), np.nan), delimiter=",")
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = run(*args, cwd=tmp_path)
    assert_one_line_error(proc, needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_jitter_certify_answers_per_link_and_for_delays_varying_together(tmp_path):
    """At b: +-0.03 s is within the small-gain margin (0.035 s); +-0.05 s is not, and is certified per mode.

    The per-mode verdict is that of the library (every mode re-checked exactly), whose numbers are
    checked against the spectrum and the adversary in test_covered_windows.py and test_team_certificates.py.
    """
    inside = run("jitter", "--tau1", "2", "--tau2", "1", "--certify", "0.03", "--json", cwd=tmp_path)
    assert inside.returncode == 0, inside.stderr
    out = json.loads(inside.stdout)
    assert out["per_link"] is True and out["together"] is True and 0.03 < out["per_link_margin_s"] < 0.04
    assert out["together_reason"] is None and out["covers"]["together"].startswith("the same")
    beyond = run("jitter", "--tau1", "2", "--tau2", "1", "--certify", "0.05", cwd=tmp_path)
    assert beyond.returncode == 0, beyond.stderr
    lines = beyond.stdout.splitlines()
    assert lines[0].startswith("+-0.05 s per link, each delay varying on its own: not certified (small-gain margin 0.035")
    assert lines[1].startswith("+-0.05 s with the same delays on every link, varying together: certified, every mode")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "args, needle",
    [
        (("--certify", "0"), "(0, tau1 = 2)"),
        (("--certify", "2.5"), "(0, tau1 = 2)"),
        (("--certify", "nan"), "(0, tau1 = 2)"),
        (("--certify", "0.1", "--method", "best"), "--method chooses a margin's search"),
        (("--certify", "0.1", "--tau1-file", "t1.csv"), "one delay pair on every link"),
    ],
)
def test_jitter_certify_refuses_bad_input_in_one_line(tmp_path, args, needle):
    np.savetxt(tmp_path / "t1.csv", np.full((6, 6), 2.0), delimiter=",")
    base = ("jitter", "--tau2", "1") + (() if "--tau1-file" in args else ("--tau1", "2"))
    proc = run(*base, *args, cwd=tmp_path)
    assert_one_line_error(proc, needle)
