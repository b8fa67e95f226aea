"""A rosbridge v2 protocol server over websockets: the subset roslibpy uses for topics.

Clients advertise, publish, subscribe and unsubscribe; the server publishes to
its subscribers. It records every message it receives, so tests can assert on
exactly what reached the "robot", and it can inject faults.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from dataclasses import dataclass, field
from http import HTTPStatus
from typing import Callable

from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

log = logging.getLogger("envfactory.twin")


@dataclass(frozen=True)
class Received:
    time: float  # time.monotonic()
    topic: str
    msg: dict


@dataclass
class Faults:
    """What the twin does wrong on purpose."""

    silenced: set[str] = field(default_factory=set)  # topics it stops publishing
    malformed: set[str] = field(default_factory=set)  # topics it publishes broken messages on
    delay_s: float = 0.0  # latency added to every outgoing message
    refuse_connections: bool = False  # new clients are turned away (a reconnect then fails)


class RosbridgeServer:
    def __init__(self, on_publish: Callable[[str, dict], None], host: str = "127.0.0.1", port: int = 0):
        self.host, self.port = host, port
        self.on_publish = on_publish
        self.faults = Faults()
        self.received: list[Received] = []
        self.errors: list[str] = []  # protocol errors, as a rosbridge server would report them
        self._subscribers: dict[str, set[ServerConnection]] = {}
        self._connections: set[ServerConnection] = set()
        self._server = None

    async def start(self) -> None:
        self._server = await serve(self._serve, self.host, self.port, process_request=self._admit)
        self.port = self._server.sockets[0].getsockname()[1]

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()

    @property
    def client_count(self) -> int:
        return len(self._connections)

    def subscribed(self, topic: str) -> bool:
        return bool(self._subscribers.get(topic))

    async def drop_connections(self) -> None:
        for connection in list(self._connections):
            await connection.close(code=1011, reason="twin: connection dropped on purpose")

    async def publish(self, topic: str, msg: dict) -> None:
        if topic in self.faults.silenced or not self._subscribers.get(topic):
            return
        payload = json.dumps({"op": "publish", "topic": topic, "msg": msg})
        if self.faults.delay_s > 0:
            await asyncio.sleep(self.faults.delay_s)
        for connection in list(self._subscribers.get(topic, ())):
            try:
                await connection.send(payload)
            except ConnectionClosed:
                self._forget(connection)

    def _forget(self, connection: ServerConnection) -> None:
        self._connections.discard(connection)
        for subscribers in self._subscribers.values():
            subscribers.discard(connection)

    def _admit(self, connection: ServerConnection, request):
        if self.faults.refuse_connections:  # turned away at the handshake, as an unreachable robot would be
            return connection.respond(HTTPStatus.SERVICE_UNAVAILABLE, "twin: refusing connections\n")
        return None

    async def _serve(self, connection: ServerConnection) -> None:
        self._connections.add(connection)
        try:
            async for raw in connection:
                self._handle(connection, raw)
        except ConnectionClosed:
            pass
        finally:
            self._forget(connection)

    def _handle(self, connection: ServerConnection, raw) -> None:
        try:
            message = json.loads(raw)
            op, topic = message["op"], message.get("topic", "")
        except (ValueError, KeyError, TypeError):
            self.errors.append(f"unparsable message: {str(raw)[:200]}")
            return
        if op == "subscribe":
            self._subscribers.setdefault(topic, set()).add(connection)
        elif op == "unsubscribe":
            self._subscribers.get(topic, set()).discard(connection)
        elif op == "publish":
            self.received.append(Received(time.monotonic(), topic, message.get("msg", {})))
            try:
                self.on_publish(topic, message.get("msg", {}))
            except Exception as exc:  # a bad command is reported, never crashes the twin
                self.errors.append(f"{topic}: {exc}")
                log.warning("twin: rejected a message on %s: %s", topic, exc)
        elif op in ("advertise", "unadvertise"):
            pass  # publishing needs no prior advertisement here
        else:
            self.errors.append(f"unsupported op {op!r}")
