"""Operator feed: a small HTTP server over an :class:`~sarmission.alerts.store.AlertStore`.

Routes (all JSON errors are ``{"error": ...}``):

- ``GET /``: the operator page (self-contained HTML, live over ``/events``).
- ``GET /events``: Server-Sent Events. On connect, every stored alert as an ``alert`` event,
  then ``hello``; afterwards ``alert`` for each new alert and ``update`` for acknowledgements,
  deliveries and positions attached later. Data is the alert's JSON document; ``id`` is the
  store's event sequence number, so a reconnecting browser (``Last-Event-ID``) gets only what it
  missed.
- ``GET /api/alerts[?since=T]``: JSON list of alerts (``since``: lock time, POSIX seconds).
- ``GET /api/alerts/<id>``: one alert.
- ``POST /api/alerts/<id>/ack``: acknowledge; body ``{"by": "name"}``, ``Content-Type:
  application/json`` required (a cross-site form cannot send it). Returns the alert.
- ``GET /alerts.jsonl[?since=T][&follow=1]``: one alert per line; with ``follow=1`` the
  response stays open and each new alert is written as it is stored, and again when a position
  is attached to an alert stored without one (same ``alert_id``: the later line supersedes).
- ``GET /alerts.geojson``, ``GET /alerts.kml``: exports (see :mod:`sarmission.alerts.export`).
- ``GET /thumb/<id>.jpg``: the alert's thumbnail.
- ``GET /healthz``: ``{"ok": true, "alerts": n, "last_event": seq}``.
"""

from __future__ import annotations

import json
import logging
import re
import select
import socket
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

from sarmission.alerts.export import alerts_geojson_bytes, alerts_kml
from sarmission.alerts.model import Alert
from sarmission.alerts.page import PAGE_HTML
from sarmission.alerts.store import AlertEvent, AlertStore
from sarmission.errors import SarmissionError

log = logging.getLogger(__name__)

_ID = r"([0-9A-Za-z_.-]{1,64})"
_ALERT = re.compile(rf"^/api/alerts/{_ID}$")
_ACK = re.compile(rf"^/api/alerts/{_ID}/ack$")
_THUMB = re.compile(rf"^/thumb/{_ID}\.jpg$")
_PAGE_CSP = (
    "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
    "img-src 'self'; connect-src 'self'; base-uri 'none'; form-action 'none'"
)
_GET_PATHS = frozenset(
    ("/", "/events", "/api/alerts", "/alerts.jsonl", "/alerts.geojson", "/alerts.kml", "/healthz")
)
_MAX_BODY = 4096
#: How often a waiting stream checks for shutdown and client disconnects (seconds).
_TICK_S = 0.5
#: SSE comment sent when idle, so proxies keep the stream open.
_KEEPALIVE_S = 15.0


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], feed: FeedServer) -> None:
        self.feed = feed
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        super().__init__(address, _Handler)

    def handle_error(self, request: Any, client_address: Any) -> None:
        log.exception("feed: error serving %s", client_address)


