"""Hardening at run time (issue 24, items 2-3): Dask workers and scheduler addresses, interrupted writes.

Every server here is a throwaway socket or HTTP server on 127.0.0.1 started
by the test; nothing else is ever contacted. The command line runs in-process
(``delayform.cli.main``) where that is enough, in a subprocess where the
question is what a user's terminal shows.
"""

from __future__ import annotations

import http.server
import json
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import delayform
from delayform._files import PARTIAL_MARK, atomic_path, staged_folder, write_text
from delayform.errors import ClusterError
from delayform.simulation.experiments.sweeps import check_scheduler, check_workers, executor_for, parse_scheduler, usable_cores

SRC = Path(delayform.__file__).resolve().parents[1]


def run(*args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "delayform", *args], capture_output=True, text=True, cwd=cwd, timeout=timeout,
        env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin", "HOME": str(cwd), "PYTHONPATH": str(SRC)},
    )  # fmt: skip


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    from delayform.cli import main

    with pytest.raises(SystemExit) as info:
        main(list(args))
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return int(info.value.code or 0), out, err


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


# ----------------------------------------------------------------- servers on 127.0.0.1
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def web_server() -> Iterator[str]:
    """An HTTP server: it accepts and waits for a request, as a web server does."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.fixture
def chatty_server() -> Iterator[str]:
    """A server that speaks first, but not Dask: its first 8 bytes read as a length of exabytes."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen()
    sock.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = sock.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{sock.getsockname()[1]}"
    stop.set()
    thread.join()
    sock.close()


# ----------------------------------------------------------------- item 2: Dask
@pytest.mark.parametrize(
    ("address", "reason"),
    [
        ("tcp://[::1", "invalid ipv6 url"),
        ("tcp://[::1]:87x6", "port"),
        ("tcp://host", "no port"),
        ("tcp://host:0", "no port"),
        ("tcp://host:70000", "out of range"),
        ("tcp://:8786", "no host"),
        ("http://host:8786", "tcp or tls"),
        ("tcp://host:8786/path", "nothing may follow"),
        ("tcp://user@host:8786", "nothing may follow"),
        ("tcp://ho st:8786", "spaces"),
        ("", "empty"),
    ],
)
def test_a_malformed_scheduler_address_is_one_clear_error_before_any_connection(address: str, reason: str) -> None:
    with pytest.raises(ClusterError, match=reason) as info:
        parse_scheduler(address)
    assert "\n" not in str(info.value)
    with pytest.raises(ClusterError, match=reason):
        with executor_for(scheduler=address):
            pass


def test_well_formed_addresses_parse_to_scheme_host_port() -> None:
    assert parse_scheduler("tcp://10.0.0.5:8786") == ("tcp", "10.0.0.5", 8786)
    assert parse_scheduler("127.0.0.1:8786") == ("tcp", "127.0.0.1", 8786)
    assert parse_scheduler("tls://[::1]:8786") == ("tls", "::1", 8786)
    with pytest.raises(ClusterError, match="must be an address"):
        parse_scheduler(8786)


def test_worker_counts_beyond_this_machine_are_refused_up_front_naming_its_cores() -> None:
    cores = usable_cores()
    assert check_workers(cores) == cores
    with pytest.raises(ClusterError, match=f"this machine has {cores} core") as info:
        check_workers(1000)
    assert f"at most {cores}" in str(info.value)
    for bad in (0, -1, True, 1.5, "2"):
        with pytest.raises(ClusterError, match="positive integer"):
            check_workers(bad)


def test_a_closed_port_fails_at_once() -> None:
    start = time.perf_counter()
    with pytest.raises(ClusterError, match="cannot reach"):
        check_scheduler(f"tcp://127.0.0.1:{_free_port()}", timeout=2.0)
    assert time.perf_counter() - start < 2.0


def test_a_web_server_is_not_taken_for_a_scheduler_and_fails_within_the_timeout(web_server: str) -> None:
    start = time.perf_counter()
    with pytest.raises(ClusterError, match="is not a Dask scheduler: nothing came back within 0.5 s"):
        with executor_for(scheduler=web_server, timeout=0.5):
            pass
    assert time.perf_counter() - start < 3.0


def test_a_server_that_answers_something_else_is_refused_without_reading_its_length(chatty_server: str) -> None:
    with pytest.raises(ClusterError, match=r"is not a Dask scheduler \(it answered b'HTTP/1.1'\)"):
        check_scheduler(chatty_server, timeout=2.0)


