"""A rosbridge v2 protocol server over websockets that behaves as a ROS 1 rosbridge_server
(0.11) with rosapi does for the operations roslibpy uses.

The ROS graph behind it is a set of nodes (the twin's driver and cube tracker)
that publish and subscribe typed topics. As on the real server:
- a topic's type is the one it was first registered with; an advertise,
  subscribe or publish whose type conflicts is refused;
- a published message must fill its type (no unknown fields, the right kinds of
  values), or it is refused;
- refusals are logged on the server and reach the client as `status` messages
  only after the client asked for them with `set_level`;
- NaN and infinity go out as null;
- rosapi answers the topic services (/rosapi/topic_type, /rosapi/subscribers,
  /rosapi/publishers, /rosapi/topics, /rosapi/topics_for_type), and the nodes
  answer their own (a driver's); a call a service refuses answers with
  `result: false` and the reason, as a ROS 1 service that returns false.
It records every message its nodes receive, so tests can assert on exactly what
reached the "robot", and it can inject faults.
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import time
from dataclasses import dataclass, field
from http import HTTPStatus
from typing import Callable

from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from envfactory.twin import msgtypes

log = logging.getLogger("envfactory.twin")

BRIDGE_NODE = "/rosbridge_websocket"
STATUS_LEVELS = ("info", "warning", "error", "none")  # a client sees status at or above its level


@dataclass(frozen=True)
class Received:
    time: float  # time.monotonic()
    topic: str
    msg: dict


@dataclass
class Faults:
    """What the twin does wrong on purpose."""

    silenced: dict[str, float] = field(default_factory=dict)  # topic -> time.monotonic() it speaks again
    malformed: dict[str, float] = field(default_factory=dict)  # topic -> how many more messages go out broken
    delay_s: float = 0.0  # latency added to every outgoing message
    refuse_connections: bool = False  # new clients are turned away at the handshake
    no_rosapi: bool = False  # the server runs without rosapi: its services do not exist
    ignore_commands: bool = False  # the driver takes commands but does not execute them (controller stopped)
    refuse_services: set[str] = field(default_factory=set)  # a driver's services that refuse every call

    def silence(self, topic: str, seconds: float = math.inf) -> None:
        self.silenced[topic] = time.monotonic() + seconds

    def is_silenced(self, topic: str) -> bool:
        return time.monotonic() < self.silenced.get(topic, -math.inf)

    def corrupt(self, topic: str, count: float = math.inf) -> None:
        self.malformed[topic] = count

    def take_malformed(self, topic: str) -> bool:
        """Whether the next message on `topic` goes out broken (and count it)."""
        left = self.malformed.get(topic, 0)
        if left <= 0:
            return False
        self.malformed[topic] = left - 1
        return True


@dataclass(frozen=True)
class ServiceReply:
    """What a node's service answers: ok (a ROS 1 handler's true), and the response, or the reason it logs."""

    ok: bool
    values: dict | str


@dataclass
class Node:
    """A node of the ROS graph behind the server: what it publishes, what it takes in."""

    name: str
    publishes: dict[str, str] = field(default_factory=dict)  # topic -> type
    subscribes: dict[str, tuple[str, Callable[[str, dict], None]]] = field(default_factory=dict)
    # service -> (type, handler(request) -> ServiceReply): the node's own services
    services: dict[str, tuple[str, Callable]] = field(default_factory=dict)


@dataclass
class _Client:
    level: str = "none"  # no status messages until the client asks (set_level)
    advertised: set[str] = field(default_factory=set)
    subscribed: set[str] = field(default_factory=set)


class ProtocolError(Exception):
    """A refused operation: logged by the server, sent as status only on request."""


class RosbridgeServer:
    """A rosbridge v2 server over websockets with the graph of nodes behind it: it keeps each topic's type,
    checks what is published against it, forwards to subscribers and nodes, answers rosapi's and the nodes'
    services, records what the nodes received, and injects the faults in `faults`."""

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, message_types: dict[str, dict[str, str]] = msgtypes.MESSAGES
    ):
        self.host, self.port = host, port
        self.message_types = message_types  # what its ROS installation defines
        self.faults = Faults()
        self.received: list[Received] = []
        self.errors: list[str] = []  # what the server logged as refused
        self.calls: list[tuple[str, dict, bool]] = []  # the nodes' services called: (service, request, answered)
        self.nodes: list[Node] = []
        self.service_types = dict(msgtypes.SERVICES)  # rosapi's and the nodes' own
        self._types: dict[str, str] = {}  # topic -> its established type
        self._clients: dict[ServerConnection, _Client] = {}
        self._server = None
        self._services = {
            "/rosapi/topic_type": ("rosapi/TopicType", lambda a: {"type": self._types.get(a.get("topic", ""), "")}),
            "/rosapi/subscribers": (
                "rosapi/Subscribers",
                lambda a: {"subscribers": self._subscriber_nodes(a.get("topic", ""))},
            ),
            "/rosapi/publishers": (
                "rosapi/Publishers",
                lambda a: {"publishers": self._publisher_nodes(a.get("topic", ""))},
            ),
            "/rosapi/topics": (
                "rosapi/Topics",
                lambda a: {"topics": sorted(self._types), "types": [self._types[t] for t in sorted(self._types)]},
            ),
            "/rosapi/topics_for_type": (
                "rosapi/TopicsForType",
                lambda a: {"topics": sorted(t for t, ty in self._types.items() if ty == a.get("type"))},
            ),
        }

    # ------------------------------------------------------------------ the graph

    def add_node(self, node: Node, service_types: dict[str, tuple[dict, dict]] | None = None) -> None:
        """A node joins the graph; `service_types` defines the types of its services (request, response fields)."""
        for topic, type_name in [*node.publishes.items(), *((t, ty) for t, (ty, _) in node.subscribes.items())]:
            self._types.setdefault(topic, type_name)
        self.service_types.update(service_types or {})
        self.nodes.append(node)

    def topic_type(self, topic: str) -> str:
        return self._types.get(topic, "")

    def _subscriber_nodes(self, topic: str) -> list[str]:
        names = [node.name for node in self.nodes if topic in node.subscribes]
        if any(topic in client.subscribed for client in self._clients.values()):
            names.append(BRIDGE_NODE)
        return names

    def _publisher_nodes(self, topic: str) -> list[str]:
        names = [node.name for node in self.nodes if topic in node.publishes]
        if any(topic in client.advertised for client in self._clients.values()):
            names.append(BRIDGE_NODE)
        return names

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        self._server = await serve(self._serve, self.host, self.port, process_request=self._admit)
        self.port = self._server.sockets[0].getsockname()[1]

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            self._server = None

    async def kill(self, down_for: float) -> None:
        """The server process dies (every client loses its connection, nothing listens) and
        comes back after `down_for` seconds on the same port; the robot's nodes live on."""
        await self.close()
        self._clients.clear()
        await asyncio.sleep(down_for)
        await self.start()

    @property
    def running(self) -> bool:
        return self._server is not None

    @property
    def client_count(self) -> int:
        return len(self._clients)

    async def drop_connections(self) -> None:
        for connection in list(self._clients):
            await connection.close(code=1011, reason="twin: connection dropped on purpose")

    # ------------------------------------------------------------------ out

    async def publish(self, topic: str, msg: dict) -> None:
        """A node publishes: every client subscribed to the topic gets it."""
        if self.faults.is_silenced(topic):
            return
        receivers = [c for c, client in self._clients.items() if topic in client.subscribed]
        if not receivers:
            return
        payload = json.dumps({"op": "publish", "topic": topic, "msg": msgtypes.nulls_for_non_finite(msg)})
        if self.faults.delay_s > 0:
            await asyncio.sleep(self.faults.delay_s)
        for connection in receivers:
            await self._send(connection, payload)

    async def _send(self, connection: ServerConnection, payload: str) -> None:
        try:
            await connection.send(payload)
        except ConnectionClosed:
            self._clients.pop(connection, None)

    def _refuse(self, connection: ServerConnection, message: dict, reason: str) -> None:
        self.errors.append(reason)
        log.warning("twin: %s", reason)
        client = self._clients.get(connection)
        if client is None or STATUS_LEVELS.index(client.level) > STATUS_LEVELS.index("error"):
            return
        status = {"op": "status", "level": "error", "msg": reason}
        if "id" in message:
            status["id"] = message["id"]
        asyncio.ensure_future(self._send(connection, json.dumps(status)))

    # ------------------------------------------------------------------ in

    def _admit(self, connection: ServerConnection, request):
        if self.faults.refuse_connections:  # turned away at the handshake, as an unreachable robot would be
            return connection.respond(HTTPStatus.SERVICE_UNAVAILABLE, "twin: refusing connections\n")
        return None

    async def _serve(self, connection: ServerConnection) -> None:
        self._clients[connection] = _Client()
        try:
            async for raw in connection:
                await self._handle(connection, raw)
        except ConnectionClosed:
            pass
        finally:
            self._clients.pop(connection, None)

    async def _handle(self, connection: ServerConnection, raw) -> None:
        try:
            message = json.loads(raw)
            op = message["op"]
        except (ValueError, KeyError, TypeError):
            self._refuse(connection, {}, f"unparsable message: {str(raw)[:200]}")
            return
        handler = {
            "advertise": self._advertise,
            "unadvertise": self._unadvertise,
            "publish": self._publish,
            "subscribe": self._subscribe,
            "unsubscribe": self._unsubscribe,
            "set_level": self._set_level,
            "call_service": self._call_service,
        }.get(op)
        client = self._clients.get(connection)
        if client is None:
            return
        try:
            if handler is None:
                raise ProtocolError(f"unknown operation {op!r}")
            reply = handler(client, message)
        except ProtocolError as exc:
            self._refuse(connection, message, f"{op}: {exc}")
            return
        if reply is not None:
            await self._send(connection, json.dumps(reply))

    def _establish(self, topic: str, type_name: str | None) -> str:
        """The topic's type, registering `type_name` if the topic is new; ProtocolError on a conflict."""
        established = self._types.get(topic)
        if established and type_name and type_name != established:
            raise ProtocolError(f"topic {topic} is established with type {established}; {type_name} conflicts")
        if not established and not type_name:
            raise ProtocolError(f"cannot infer the type of {topic}: nothing has advertised it")
        if type_name and not msgtypes.known(type_name, self.message_types):
            raise ProtocolError(f"unknown message type {type_name}")
        self._types.setdefault(topic, type_name)
        return self._types[topic]

    def _advertise(self, client: _Client, message: dict) -> None:
        topic = message.get("topic", "")
        self._establish(topic, message.get("type"))
        client.advertised.add(topic)

    def _unadvertise(self, client: _Client, message: dict) -> None:
        client.advertised.discard(message.get("topic", ""))

    def _subscribe(self, client: _Client, message: dict) -> None:
        topic = message.get("topic", "")
        self._establish(topic, message.get("type"))
        client.subscribed.add(topic)

    def _unsubscribe(self, client: _Client, message: dict) -> None:
        client.subscribed.discard(message.get("topic", ""))

    def _set_level(self, client: _Client, message: dict) -> None:
        level = message.get("level")
        if level not in STATUS_LEVELS:
            raise ProtocolError(f"unknown status level {level!r} (one of {', '.join(STATUS_LEVELS)})")
        client.level = level

    def _publish(self, client: _Client, message: dict) -> None:
        topic, msg = message.get("topic", ""), message.get("msg", {})
        type_name = self._establish(topic, None)  # a publish takes the topic's established type
        try:
            msgtypes.check(type_name, msg, types=self.message_types)
        except msgtypes.FieldError as exc:
            raise ProtocolError(f"{topic} ({type_name}): {exc}") from None
        for node in self.nodes:
            if topic not in node.subscribes:
                continue
            self.received.append(Received(time.monotonic(), topic, msg))
            try:
                node.subscribes[topic][1](topic, msg)
            except Exception as exc:  # a node that chokes on a message logs it and lives on
                self.errors.append(f"{node.name} on {topic}: {exc}")
                log.warning("twin: %s rejected a message on %s: %s", node.name, topic, exc)
        for connection, other in self._clients.items():
            if other is not client and topic in other.subscribed:
                asyncio.ensure_future(
                    self._send(
                        connection,
                        json.dumps({"op": "publish", "topic": topic, "msg": msgtypes.nulls_for_non_finite(msg)}),
                    )
                )

    def _call_service(self, client: _Client, message: dict) -> dict:
        name = message.get("service", "")
        reply = {"op": "service_response", "service": name}
        if "id" in message:
            reply["id"] = message["id"]
        rosapi = None if self.faults.no_rosapi else self._services.get(name)
        offered = [node.services[name] for node in self.nodes if name in node.services]
        service = rosapi or (offered[0] if offered else None)
        if service is None:
            self.errors.append(f"call_service: service {name} does not exist")
            return {**reply, "values": f"Service {name} does not exist", "result": False}
        type_name, answer = service
        request_fields, _ = self.service_types[type_name]
        args = message.get("args") or {}
        try:
            msgtypes.check_fields(type_name, request_fields, args, types=self.message_types)
        except msgtypes.FieldError as exc:
            self.errors.append(f"call_service {name}: {exc}")
            return {**reply, "values": str(exc), "result": False}
        if rosapi is not None:
            return {**reply, "values": answer(args), "result": True}
        # a service that returns false reaches the client as rospy's error, without the node's reason (that
        # goes to the node's own log)
        outcome = ServiceReply(False, "refused (twin fault)") if name in self.faults.refuse_services else answer(args)
        self.calls.append((name, args, outcome.ok))
        if not outcome.ok:
            self.errors.append(f"{name}: {outcome.values}")
            return {**reply, "values": f"service [{name}] responded with an error: b''", "result": False}
        return {**reply, "values": outcome.values, "result": True}
