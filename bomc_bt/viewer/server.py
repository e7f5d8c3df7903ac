"""The viewer's local web server: one static page, its state as server-sent events, the map PNG.

Standard library only (``http.server`` on a thread per connection). It binds 127.0.0.1
and nothing else: the page shows a building's map and contents, which is not for the
whole network; reach it from elsewhere through an SSH tunnel.

Routes:

* ``/`` and ``/static/<file>`` -- the page (``bomc_bt/viewer/static``).
* ``/events`` -- ``text/event-stream``. Each message is ``{"version", "full", "sections"}``
  with the sections that changed; its SSE id is ``<epoch>:<version>``. A browser's
  ``EventSource`` reconnects by itself and sends that id back as ``Last-Event-ID``, so a
  reconnecting page receives only what it missed, and everything when the server is not
  the one it was talking to. When the server closes (the mission, or ``bomc view``,
  ended) each stream sends ``event: end`` last, so the page says so instead of
  "reconnecting" (it still reconnects to a new mission on the port).
* ``/state.json`` -- the full state at once (scripts, debugging).
* ``/map.png`` -- the current occupancy map, grey, north up, one pixel per cell.
* ``/api/diff?a=N&b=M`` -- a finished site's changes between two sessions.
* ``/api/timeline?session=N`` -- a pass's recorded timeline, for replay (:mod:`.replay`).
* ``/api/change_model`` -- a finished site's change model per region (the heat map, :mod:`.heatmap`).
* ``POST /api/edit`` -- an operator's correction of a finished site (:mod:`.corrections`).
"""

from __future__ import annotations

import contextlib
import errno
import json
import mimetypes
import threading
from collections.abc import Callable
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from bomc_bt.errors import BomcError
from bomc_bt.viewer.corrections import CorrectionsApi, read_request
from bomc_bt.viewer.live import ViewerHook
from bomc_bt.viewer.replay import ReplayApi
from bomc_bt.viewer.site import SiteView, load_site
from bomc_bt.viewer.store import StateStore, ViewerParams

STATIC = Path(__file__).parent / "static"
HOST = "127.0.0.1"
DEFAULT_PORT = 8765
KEEPALIVE_S = 10.0  # wall seconds between SSE comments, so proxies and browsers keep the stream

Api = Callable[[dict[str, list[str]]], Any]