def test_a_real_scheduler_passes_the_check_and_one_without_workers_is_refused() -> None:
    from distributed import LocalCluster

    # threads, not processes: only the scheduler's greeting matters here
    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:  # fmt: skip
        address = cluster.scheduler_address
        assert check_scheduler(address, timeout=2.0) == address
        with pytest.raises(ClusterError, match="has no workers"):
            with executor_for(scheduler=address, timeout=0.5):
                pass


def test_a_local_cluster_that_cannot_start_is_one_cluster_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import distributed

    def fails(*args: object, **kwargs: object) -> None:
        raise RuntimeError("Nanny failed to start.")

    monkeypatch.setattr(distributed, "LocalCluster", fails)
    with pytest.raises(ClusterError, match=r"could not start a local Dask cluster of 1 worker process \(Nanny"):
        with executor_for(workers=1):
            pass


@pytest.mark.parametrize("command", [("montecarlo", "--runs", "2"),
                                     ("sweep", "--tau1-values", "0.3", "--tau2-values", "0.2", "--runs", "1")])  # fmt: skip
def test_cli_workers_beyond_the_cores_exit_2_at_once(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, command: tuple[str, ...]
) -> None:
    code, out, err = cli(capsys, *command, "--workers", "1000", "--out", str(tmp_path / "o"))
    assert code == 2 and out == ""
    assert f"this machine has {usable_cores()} core" in one_line(err)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", [("montecarlo", "--runs", "2"),
                                     ("sweep", "--tau1-values", "0.3", "--tau2-values", "0.2", "--runs", "1")])  # fmt: skip
def test_cli_bad_schedulers_exit_2_in_one_line_and_leave_no_folder(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, chatty_server: str, command: tuple[str, ...]
) -> None:
    for address, needle in (("tcp://[::1", "invalid ipv6 url"), (chatty_server, "is not a Dask scheduler")):
        out_dir = tmp_path / "o"
        code, out, err = cli(capsys, *command, "--scheduler", address, "--out", str(out_dir))
        assert code == 2 and out == "", err
        assert needle in one_line(err)
        assert not out_dir.exists()


