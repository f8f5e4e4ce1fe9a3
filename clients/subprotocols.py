"""Both names of Foxglove's WebSocket protocol on one port, in front of foxglove-sdk's server.

foxglove-sdk's server accepts only the subprotocol `foxglove.sdk.v1` (0.30, and its newest source:
`rust/foxglove/src/websocket/handshake.rs` answers anything else with HTTP 400); Lichtblick and the
official `@foxglove/ws-protocol` client (0.8.0) offer only `foxglove.websocket.v1`, the same protocol
under its first name (Foxglove says so: the two are identical for now). No SDK version takes both.

So `simbot foxglove` serves the SDK on a private loopback port, and this front listens where the user
asked. Each connection is passed through byte for byte, except for one header of the handshake: a
client that offers `foxglove.websocket.v1` and not `foxglove.sdk.v1` has it offered to the SDK under
the new name, and the SDK's answer names the old one again, so every client gets the subprotocol it
asked for. The handshake stays valid (Sec-WebSocket-Accept hashes the client's key alone); what
follows it is spliced unchanged, so the SDK still speaks the whole protocol.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
import threading

SDK_SUBPROTOCOL = b"foxglove.sdk.v1"
LEGACY_SUBPROTOCOL = b"foxglove.websocket.v1"
HEAD_END = b"\r\n\r\n"
HEAD_LIMIT = 64 * 1024
"""Longest handshake accepted (request or response head); a longer one ends the connection."""
CHUNK = 256 * 1024
PROTOCOL_LINE = re.compile(rb"^(sec-websocket-protocol:)([^\r\n]*)", re.IGNORECASE | re.MULTILINE)
LOOPBACK = "127.0.0.1"


def offered(head: bytes) -> list[bytes]:
    """The subprotocols a handshake head names, in order, from every Sec-WebSocket-Protocol line."""
    return [name.strip() for match in PROTOCOL_LINE.finditer(head) for name in match.group(2).split(b",")]


def rename(head: bytes, old: bytes, new: bytes) -> bytes:
    """The head with the subprotocol `old` called `new` in its Sec-WebSocket-Protocol lines (nowhere else)."""

    def line(match: re.Match[bytes]) -> bytes:
        names = [name.replace(old, new) if name.strip() == old else name for name in match.group(2).split(b",")]
        return match.group(1) + b",".join(names)

    return PROTOCOL_LINE.sub(line, head)


def legacy_only(request: bytes) -> bool:
    """Whether a client offers only the old name, so that its handshake needs renaming."""
    names = offered(request)
    return LEGACY_SUBPROTOCOL in names and SDK_SUBPROTOCOL not in names


async def _splice(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Copy one direction until its end, then end the other side's writing too."""
    try:
        while chunk := await reader.read(CHUNK):
            writer.write(chunk)
            await writer.drain()
    finally:
        writer.close()


class SubprotocolFront:
    """A TCP front on (host, port) for a WebSocket server on a loopback port; its own event loop thread.

    `bind` comes first, so that a port in use is reported before the server behind starts; `serve`
    then accepts connections for the server's port.
    """

    def __init__(self, host: str, port: int) -> None:
        self._address = (host, port)
        self._backend_port = 0
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="foxglove-front", daemon=True)
        self._server: asyncio.Server | None = None
        self.port = 0

    def bind(self) -> None:
        """Take the address; one in use or a bad host raises OSError here, in the caller's thread."""
        self._thread.start()
        host, port = self._address
        listening = asyncio.start_server(self._serve, host, port, limit=HEAD_LIMIT, start_serving=False)
        self._server = asyncio.run_coroutine_threadsafe(listening, self._loop).result()
        self.port = self._server.sockets[0].getsockname()[1]

    def serve(self, backend_port: int) -> None:
        """Accept connections, each passed to the WebSocket server on the loopback port `backend_port`."""
        assert self._server is not None, "bind first"
        self._backend_port = backend_port
        asyncio.run_coroutine_threadsafe(self._server.start_serving(), self._loop).result()

    def stop(self) -> None:
        """Stop listening, end every connection and the loop's thread."""
        if self._thread.is_alive():
            asyncio.run_coroutine_threadsafe(self._shutdown(), self._loop).result()
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join()
        self._loop.close()

    async def _shutdown(self) -> None:
        if self._server is not None:
            self._server.close()
        tasks = [task for task in asyncio.all_tasks() if task is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    async def _serve(self, client_reader: asyncio.StreamReader, client_writer: asyncio.StreamWriter) -> None:
        """One connection: the handshake, renamed where needed, then both directions spliced."""
        backend_writer: asyncio.StreamWriter | None = None
        try:
            request = await client_reader.readuntil(HEAD_END)
            legacy = legacy_only(request)
            backend_reader, backend_writer = await asyncio.open_connection(
                LOOPBACK, self._backend_port, limit=HEAD_LIMIT
            )
            backend_writer.write(rename(request, LEGACY_SUBPROTOCOL, SDK_SUBPROTOCOL) if legacy else request)
            response = await backend_reader.readuntil(HEAD_END)
            client_writer.write(rename(response, SDK_SUBPROTOCOL, LEGACY_SUBPROTOCOL) if legacy else response)
            await asyncio.gather(_splice(client_reader, backend_writer), _splice(backend_reader, client_writer))
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            pass  # the client or the SDK went, or sent no handshake: nothing to keep
        finally:
            for writer in (client_writer, backend_writer):
                if writer is not None:
                    writer.close()
                    with contextlib.suppress(OSError, asyncio.CancelledError):
                        await writer.wait_closed()
