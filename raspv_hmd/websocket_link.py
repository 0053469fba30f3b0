"""The WebSocket link of the browser client page (no rclpy): JSON text and frames over one
WebSocket (the same port serves the page over HTTP, :mod:`raspv_hmd.http_pages`)."""
from __future__ import annotations

import asyncio

from websockets.asyncio.server import ServerConnection
from websockets.exceptions import ConnectionClosed

from raspv_hmd import protocol as P
from raspv_hmd.client_session import CLOSE_TIMEOUT_S, HARD_MESSAGE_LIMIT, Drop


class WebSocketLink:
    transport = "websocket"

    def __init__(self, ws: ServerConnection) -> None:
        self.ws = ws
        self.said_bye = False             # the server told the client why it goes (_send_bye)
        self._receiving = False

    async def send_text(self, text: str) -> None:
        await self.ws.send(text)

    async def send_frame(self, data: bytes) -> None:
        await self.ws.send(data)

    async def recv(self) -> str | bytes | None:
        self._receiving = True
        try:
            msg = await self.ws.recv()
        except ConnectionClosed as exc:
            if exc.sent is not None and exc.sent.code == 1009:
                raise Drop("oversized", f"message above {HARD_MESSAGE_LIMIT} bytes") from None
            return None
        finally:
            self._receiving = False
        if isinstance(msg, bytes):
            raise P.ProtocolError("binary", "clients send JSON text messages, not binary ones")
        return msg

    async def close(self) -> None:
        if not self.said_bye or self._receiving:   # receiving elsewhere: that loop cuts (the server's receive loop)
            await self.ws.close()
            return
        # after a bye the only answer expected is the closing handshake; a client that sends a
        # message instead is not listening, and is cut off at once rather than after the timeout
        closing = asyncio.create_task(self.ws.close())
        try:
            await asyncio.wait_for(self.ws.recv(), CLOSE_TIMEOUT_S)
        except (ConnectionClosed, asyncio.TimeoutError):
            pass
        else:
            self.cut()
        await closing

    def cut(self) -> None:
        """Close the connection now (what is buffered is still sent), no closing handshake."""
        self.ws.transport.close()