@pytest.mark.slow
def test_cli_sweep_against_a_web_server_fails_in_seconds_with_no_folder(tmp_path: Path, web_server: str) -> None:
    start = time.perf_counter()
    proc = run("sweep", "--tau1-values", "0.3", "--tau2-values", "0.2", "--runs", "1", "--scheduler", web_server,
               "--out", "o", cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 2 and proc.stdout == ""
    assert "is not a Dask scheduler" in one_line(proc.stderr)
    assert time.perf_counter() - start < 30.0  # the 5 s greeting wait plus the interpreter's start
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------- item 3: interrupted writes
def _left_over(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if PARTIAL_MARK in p.name)


def test_atomic_path_keeps_the_old_file_when_interrupted(tmp_path: Path) -> None:
    target = write_text(tmp_path / "table.csv", "old,complete\n")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("new,trunc")
            raise KeyboardInterrupt
    assert target.read_text() == "old,complete\n" and _left_over(tmp_path) == []
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".csv" and PARTIAL_MARK in tmp.name
        tmp.write_text("new,complete\n")
    assert target.read_text() == "new,complete\n" and _left_over(tmp_path) == []


@pytest.mark.slow
def test_simulate_csv_interrupted_leaves_the_previous_csv_and_exits_130(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    args = ("simulate", "--csv", "--duration", "2", "--topology", "ring", "--n", "3", "--formation", "polygon",
            "--model", "double_integrator", "--out", str(tmp_path))
    assert cli(capsys, *args)[0] == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert "sim_operating.csv" in before
    real = np.savetxt

    def half_then_ctrl_c(fname: object, X: object, *a: object, **k: object) -> None:
        real(fname, np.asarray(X)[:3], *a, **k)  # some rows reach the disk, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savetxt", half_then_ctrl_c)
    code, out, err = cli(capsys, *args)
    assert code == 130
    assert one_line(err) == "delayform: interrupted; files being written were discarded, earlier outputs are intact"
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after["sim_operating.csv"] == before["sim_operating.csv"]
    assert _left_over(tmp_path) == []


def test_a_gif_interrupted_is_not_left_half_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from PIL import Image

    from delayform.simulation import simulate
    from delayform.topology import ring

    traj = simulate(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", model="double_integrator", duration=1.0, dt=0.05)

    def half_then_ctrl_c(self: object, fp: object, *args: object, **kwargs: object) -> None:
        Path(str(fp)).write_bytes(b"GIF89a")  # the file's first bytes reach the disk, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(Image.Image, "save", half_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        traj.save_gif(tmp_path / "run.gif", frames=3)
    assert list(tmp_path.iterdir()) == []


def test_staged_folder_replaces_the_previous_report_whole_and_keeps_foreign_files(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    with staged_folder(tmp_path) as build:
        for name in ("index.html", "a.png", "old_only.png"):
            (build / name).write_text("run 1")
        write_text(build / "summary.json", json.dumps({"files": ["index.html", "a.png", "old_only.png", "summary.json",
                                                                 "../escape", "notes.txt2"]}))  # fmt: skip
    with pytest.raises(KeyboardInterrupt):  # run 2 interrupted: run 1 stays whole
        with staged_folder(tmp_path) as build:
            (build / "index.html").write_text("run 2")
            raise KeyboardInterrupt
    assert (tmp_path / "index.html").read_text() == "run 1" and (tmp_path / "old_only.png").exists()
    with staged_folder(tmp_path) as build:  # run 3 completes: nothing of run 1 remains
        (build / "index.html").write_text("run 3")
        (build / "a.png").write_text("run 3")
        write_text(build / "summary.json", json.dumps({"files": ["index.html", "a.png", "summary.json"]}))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "index.html", "notes.txt", "summary.json"]
    assert (tmp_path / "index.html").read_text() == "run 3" and (tmp_path / "notes.txt").read_text() == "mine"


def test_staged_folder_it_made_is_gone_when_the_build_fails(tmp_path: Path) -> None:
    """A refused build leaves no folder it created (nested ones included), and never removes one it found."""
    with pytest.raises(ValueError):
        with staged_folder(tmp_path / "a" / "b") as build:
            (build / "index.html").write_text("half")
            raise ValueError("refused by the build")
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "kept").mkdir()
    with pytest.raises(ValueError):
        with staged_folder(tmp_path / "kept" / "new") as build:
            raise ValueError("refused by the build")
    assert [p.name for p in tmp_path.iterdir()] == ["kept"] and list((tmp_path / "kept").iterdir()) == []


def test_report_interrupted_leaves_the_older_report_intact_and_a_new_one_replaces_it_whole(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C while the new report draws its charts: the old index.html and charts stay, nothing new appears.

    The analyses are replaced by a stand-in that writes one chart (the real
    ones take minutes); the staging, the commit and write_report are real.
    """
    import delayform.report as report

    out = tmp_path / "report"
    out.mkdir()
    old = {"index.html": "old report", "chart.png": "old chart", "mine.txt": "not a report file",
           "summary.json": json.dumps({"files": ["index.html", "summary.json", "chart.png"]})}  # fmt: skip
    for name, text in old.items():
        (out / name).write_text(text)

    def interrupted(sc: object, directory: Path, progress: object = None) -> list[object]:
        (directory / "chart.png").write_text("new chart")
        raise KeyboardInterrupt

    monkeypatch.setattr(report, "scenario_sections", interrupted)
    code, _, err = cli(capsys, "report", "--out", str(out))
    assert code == 130 and "interrupted" in one_line(err)
    assert {p.name: p.read_text() for p in out.iterdir()} == old

    monkeypatch.setattr(report, "scenario_sections", lambda sc, directory, progress=None: [])
    code, stdout, err = cli(capsys, "report", "--out", str(out))
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "mine.txt", "summary.json"]
    assert "old report" not in (out / "index.html").read_text()
    assert f"Report: {out / 'index.html'}" in stdout


def test_every_file_the_package_writes_goes_through_atomic_path() -> None:
    """A static check, so a new writer cannot bypass the mechanism: raw writes only to a temporary name."""
    import re

    package = Path(delayform.__file__).parent
    writer = re.compile(r"(\.write_text|\.write_bytes|savez_compressed|np\.savez|savetxt|savefig|\.save)\((\w+)")
    opened = re.compile(r"open\([^)]*[\"'][wax]b?[\"']")
    offenders = []
    for path in package.rglob("*.py"):
        if path.name == "_files.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            for match in writer.finditer(line):
                receiver = line[: match.start()].rsplit(None, 1)[-1] if line[: match.start()].strip() else ""
                into_memory = match.group(1) == "savefig" and match.group(2) == "data"  # a BytesIO
                if match.group(2) != "tmp" and not receiver.endswith("tmp") and not into_memory:
                    offenders.append(f"{path.relative_to(package)}:{number}: {line.strip()}")
            # a child process's stderr is a stream written while it runs, in the fleet's own scratch
            # folder (removed after the run): it cannot be renamed into place, and nobody reads it half-written
            child_stream = path.name == "lifecycle.py" and 'open(err, "wb") as stderr' in line
            if opened.search(line) and "tmp" not in line and not child_stream:
                offenders.append(f"{path.relative_to(package)}:{number}: {line.strip()}")
    assert offenders == []
