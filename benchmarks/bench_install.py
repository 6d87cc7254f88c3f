"""Benchmark: what ``pip install delayform`` brings, with and without extras. Prints a markdown table.

Builds the wheel of this checkout, installs it into fresh venvs (the core;
``[all]``) from the configured package index, and reports for each: the
packages pip installed (delayform included; the venv's own pip and
setuptools not), the size of site-packages (``du -sm``, pip and setuptools
included, as a user sees it) and the wall time of ``import delayform`` and
``import delayform.cli`` in a fresh interpreter (best and median of
``--repeat``). The machine is shared: times are inflated by others' load.

Run: ``.venv/bin/python benchmarks/bench_install.py [--repeat 7] [--extras "" all]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_COUNT = ("import importlib.metadata as md, json; print(json.dumps(sorted(d.metadata['Name'] for d in "
          "md.distributions() if d.metadata['Name'].lower() not in ('pip', 'setuptools'))))")  # fmt: skip


def _venv(where: Path, requirement: str) -> Path:
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True)
    python = where / "bin" / "python"
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", requirement], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    return python


def _times(python: Path, code: str, repeat: int) -> tuple[float, float]:
    seconds = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([str(python), "-c", code], check=True)
        seconds.append(time.perf_counter() - start)
    return min(seconds), statistics.median(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--extras", nargs="*", default=["", "all"], help='extras to install ("" for the core)')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        dist = Path(tmp) / "dist"
        subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(ROOT)], check=True,
                       stdout=subprocess.DEVNULL)  # fmt: skip
        (wheel,) = dist.glob("delayform-*.whl")
        print("| install | packages | site-packages (MiB) | import delayform best / median (s) "
              "| import delayform.cli best / median (s) |\n|---|---|---|---|---|")  # fmt: skip
        for extra in args.extras:
            python = _venv(Path(tmp) / f"venv-{extra or 'core'}", f"{wheel}[{extra}]" if extra else str(wheel))
            names = json.loads(subprocess.run([str(python), "-c", _COUNT], check=True, capture_output=True,
                                              text=True).stdout)  # fmt: skip
            site = next((python.parent.parent / "lib").glob("python*/site-packages"))
            mib = int(subprocess.run(["du", "-sm", str(site)], check=True, capture_output=True, text=True).stdout.split()[0])
            root = _times(python, "import delayform", args.repeat)
            cli = _times(python, "import delayform.cli", args.repeat)
            label = f"delayform[{extra}]" if extra else "delayform"
            print(f"| `{label}` | {len(names)} | {mib} | {root[0]:.3f} / {root[1]:.3f} | {cli[0]:.3f} / {cli[1]:.3f} |")


if __name__ == "__main__":
    main()
