"""The plain TCP link of native clients (no rclpy): length-prefixed JSON and frame messages
(``protocol.TCP_HEADER``)."""
from __future__ import annotations

import asyncio

from raspv_hmd import protocol as P
from raspv_hmd.client_session import CLOSE_TIMEOUT_S, HARD_MESSAGE_LIMIT, Drop


class TcpLink:
    transport = "tcp"

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer
        self.said_bye = False
        writer.transport.set_write_buffer_limits(high=P.MAX_CLIENT_MESSAGE * 16)

    async def _write(self, kind: int, data: bytes) -> None:
        self.writer.writelines([P.TCP_HEADER.pack(len(data), kind), data])
        await self.writer.drain()

    async def send_text(self, text: str) -> None:
        await self._write(P.TCP_JSON, text.encode())

    async def send_frame(self, data: bytes) -> None:
        await self._write(P.TCP_FRAME, data)

    async def recv(self) -> str | bytes | None:
        try:
            length, kind = P.TCP_HEADER.unpack(await self.reader.readexactly(P.TCP_HEADER.size))
            if length > HARD_MESSAGE_LIMIT:
                raise Drop("oversized", f"message of {length} bytes announced; the limit is {HARD_MESSAGE_LIMIT}")
            payload = await self.reader.readexactly(length)
        except (asyncio.IncompleteReadError, ConnectionError):
            return None
        if kind != P.TCP_JSON:
            raise P.ProtocolError("bad_kind", f"clients send JSON messages (kind {P.TCP_JSON}), got kind {kind}")
        return payload

    async def close(self) -> None:
        self.writer.close()                 # flushes what is buffered, then closes
        try:
            await asyncio.wait_for(self.writer.wait_closed(), CLOSE_TIMEOUT_S)
        except (OSError, asyncio.TimeoutError):
            self.writer.transport.abort()   # the client does not read: do not linger

    def cut(self) -> None:
        self.writer.transport.close()
