"""The HTTP side of the headset server's port (no rclpy): the browser client page and its files,
the WebSocket upgrade's checks (Host a loopback name unless a token is needed, the token in the
page URL, same-origin WebSocket), and the security headers of every answer."""
from __future__ import annotations

import collections
import hmac
import ipaddress
from importlib import resources
from typing import Callable
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.server import ServerConnection
from websockets.datastructures import Headers
from websockets.http11 import Request, Response

WS_PATH = "/ws"
STATIC_FILES = {"/": ("index.html", "text/html; charset=utf-8"),
                "/index.html": ("index.html", "text/html; charset=utf-8"),
                "/client.js": ("client.js", "text/javascript; charset=utf-8"),
                "/levels_renderer.js": ("levels_renderer.js", "text/javascript; charset=utf-8"),
                "/levels_kernels.wasm": ("levels_kernels.wasm", "application/wasm"),
                "/audio_cues.js": ("audio_cues.js", "text/javascript; charset=utf-8"),
                "/gaze.js": ("gaze.js", "text/javascript; charset=utf-8"),
                "/style.css": ("style.css", "text/css; charset=utf-8")}
LOOPBACK_NAMES = {"localhost", "127.0.0.1", "::1"}
CSP = ("default-src 'self'; connect-src 'self' ws: wss:; img-src 'self' blob: data:; "
       "style-src 'self'; script-src 'self' 'wasm-unsafe-eval'")     # WebAssembly: the levels kernels


def is_loopback(host: str) -> bool:
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def load_client_files() -> dict[str, bytes]:
    root = resources.files("raspv_hmd") / "client"
    return {name: (root / name).read_bytes() for name, _ in set(STATIC_FILES.values())}


class HttpPages:
    """Answers the port's HTTP requests (``process_request`` of the WebSocket server); None lets
    a WebSocket upgrade of :data:`WS_PATH` through. ``rejected`` counts refusals by reason."""

    def __init__(self, token: str, port: Callable[[], int], rejected: collections.Counter[str]) -> None:
        self.token, self.port, self.rejected = token, port, rejected
        self.files = load_client_files()

    def host_allowed(self, request: Request) -> bool:
        if self.token:
            return True
        host = urlsplit("//" + request.headers.get("Host", "")).hostname or ""
        return is_loopback(host)

    def process_request(self, connection: ServerConnection, request: Request) -> Response | None:
        url = urlsplit(request.path)
        if not self.host_allowed(request):
            return _response(403, "This bridge listens on loopback only; open it as http://127.0.0.1:"
                                  f"{self.port()}/ (Host {request.headers.get('Host')!r} refused).")
        if url.path == WS_PATH:
            origin = request.headers.get("Origin")
            if origin is not None and urlsplit(origin).netloc != request.headers.get("Host"):
                self.rejected["origin"] += 1
                return _response(403, f"WebSocket from another origin ({origin}) refused")
            return None
        if url.path == "/favicon.ico":
            return _response(204, b"")
        if url.path not in STATIC_FILES:
            return _response(404, f"{url.path} not found; the client page is at /")
        name, content_type = STATIC_FILES[url.path]
        if name == "index.html" and self.token:
            given = parse_qs(url.query).get("token", [""])[0]
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return _response(403, "This bridge needs its token: open the URL printed at its start-up "
                                      "(…/?token=…).")
        return _response(200, self.files[name], content_type)


def _response(status: int, body: str | bytes, content_type: str = "text/plain; charset=utf-8") -> Response:
    data = body.encode() if isinstance(body, str) else body
    reason = {200: "OK", 204: "No Content", 403: "Forbidden", 404: "Not Found"}.get(status, "")
    headers = Headers([("Content-Type", content_type), ("Content-Length", str(len(data))),
                       ("Cache-Control", "no-store"), ("X-Content-Type-Options", "nosniff"),
                       ("Content-Security-Policy", CSP), ("Connection", "close")])
    return Response(status, reason, headers, data)
