"""The explorer's web server: a Starlette app on uvicorn, bound to 127.0.0.1 only.

Endpoints (all ``GET``; every number is checked by :mod:`delayform.app.params`)::

    /                          the page (static/index.html)
    /static/<fixed name>       the page's script and style, and plotly.min.js from the
                               installed ``plotly`` package (nothing from the internet)
    /api/scenario              the scenario, the limits, the defaults of every parameter
    /api/chart                 P, D, tau1_max, tau2_max, grid -> exact curves and NU shading
    /api/point                 tau1, tau2 [, P, D] -> stable, unstable_count, dominant_root [re, im]
    /api/guarantee             tau1, tau2 [, P, D] -> jitter_margin (s, certified)
    /api/jitter_map            P, D, tau1_max, tau2_max, grid -> the certified margin on the chart's window
    /api/guarantees            as /api/simulate -> the certificates for its network beside the run's status
    /api/roots                 tau1, tau2 [, P, D] -> the roots of every factor near the imaginary axis
    /api/region                tau1, tau2 [, P, D] -> the eigenvalue plane: boundary curve L(j omega),
                               NU(lam) on a grid, the team's eigenvalues of C with their NU
    /api/simulate              tau1, tau2 [, P, D, duration, frames, limits | network, loss, jitter]
                               -> animation frames
    /download/scenario.toml    the scenario at the current settings (also saved in the output folder)
    /download/figures.zip      chart and robot figures, point.json, scenario.toml (also saved)

Safety
------
* :func:`serve` and :func:`start` bind to 127.0.0.1 and refuse any other host
  before opening a socket. The ``Host`` header must name the loopback too
  (against DNS rebinding: a web page elsewhere cannot reach the explorer by name).
* A malformed request (unknown, repeated, missing, non-numeric or out-of-bounds
  parameter; work beyond :class:`~delayform.app.params.ExplorerLimits`) gets
  HTTP 400 and one line of JSON ``{"error": "..."}``; a computation that fails
  gets 500 and one line; never a traceback.
* Files are read only from a fixed list (the package's static files and
  plotly's bundle; no path comes from a request) and written only into the
  output folder (:meth:`Explorer._write`).
* Computations run in worker threads, at most two at a time (the machine's cores).
"""

from __future__ import annotations

import importlib.util
import ipaddress
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from delayform.app.explorer import Explorer
from delayform.app.jitter_layer import JitterLayer
from delayform.app.side_by_side import SideBySide
from delayform.app.params import Param, parse_query
from delayform.app.robot_controls import RobotControls
from delayform._extras import require_extra
from delayform.errors import DelayformError, InputError

__all__ = ["LOOPBACK", "create_app", "check_host", "bind", "start", "serve", "RunningExplorer"]

