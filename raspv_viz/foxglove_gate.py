"""A token check in front of the Foxglove server when it listens beyond loopback (no rclpy).

foxglove-sdk's server has no authentication, so off-loopback the `foxglove` node runs it on an
ephemeral loopback port and puts this gate on the public address: a WebSocket request whose URL
carries the right ``?token=…`` (compared in constant time) is relayed frame by frame to the SDK
server with the subprotocol the client asked for; anything else gets HTTP 403 and never reaches
it. A client that does not offer the subprotocol the SDK speaks (``foxglove.sdk.v1``; an older
Foxglove app offers only ``foxglove.websocket.v1``) gets HTTP 400 saying so. In the Foxglove app: Open connection → Foxglove WebSocket → ``ws://HOST:PORT/?token=TOKEN``.
"""
from __future__ import annotations

import asyncio
import hmac
import threading
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.client import connect
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from raspv_hmd.http_pages import is_loopback

__all__ = ["TokenGate", "is_loopback", "unsupported_subprotocol"]
MAX_MESSAGE = 64 * 1024 * 1024      # bytes: a client's largest frame to the server (parameter sets, not images)


class TokenGate:
    """Relays authorised WebSocket connections from ``host:port`` to ``127.0.0.1:upstream_port``."""

    def __init__(self, host: str, port: int, token: str, upstream_port: int, subprotocols: tuple[str, ...]) -> None:
        if not token:
            raise ValueError("a gate needs a token")
        self.host, self.port, self.token, self.upstream_port = host, port, token, upstream_port
        self.subprotocols = subprotocols
        self.refused = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None

    def start(self) -> int:
        """Listen (in a thread of its own); returns the port."""
        self._thread = threading.Thread(target=self._run, name="foxglove-gate", daemon=True)
        self._thread.start()
        self._ready.wait(10.0)
        if self._error is not None:
            raise OSError(f"cannot listen on {self.host}:{self.port}: {self._error}")
        return self.port

    def stop(self) -> None:
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(5.0)

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as exc:  # reported by start()
            self._error = exc
            self._ready.set()

    async def _serve(self) -> None:
        self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
        async with serve(self._relay, self.host, self.port, subprotocols=list(self.subprotocols),
                         process_request=self._check, max_size=MAX_MESSAGE, compression=None) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._ready.set()
            await self._stop.wait()

    def _check(self, connection: ServerConnection, request: Request) -> Response | None:
        given = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
        if not hmac.compare_digest(given.encode(), self.token.encode()):
            self.refused += 1
            return connection.respond(403, "This Foxglove server needs its token: ws://HOST:PORT/?token=... as "
                                           "printed at its start-up.\n")
        offered = [p.strip() for p in ",".join(request.headers.get_all("Sec-WebSocket-Protocol")).split(",") if p.strip()]
        if self.subprotocols[0] not in offered:
            self.refused += 1
            return connection.respond(400, unsupported_subprotocol(offered) + "\n")
        return None

    async def _relay(self, client: ServerConnection) -> None:
        subprotocols = [client.subprotocol] if client.subprotocol else list(self.subprotocols)
        try:
            async with connect(f"ws://127.0.0.1:{self.upstream_port}", subprotocols=subprotocols,
                               max_size=None, compression=None) as upstream:
                await asyncio.wait([asyncio.create_task(_pump(client, upstream)),
                                    asyncio.create_task(_pump(upstream, client))],
                                   return_when=asyncio.FIRST_COMPLETED)
        except (OSError, ConnectionClosed):
            pass


def unsupported_subprotocol(offered: list[str]) -> str:
    """Why a client offering ``offered`` subprotocols is refused, in one line."""
    what = ", ".join(offered) if offered else "no subprotocol"
    return (f"this Foxglove server (foxglove-sdk) speaks the WebSocket subprotocol foxglove.sdk.v1; the client "
            f"offered {what} (an older Foxglove app or another client): use a Foxglove app that connects to "
            f"foxglove-sdk servers")


async def _pump(source, sink) -> None:
    try:
        async for message in source:
            await sink.send(message)
    except ConnectionClosed:
        pass
    finally:
        await sink.close()
