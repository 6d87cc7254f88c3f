"""Tests of delayform.analysis.roots.team_roots: every root of every factor in a rectangle, batched.

The batched family path (reduced Chebyshev generator, vectorized Newton, the rectangle's
winding walked for all factors at once) is checked against the per-factor
``spectrum.roots_in`` (full-size generator, generic Newton, per-segment walk) and every
root against the quasi-polynomial itself; ``delayform roots`` keeps its output and shows
its progress on stderr only.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import delayform
from delayform.analysis.roots import team_roots as fr
from delayform.analysis.roots.team_roots import factor_roots_in
from delayform.analysis.roots.dominant import RESIDUAL_TOL, relative_residual, roots_in
from delayform.characteristic import factors
from delayform.errors import ResourceLimitError
from delayform.topology import paper_six, random_digraph, ring, star

CASES = [
    (paper_six(), 0.3, 0.2, (-2.0, 1.0, -0.01, 10.0)),
    (paper_six(), 1.0, 2.0, (-3.0, 1.0, -5.0, 5.0)),  # point c: unstable, complex pairs
    (ring(40), 3.0, 2.0, (-2.0, 1.0, -0.01, 10.0)),  # many factors, long delays
    (random_digraph(30, 0.1, seed=3), 0.5, 0.0, (-4.0, 1.0, -3.0, 8.0)),  # complex lam, tau2 = 0
    (star(7), 0.0, 0.4, (-3.0, 1.0, -0.01, 6.0)),  # tau1 = 0: the centroid's double zero
]


def _same_as_roots_in(topo, t1, t2, region, got) -> int:
    fs = factors(topo, 1.0, 0.5)
    assert [complex(f.lam) for f, _ in got] == [complex(f.lam) for f in fs]
    total = 0
    for f, roots in got:
        ref = roots_in(f, t1, t2, region)
        assert roots.shape == ref.shape, (f, roots, ref)
        assert np.allclose(roots, ref, rtol=0.0, atol=1e-8 * (1.0 + np.abs(ref))), (f, roots, ref)
        x0, x1, y0, y1 = region
        assert np.all((roots.real >= x0) & (roots.real <= x1) & (roots.imag >= y0) & (roots.imag <= y1))
        assert np.all(relative_residual(f.quasi_polynomial, roots, t1, t2) <= RESIDUAL_TOL)
        total += roots.size
    return total


@pytest.mark.parametrize("topo, t1, t2, region", CASES, ids=lambda v: getattr(v, "name", None))
def test_batched_roots_equal_the_per_factor_roots(topo, t1, t2, region):
    got = factor_roots_in(topo, 1.0, 0.5, t1, t2, region)
    assert _same_as_roots_in(topo, t1, t2, region, got) > 0


def test_fallbacks_give_the_same_roots(monkeypatch):
    topo, t1, t2, region = CASES[2]
    # an uncertified count sends every factor through roots_in; a "multiple" root through
    # the generic multiplicity test: the answer must not change either way
    monkeypatch.setattr(fr, "_rectangle_counts", lambda lam, *a, **k: np.full(lam.size, np.nan))
    _same_as_roots_in(topo, t1, t2, region, factor_roots_in(topo, 1.0, 0.5, t1, t2, region))
    monkeypatch.undo()
    monkeypatch.setattr(fr, "_simple", lambda s, *a: np.zeros(s.shape, dtype=bool))
    _same_as_roots_in(topo, t1, t2, region, factor_roots_in(topo, 1.0, 0.5, t1, t2, region))


def test_batched_counts_equal_the_per_segment_counts():
    # the family walk against the generic per-segment walk behind roots_in, factor by factor
    topo, t1, t2, region = CASES[3]
    x0, x1, y0, y1 = region
    mirrored = (x0, x1, -max(abs(y0), abs(y1)), max(abs(y0), abs(y1)))
    fs = [f for f in factors(topo, 1.0, 0.5) if not f.is_centroid]
    lam = np.array([complex(f.lam) for f in fs])
    pair = np.array([f.group.is_complex_pair for f in fs])
    counts_pair = fr._rectangle_counts(lam[pair], t1, t2, 1.0, 0.5, mirrored)
    counts_real = fr._rectangle_counts(lam[~pair], t1, t2, 1.0, 0.5, region)
    assert pair.any() and (~pair).any()
    # a pair factor lists lam's roots and their conjugates: lam's own count is half of them
    assert counts_pair.tolist() == [roots_in(f, t1, t2, mirrored).size / 2 for f, p in zip(fs, pair) if p]
    assert counts_real.tolist() == [roots_in(f, t1, t2, region).size for f, p in zip(fs, pair) if not p]


def test_progress_reaches_every_factor():
    calls = []
    got = factor_roots_in(ring(40), 1.0, 0.5, 3.0, 2.0, (-2.0, 1.0, -0.01, 10.0), progress=lambda d, t: calls.append((d, t)))
    assert calls[-1] == (len(got), len(got)) and all(b[0] >= a[0] for a, b in zip(calls, calls[1:]))


def test_far_rectangle_is_refused_up_front_with_one_that_fits():
    with pytest.raises(ResourceLimitError, match=r"\|s\| <= 1280.*e\.g\. -1000,1,0,") as info:
        factor_roots_in(ring(3000), 1.0, 0.5, 0.3, 0.2, (-1000.0, 1.0, 0.0, 10000.0))
    message = str(info.value)
    assert "\n" not in message
    hint = tuple(float(v) for v in message.rsplit("e.g. ", 1)[1].split(","))
    from delayform.analysis.roots.generator import _require_resolvable

    _require_resolvable(hint, 0.3)  # the suggested rectangle is accepted
    assert hint[0] == -1000.0 and hint[3] < 10000.0


def test_roots_command_output_unchanged_and_progress_on_stderr_only(tmp_path: Path):
    args = [sys.executable, "-m", "delayform", "roots", "--json", "--topology", "ring", "--n", "40", "--formation",
            "polygon", "--tau1", "3", "--tau2", "2", "--out", str(tmp_path)]  # fmt: skip
    env = {"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "PYTHONPATH": str(Path(delayform.__file__).resolve().parents[1])}  # fmt: skip
    plain = subprocess.run(args, capture_output=True, text=True, env=env, timeout=300)
    # a terminal, as far as Rich can tell: the bar is drawn and left standing
    tty = subprocess.run(args, capture_output=True, text=True, env=env | {"TTY_COMPATIBLE": "1"}, timeout=300)
    assert plain.returncode == 0 and tty.returncode == 0, (plain.stderr, tty.stderr)
    assert plain.stderr == "" and "roots of every factor" in tty.stderr and "21/21" in tty.stderr
    assert plain.stdout == tty.stdout  # the bar never reaches stdout
    out = json.loads(tty.stdout)
    listed = np.array([complex(r["root"]["re"], r["root"]["im"]) for r in out["roots_in_region"]])
    ref = np.concatenate([roots_in(f, 3.0, 2.0, out["region"]) for f in factors(ring(40), 1.0, 0.5)])
    assert listed.size == ref.size and np.abs(listed[:, None] - ref[None, :]).min(axis=1).max() < 1e-8
    assert os.path.exists(tmp_path / "roots.csv")