#: the only address the explorer listens on
LOOPBACK = "127.0.0.1"
STATIC = Path(__file__).parent / "static"
#: computations at once (the machine has two cores; a third click waits)
_WORKERS = 2
_SECURITY_HEADERS = {
    # everything the page loads comes from this server; Plotly sets inline styles
    "Content-Security-Policy": "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}


def plotly_bundle() -> Path:
    """The ``plotly.min.js`` shipped inside the installed ``plotly`` Python package.

    Found without importing plotly (only its file is used).

    Raises
    ------
    MissingExtraError
        When the ``plotly`` package is not installed (the ``explore`` extra).
    InputError
        When the installed plotly has no bundle.
    """
    require_extra("explore")
    spec = importlib.util.find_spec("plotly")
    folders = list(spec.submodule_search_locations or []) if spec is not None else []
    path = Path(folders[0]) / "package_data" / "plotly.min.js" if folders else None
    if path is None or not path.is_file():
        raise InputError("the installed plotly package has no plotly.min.js")
    return path


def check_host(host: str) -> str:
    """Return the loopback address for ``host``, or raise for anything else.

    Parameters
    ----------
    host
        ``127.0.0.1`` or ``localhost``.

    Raises
    ------
    InputError
        One line, for any other host (another interface, ``0.0.0.0``, a name).

    Examples
    --------
    >>> check_host("localhost")
    '127.0.0.1'
    """
    if host in (LOOPBACK, "localhost"):
        return LOOPBACK
    try:
        ipaddress.ip_address(host)
        kind = "address"
    except ValueError:
        kind = "host"
    raise InputError(f"the explorer listens on {LOOPBACK} only, not on {kind} {host!r}")


def bind(host: str = LOOPBACK, port: int = 0) -> socket.socket:
    """A listening TCP socket on the loopback (port 0: a free port).

    Parameters
    ----------
    host
        Must be the loopback (:func:`check_host`).
    port
        0..65535.

    Raises
    ------
    InputError
        For another host, a bad port, or a port already in use.
    """
    address = check_host(host)
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InputError(f"port must be an integer in 0..65535, got {port!r}")
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((address, port))
    except OSError as exc:
        sock.close()
        raise InputError(f"cannot listen on {address}:{port}: {exc.strerror or exc}") from None
    sock.listen(64)
    return sock


# ================================================================ the app
def create_app(explorer: Explorer) -> Any:
    """The Starlette application serving one :class:`Explorer`.

    Parameters
    ----------
    explorer
        The computations behind the page.

    Raises
    ------
    MissingExtraError
        Without the ``explore`` extra (Starlette, uvicorn, Plotly, Clarabel).
    """
    require_extra("explore")
    import anyio
    from starlette.applications import Starlette
    from starlette.exceptions import HTTPException
    from starlette.middleware import Middleware
    from starlette.middleware.trustedhost import TrustedHostMiddleware
    from starlette.requests import Request
    from starlette.responses import FileResponse, JSONResponse, Response
    from starlette.routing import Route

    limiter = anyio.CapacityLimiter(_WORKERS)
    robot = RobotControls(explorer)
    assets = {
        "explorer.js": (STATIC / "explorer.js", "text/javascript"),
        "jitter_layer.js": (STATIC / "jitter_layer.js", "text/javascript"),
        "side_by_side.js": (STATIC / "side_by_side.js", "text/javascript"),
        "explorer.css": (STATIC / "explorer.css", "text/css"),
        "robot_controls.js": (STATIC / "robot_controls.js", "text/javascript"),
        "plotly.min.js": (plotly_bundle(), "text/javascript"),
    }

    def error(status: int, message: str) -> JSONResponse:
        return JSONResponse({"error": message.replace("\n", " ")}, status_code=status, headers=_SECURITY_HEADERS)

    async def compute(request: Request, spec: tuple[Param, ...], work: Callable[..., Any]) -> Any:
        args = parse_query(request.query_params.multi_items(), spec)
        return await anyio.to_thread.run_sync(lambda: work(**args), limiter=limiter)

    def json_endpoint(spec: Callable[[], tuple[Param, ...]], work: Callable[..., Any]) -> Callable[..., Any]:
        async def endpoint(request: Request) -> Response:
            result = await compute(request, spec(), work)
            return JSONResponse(result.as_json(), headers=_SECURITY_HEADERS)

        return endpoint

    def file_endpoint(spec: Callable[[], tuple[Param, ...]], work: Callable[..., Path], media: str) -> Callable[..., Any]:
        async def endpoint(request: Request) -> Response:
            path = await compute(request, spec(), work)
            headers = {**_SECURITY_HEADERS, "Content-Disposition": f'attachment; filename="{path.name}"'}
            return Response(path.read_bytes(), media_type=media, headers=headers)

        return endpoint

    async def page(request: Request) -> Response:
        parse_query(request.query_params.multi_items(), ())
        return FileResponse(STATIC / "index.html", media_type="text/html", headers=_SECURITY_HEADERS)

    async def static(request: Request) -> Response:
        parse_query(request.query_params.multi_items(), ())
        asset = assets.get(request.path_params["name"])
        if asset is None:
            return error(404, f"no such file: {request.url.path}")
        return FileResponse(asset[0], media_type=asset[1], headers=_SECURITY_HEADERS)

    async def no_icon(request: Request) -> Response:
        return Response(status_code=204, headers=_SECURITY_HEADERS)

    async def scenario(request: Request) -> Response:
        parse_query(request.query_params.multi_items(), ())
        s = explorer.scenario
        defaults = {p.name: p.default for spec in (explorer.chart_params(), explorer.animation_params())
                    for p in spec}  # fmt: skip
        body = {
            "scenario": s.summary(),
            "points": [{"label": k, "tau1": a, "tau2": b} for k, a, b in s.chart.points],
            "defaults": defaults | {"tau1": s.tau1, "tau2": s.tau2},
            "limits": explorer.limits.__dict__,
            # the longest delay per kind of request at the scenario's gains (the roots' from the finder's own rule)
            "delay_limits": explorer.delay_limits(s.P, s.D),
            "toggles": explorer.toggles,
            "robot_controls": robot.describe(),  # actuation delay, safety filter, slot assignment
            "out_dir": str(explorer.out_dir),
        }
        return JSONResponse(body, headers=_SECURITY_HEADERS)

    async def on_input_error(request: Request, exc: Exception) -> Response:
        return error(400, str(exc))

    async def on_failure(request: Request, exc: Exception) -> Response:
        return error(500, f"computation failed: {exc}")

    async def on_http(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, HTTPException)
        return error(exc.status_code, str(exc.detail))

    async def on_crash(request: Request, exc: Exception) -> Response:
        return error(500, f"internal error: {type(exc).__name__}")

    routes = [
        Route("/", page),
        Route("/static/{name}", static),
        Route("/favicon.ico", no_icon),
        Route("/api/scenario", scenario),
        # every answer at the page's robot controls (delayform.app.robot_controls)
        Route("/api/chart", json_endpoint(*robot.route("chart_params", "chart"))),
        Route("/api/point", json_endpoint(*robot.route("point_params", "point"))),
        Route("/api/roots", json_endpoint(*robot.route("point_params", "roots"))),
        Route("/api/guarantee", json_endpoint(*robot.route("point_params", "guarantee"))),
        Route("/api/jitter_map", json_endpoint(*robot.route("params", "compute", on=JitterLayer))),
        Route("/api/guarantees", json_endpoint(*robot.route("params", "compute", run=True, on=SideBySide))),
        Route("/api/region", json_endpoint(*robot.route("point_params", "region"))),
        Route("/api/simulate", json_endpoint(*robot.route("animation_params", "animation", run=True))),
        Route("/download/scenario.toml",
              file_endpoint(*robot.route("download_params", "scenario_file", run=True), "application/toml")),
        Route("/download/figures.zip",
              file_endpoint(*robot.route("download_params", "figures_file", run=True), "application/zip")),
    ]
    hosts = [LOOPBACK, "localhost"]
    return Starlette(
        routes=routes,
        middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=hosts)],
        exception_handlers={
            InputError: on_input_error, DelayformError: on_failure,
            HTTPException: on_http, Exception: on_crash,
        },
    )  # fmt: skip