class Server:
    """Serves ``state`` on ``127.0.0.1:port`` (0: any free port) from a daemon thread."""

    def __init__(self, state: StateStore, port: int = DEFAULT_PORT, api: dict[str, Api] | None = None,
                 post_api: dict[str, Callable[[Any], Any]] | None = None):
        self.state = state
        self.api = dict(api or {})
        self.post_api = dict(post_api or {})  # route -> handler of the request's JSON body
        try:
            self.httpd = ThreadingHTTPServer((HOST, port), _handler(self))
        except OSError as exc:
            why = "is in use" if exc.errno == errno.EADDRINUSE else f"cannot be opened ({exc.strerror})"
            raise BomcError(f"port {port} {why}; choose another with --port", None, "--port") from None
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self._thread: threading.Thread | None = None
        self._streams = 0  # event streams open now
        self._streams_changed = threading.Condition()

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/"

    def start(self) -> Server:
        if self._thread is None:
            self._thread = threading.Thread(target=self.httpd.serve_forever, name="bomc-viewer", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving; open event streams say "end" (the page shows the mission ended, not a
        lost connection) and close, waited for up to a second before the process may exit."""
        self.state.close()
        with self._streams_changed:
            self._streams_changed.wait_for(lambda: self._streams == 0, timeout=1.0)
        if self._thread is not None:
            self.httpd.shutdown()
            self._thread.join(timeout=5.0)
            self._thread = None
        self.httpd.server_close()

    def count_stream(self, delta: int) -> None:
        """An event stream opened (+1) or ended (-1)."""
        with self._streams_changed:
            self._streams += delta
            self._streams_changed.notify_all()

    def __enter__(self) -> Server:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()


def serve_live(port: int = DEFAULT_PORT, params: ViewerParams | None = None
               ) -> tuple[Server, Callable[[Any], ViewerHook]]:
    """A started server for a running mission and the factory ``ctx -> on_tick hook`` for ``run_build``."""
    server = Server(StateStore(), port).start()
    server.state.update({"mode": "live"})
    return server, lambda ctx: ViewerHook(server, ctx, params)


def serve_site(site_dir: str | Path, port: int = DEFAULT_PORT, params: ViewerParams | None = None) -> Server:
    """A started server showing the finished site in ``site_dir`` (map, sessions, differences)."""
    view = SiteView(site_dir, params)
    state = StateStore()
    load_site(state, view)

    def diff(query: dict[str, list[str]]) -> Any:
        try:
            a, b = int(query["a"][0]), int(query["b"][0])
        except (KeyError, ValueError, IndexError):
            raise BomcError("give two session numbers: /api/diff?a=N&b=M", None, "a, b") from None
        return view.diff(a, b)

    from bomc_bt.viewer.heatmap import change_model_json

    corrections = CorrectionsApi(view, state)
    corrections.publish()
    api = {"/api/diff": diff, "/api/change_model": lambda query: change_model_json(site_dir),
           **ReplayApi(view).routes()}
    return Server(state, port, api=api, post_api=corrections.routes()).start()


def parse_event_id(text: str | None, epoch: str) -> int | None:
    """The version in a ``Last-Event-ID`` of this server's epoch; None means "send everything"."""
    if not text or ":" not in text:
        return None
    their_epoch, _, version = text.partition(":")
    if their_epoch != epoch or not version.isdigit():
        return None
    return int(version)


def _handler(server: Server) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        server_version = "bomc-viewer"

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base's signature
            pass  # the terminal belongs to the mission

        def do_GET(self) -> None:  # noqa: N802 - http.server's naming
            parts = urlsplit(self.path)
            route, query = parts.path, parse_qs(parts.query)
            try:
                if route == "/events":
                    self._events(query)
                elif route == "/state.json":
                    version, sections, _ = server.state.changes(None)
                    self._json({"version": version, "epoch": server.state.epoch, "sections": sections})
                elif route == "/map.png":
                    self._map()
                elif route in server.api:
                    self._api(server.api[route], query)
                elif route in ("/", "/index.html"):
                    self._file(STATIC / "index.html")
                elif route.startswith("/static/"):
                    self._static(route[len("/static/"):])
                else:
                    self.send_error(HTTPStatus.NOT_FOUND)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the page went away

        def do_POST(self) -> None:  # noqa: N802 - http.server's naming
            route = urlsplit(self.path).path
            if route not in server.post_api:
                self.send_error(HTTPStatus.NOT_FOUND)
                return
            handler = server.post_api[route]
            with contextlib.suppress(BrokenPipeError, ConnectionResetError):  # the page went away
                self._api(lambda _: handler(read_request(self.headers, self.rfile, server.port)), {})

        def _send(self, body: bytes, content_type: str, status: HTTPStatus = HTTPStatus.OK) -> None:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def _json(self, payload: Any, status: HTTPStatus = HTTPStatus.OK) -> None:
            self._send(json.dumps(payload).encode(), "application/json", status)

        def _api(self, api: Api, query: dict[str, list[str]]) -> None:
            try:
                self._json(api(query))
            except BomcError as exc:
                self._json({"error": str(exc)}, HTTPStatus.BAD_REQUEST)

        def _map(self) -> None:
            png = server.state.map_png()
            if png is None:
                self.send_error(HTTPStatus.NOT_FOUND, "no map yet")
            else:
                self._send(png, "image/png")

        def _static(self, name: str) -> None:
            path = (STATIC / name).resolve()
            if STATIC.resolve() not in path.parents or not path.is_file():
                self.send_error(HTTPStatus.NOT_FOUND)
                return
            self._file(path)

        def _file(self, path: Path) -> None:
            kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
            if kind.startswith("text/") or kind.endswith("javascript"):
                kind += "; charset=utf-8"
            self._send(path.read_bytes(), kind)

        def _events(self, query: dict[str, list[str]]) -> None:
            state = server.state
            last = self.headers.get("Last-Event-ID") or (query.get("last") or [None])[0]
            since = parse_event_id(last, state.epoch)
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(b"retry: 1000\n\n")
            self.wfile.flush()
            server.count_stream(+1)
            try:
                self._stream(state, since)
            finally:
                server.count_stream(-1)

        def _stream(self, state: StateStore, since: int | None) -> None:
            sent_any = False
            while not state.closed:
                version, sections, full = state.changes(since)
                if sections or not sent_any:
                    message = json.dumps({"version": version, "full": full, "sections": sections})
                    self.wfile.write(f"id: {state.epoch}:{version}\ndata: {message}\n\n".encode())
                    self.wfile.flush()
                    since, sent_any = version, True
                if not state.wait(since, KEEPALIVE_S) and not state.closed:
                    self.wfile.write(b": keepalive\n\n")
                    self.wfile.flush()
            self.wfile.write(b"event: end\ndata: {}\n\n")
            self.wfile.flush()

    return Handler
