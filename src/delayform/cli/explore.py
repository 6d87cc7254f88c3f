"""The explore command: the browser explorer of :mod:`delayform.app` for one scenario."""

from __future__ import annotations

from pathlib import Path

import click

from delayform.cli._common import OutDir, _out_dir, _safe_name, _scenario, cli

#: the explorer's default port (any free one with --port 0)
DEFAULT_PORT = 8765


@cli.command("explore")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--port", type=click.IntRange(0, 65535), default=DEFAULT_PORT, show_default=True,
              help="Port on 127.0.0.1; 0 picks a free one.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Only 127.0.0.1 (or localhost) is accepted: the explorer is for this machine only.")
@click.option("--no-browser", is_flag=True, help="Do not open a browser; just print the address.")
@click.option("--out", type=OutDir(),
              help="Folder for downloads, the only place it writes [default: out/<scenario name>/explore].")
def explore_command(scenario: Path | None, port: int, host: str, no_browser: bool, out: Path | None) -> None:
    """Open a local web page to explore the scenario's team (the paper's by default).

    Click the exact stability chart to see whether a delay pair is stable,
    its dominant root and the roots near the imaginary axis, and the robots
    moving there; change P, D and the chart window to redraw it; download
    the scenario as TOML and the figures. Listens on 127.0.0.1 only; stop
    it with Ctrl-C.
    """
    import webbrowser

    from delayform._extras import require_extra
    from delayform.app import Explorer, check_host, serve

    require_extra("explore")  # a core install has no web server: say which extra, before any work
    check_host(host)  # refuse before reading anything
    sc = _scenario(scenario, topology_name=None, n=None, P=None, D=None, tau1=None, tau2=None)
    # proven writable before the page is served (a download must not be the first to find out);
    # the scenario's name becomes one harmless path component, as for every other command
    folder = out if out is not None else Path("out") / _safe_name(sc.name) / "explore"
    explorer = Explorer(sc, out_dir=folder)  # a scenario it cannot explore is refused before anything is written
    _out_dir(folder, sc)

    def ready(url: str) -> None:
        click.echo(f"delayform explorer: {url} (Ctrl-C stops it); downloads go to {explorer.out_dir}")
        if not no_browser:
            webbrowser.open(url)

    serve(explorer, host=host, port=port, on_ready=ready)