# ================================================================ running it
@dataclass
class RunningExplorer:
    """An explorer serving in a background thread (tests, benchmarks, notebooks).

    Attributes
    ----------
    url
        ``http://127.0.0.1:<port>/``.
    port
        The port it listens on.
    """

    url: str
    port: int
    _server: Any
    _thread: threading.Thread

    def stop(self) -> None:
        """Stop the server and wait for its thread."""
        self._server.should_exit = True
        self._thread.join(timeout=10)

    def __enter__(self) -> RunningExplorer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _server(explorer: Explorer) -> Any:
    import uvicorn

    config = uvicorn.Config(
        create_app(explorer), log_level="warning", access_log=False, lifespan="off", server_header=False
    )
    return uvicorn.Server(config)


def start(explorer: Explorer, *, host: str = LOOPBACK, port: int = 0) -> RunningExplorer:
    """Serve ``explorer`` on the loopback in a background thread.

    Parameters
    ----------
    explorer
        The computations behind the page.
    host
        Must be the loopback (:func:`check_host`).
    port
        0 for a free port.

    Returns
    -------
    RunningExplorer
        Its ``url``; ``stop()`` it (or use it as a context manager).

    Raises
    ------
    MissingExtraError
        Without the ``explore`` extra (Starlette, uvicorn, Plotly, Clarabel), before any port is taken.
    """
    require_extra("explore")
    sock = bind(host, port)
    server = _server(explorer)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True, name="delayform-explorer")
    thread.start()
    deadline = time.monotonic() + 30.0
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise DelayformError("the explorer's server did not start")
        time.sleep(0.02)
    real = sock.getsockname()[1]
    return RunningExplorer(f"http://{LOOPBACK}:{real}/", real, server, thread)


def serve(explorer: Explorer, *, host: str = LOOPBACK, port: int = 0,
          on_ready: Callable[[str], None] | None = None) -> None:  # fmt: skip
    """Serve ``explorer`` on the loopback until interrupted (Ctrl-C).

    Parameters
    ----------
    explorer
        The computations behind the page.
    host
        Must be the loopback (:func:`check_host`).
    port
        0 for a free port.
    on_ready
        Called with the page's URL once the server listens (e.g. to open a browser).

    Raises
    ------
    MissingExtraError
        Without the ``explore`` extra (Starlette, uvicorn, Plotly, Clarabel), before any port is taken.
    """
    require_extra("explore")
    sock = bind(host, port)
    url = f"http://{LOOPBACK}:{sock.getsockname()[1]}/"
    server = _server(explorer)
    if on_ready is not None:
        def notify() -> None:
            while not server.started and not server.should_exit:
                time.sleep(0.05)
            if server.started:
                on_ready(url)

        threading.Thread(target=notify, daemon=True).start()
    server.run(sockets=[sock])