class FeedServer:
    """Serves ``store`` over HTTP on ``host:port`` (localhost by default; ``port=0`` picks a
    free port) from a background thread between :meth:`start` and :meth:`stop`."""

    def __init__(self, store: AlertStore, host: str = "127.0.0.1", port: int = 8765) -> None:
        self.store = store
        self.host = host
        self._requested_port = port
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None
        self.stopping = threading.Event()

    @property
    def port(self) -> int:
        """The bound port (after :meth:`start`)."""
        if self._server is None:
            raise RuntimeError("feed server not started")
        return self._server.server_address[1]

    @property
    def url(self) -> str:
        """Base URL, e.g. ``http://127.0.0.1:8765``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    def start(self) -> FeedServer:
        """Bind and serve in a daemon thread; returns self. Raises SarmissionError if the
        address cannot be bound."""
        if self._server is not None:
            raise RuntimeError("feed server already started")
        self.stopping.clear()
        try:
            self._server = _Server((self.host, self._requested_port), self)
        except OSError as exc:
            raise SarmissionError(
                f"cannot serve the alert feed on {self.host}:{self._requested_port}: {exc}"
            ) from exc
        self._thread = threading.Thread(
            target=self._server.serve_forever,
            kwargs={"poll_interval": 0.2},
            name="sarmission-feed",
            daemon=True,
        )
        self._thread.start()
        log.info("alert feed on %s", self.url)
        return self

    def stop(self) -> None:
        """Stop serving; open streams end within about half a second."""
        if self._server is None:
            return
        self.stopping.set()
        self._server.shutdown()
        self._server.server_close()
        if self._thread is not None:
            self._thread.join()
        self._server = None
        self._thread = None

    def __enter__(self) -> FeedServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    server_version = "sarmission-feed"

    # ------------------------------------------------------------------ plumbing

    def handle(self) -> None:
        try:
            super().handle()
        except (ConnectionError, TimeoutError):
            log.debug("feed: client %s went away", self.client_address)

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("feed %s: " + format, self.client_address[0], *args)

    @property
    def store(self) -> AlertStore:
        return self.server.feed.store

    def _send(
        self,
        status: int,
        body: bytes,
        content_type: str,
        headers: dict[str, str] | None = None,
    ) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.end_headers()
        self.wfile.write(body)

    def _json(self, status: int, value: Any) -> None:
        self._send(status, json.dumps(value).encode(), "application/json")

    def _error(self, status: HTTPStatus, message: str) -> None:
        self._json(status, {"error": message, "status": int(status), "path": self.path})

    def _start_stream(self, content_type: str) -> None:
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", content_type)
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("X-Accel-Buffering", "no")
        self.end_headers()
        self.wfile.flush()

    def _client_gone(self) -> bool:
        """True when the client has closed its end (readable socket with nothing to read)."""
        try:
            readable, _, _ = select.select([self.connection], [], [], 0)
            return bool(readable) and self.connection.recv(1, socket.MSG_PEEK) == b""
        except OSError:
            return True

    def _streaming(self) -> bool:
        return not (self.server.feed.stopping.is_set() or self.store.closed or self._client_gone())

    # ------------------------------------------------------------------ routing

    def do_GET(self) -> None:
        try:
            self._route_get()
        except _BadRequest as exc:
            self._error(HTTPStatus.BAD_REQUEST, str(exc))

    def _route_get(self) -> None:
        url = urlsplit(self.path)
        query = parse_qs(url.query)
        path = url.path
        if path == "/":
            self._send(
                HTTPStatus.OK,
                PAGE_HTML.encode(),
                "text/html; charset=utf-8",
                {"Content-Security-Policy": _PAGE_CSP},
            )
        elif path == "/events":
            self._events()
        elif path == "/api/alerts":
            alerts = self.store.list(_since(query))
            self._json(HTTPStatus.OK, [a.to_json_dict() for a in alerts])
        elif m := _ALERT.match(path):
            alert = self.store.get(m.group(1))
            if alert is None:
                self._error(HTTPStatus.NOT_FOUND, f"no alert {m.group(1)}")
            else:
                self._json(HTTPStatus.OK, alert.to_json_dict())
        elif path == "/alerts.jsonl":
            follow = query.get("follow", ["0"])[-1].lower() in ("1", "true", "yes")
            self._jsonl(_since(query), follow)
        elif path == "/alerts.geojson":
            self._send(
                HTTPStatus.OK,
                alerts_geojson_bytes(self.store.list()),
                "application/geo+json",
                {"Content-Disposition": 'inline; filename="alerts.geojson"'},
            )
        elif path == "/alerts.kml":
            self._send(
                HTTPStatus.OK,
                alerts_kml(self.store.list()),
                "application/vnd.google-earth.kml+xml",
                {"Content-Disposition": 'attachment; filename="alerts.kml"'},
            )
        elif m := _THUMB.match(path):
            alert = self.store.get(m.group(1))
            if alert is None or not alert.thumbnail:
                self._error(HTTPStatus.NOT_FOUND, f"no thumbnail for alert {m.group(1)}")
            else:
                self._send(HTTPStatus.OK, alert.thumbnail, "image/jpeg")
        elif path == "/healthz":
            self._json(
                HTTPStatus.OK,
                {
                    "ok": True,
                    "alerts": self.store.count(),
                    "last_event": self.store.last_event_seq(),
                    "time": time.time(),
                },
            )
        elif _ACK.match(path):
            self._error(HTTPStatus.METHOD_NOT_ALLOWED, "use POST to acknowledge")
        else:
            self._error(HTTPStatus.NOT_FOUND, "not found")

    def do_POST(self) -> None:
        path = urlsplit(self.path).path
        m = _ACK.match(path)
        if m is None:
            if _is_get_route(path):
                self._error(HTTPStatus.METHOD_NOT_ALLOWED, "use GET")
            else:
                self._error(HTTPStatus.NOT_FOUND, "not found")
            return
        if self.headers.get_content_type() != "application/json":
            self._error(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "send Content-Type: application/json")
            return
        try:
            length = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            length = -1
        if not 0 <= length <= _MAX_BODY:
            self._error(HTTPStatus.BAD_REQUEST, f"body must be 0..{_MAX_BODY} bytes")
            return
        try:
            body = json.loads(self.rfile.read(length) or b"{}")
            by = str(body.get("by") or "operator").strip()[:64] or "operator"
        except (ValueError, AttributeError):
            self._error(HTTPStatus.BAD_REQUEST, 'body must be a JSON object like {"by": "name"}')
            return
        try:
            alert = self.store.acknowledge(m.group(1), by)
        except KeyError:
            self._error(HTTPStatus.NOT_FOUND, f"no alert {m.group(1)}")
            return
        log.info("alert %s acknowledged by %s", alert.alert_id, by)
        self._json(HTTPStatus.OK, alert.to_json_dict())

    # ------------------------------------------------------------------ streams

    def _events(self) -> None:
        last = self.headers.get("Last-Event-ID", "")
        resume = int(last) if last.isdigit() and int(last) <= self.store.last_event_seq() else None
        with self.store.subscribe(after=resume) as sub:
            self._start_stream("text/event-stream; charset=utf-8")
            self.wfile.write(b"retry: 1000\n\n")
            if resume is None:
                for alert in self.store.list():
                    self._sse("alert", alert, sub.cursor)
            self.wfile.write(b"event: hello\ndata: {}\n\n")
            self.wfile.flush()
            idle_since = time.monotonic()
            while self._streaming():
                events = sub.get(timeout=_TICK_S)
                for event in events:
                    self._sse("alert" if event.kind == "new" else "update", event.alert, event.seq)
                if events:
                    idle_since = time.monotonic()
                elif time.monotonic() - idle_since > _KEEPALIVE_S:
                    self.wfile.write(b": keepalive\n\n")
                    idle_since = time.monotonic()
                self.wfile.flush()

    def _sse(self, name: str, alert: Alert, seq: int) -> None:
        data = json.dumps(alert.to_json_dict())
        self.wfile.write(f"event: {name}\nid: {seq}\ndata: {data}\n\n".encode())

    def _jsonl(self, since: float | None, follow: bool) -> None:
        with self.store.subscribe() as sub:
            self._start_stream("application/x-ndjson; charset=utf-8")
            sent: set[str] = set()
            for alert in self.store.list(since):
                self._line(alert)
                sent.add(alert.alert_id)
            self.wfile.flush()
            while follow and self._streaming():
                new = [e for e in sub.get(timeout=_TICK_S) if _is_line(e, sent, since)]
                for event in new:
                    self._line(event.alert)
                    sent.add(event.alert.alert_id)
                if new:
                    self.wfile.flush()

    def _line(self, alert: Alert) -> None:
        self.wfile.write(json.dumps(alert.to_json_dict()).encode() + b"\n")


def _is_line(event: AlertEvent, sent: set[str], since: float | None) -> bool:
    """Whether a followed JSON-lines stream writes ``event``: a new alert not yet written, or
    an alert's position found after it was stored."""
    return (
        (event.kind == "position" or event.kind == "new" and event.alert.alert_id not in sent)
        and (since is None or event.alert.lock_time >= since)
    )


class _BadRequest(Exception):
    """A malformed query; answered with 400 and the message."""


def _since(query: dict[str, list[str]]) -> float | None:
    """The ``since`` query parameter (POSIX seconds), None when absent."""
    if "since" not in query:
        return None
    try:
        return float(query["since"][-1])
    except ValueError:
        raise _BadRequest("since must be POSIX seconds") from None


def _is_get_route(path: str) -> bool:
    return path in _GET_PATHS or bool(_ALERT.match(path) or _THUMB.match(path))
