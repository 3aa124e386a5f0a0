"""Live view: the MCAP's messages served over the Foxglove WebSocket protocol while a run
writes its dataset. Open Foxglove, "Open connection", ``ws://127.0.0.1:8765``.

The protocol is Foxglove's WebSocket protocol v1, offered under both its names
(``foxglove.websocket.v1``, which ``@foxglove/ws-protocol`` clients, Lichtblick and older
Foxglove use, and ``foxglove.sdk.v1``, which the current Foxglove app uses). It listens on
127.0.0.1 unless the address names another host; it serves the same topics and payloads as
``run.mcap`` and writes nothing to disk. Every channel of the rig is advertised when the
server starts, before frame 0, so a viewer connected early gets every frame; the static map
goes to each subscriber of ``/map`` when it subscribes. Frames go out as fast as they are made:
a viewer that falls behind loses its oldest messages, one that stops reading for
``STALL_S`` seconds is disconnected, and closing never waits more than ``CLOSE_S`` seconds
for a viewer: a viewer can lose messages, never delay or stop the run. Messages go out
uncompressed (no per-message deflate, whatever the viewer offers): compressing each frame once
per viewer would slow the run with every viewer that connects.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import struct
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from gtgen import topics
from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.images import FrameImages
from gtgen.sinks.mcap_sink import McapFrame, channel_schema, map_message, planned_topics, serialized_frame
from networks.errors import quoted
from networks.vocabulary import SensorKind

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")  # one protocol, two names
QUEUE_MESSAGES = 256  # per viewer; the oldest are dropped beyond this
STALL_S = 5.0  # a viewer that takes longer than this to take one message is disconnected
CLOSE_S = 2.0
DRAIN_S = 1.0  # at close, how long viewers may take to receive what is queued for them (the last frame)
MESSAGE_DATA = 1  # binary opcode: subscription id (uint32), log time (uint64), payload


@dataclass(frozen=True, slots=True)
class LiveAddress:
    host: str
    port: int  # 0: any free port

    def __str__(self) -> str:
        return f"{self.host}:{self.port}"


def parse_live_address(text: str) -> LiveAddress:
    """``PORT``, ``HOST:PORT`` or ``HOST`` (port 8765); raises ValueError with what was expected."""
    text = text.strip()
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = (DEFAULT_HOST, text) if text.isdigit() else (text, str(DEFAULT_PORT))
    host = host or DEFAULT_HOST
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"PORT, HOST:PORT or HOST, with a port from 0 to 65535, got {quoted(text)}")
    return LiveAddress(host, int(port))


@dataclass(eq=False, slots=True)
class _Viewer:
    connection: ServerConnection
    channel_of: dict[int, int] = field(default_factory=dict)  # subscription id -> channel id
    subscription_of: dict[int, int] = field(default_factory=dict)  # channel id -> subscription id
    data: deque[bytes] = field(default_factory=lambda: deque(maxlen=QUEUE_MESSAGES))
    control: deque[str] = field(default_factory=deque)
    pending: asyncio.Event = field(default_factory=asyncio.Event)


def _message_data(subscription: int, log_time_ns: int, payload: bytes) -> bytes:
    return struct.pack("<BIQ", MESSAGE_DATA, subscription, log_time_ns) + payload


class FoxgloveServer:
    """The Foxglove WebSocket protocol server, on an event loop in a thread of its own. Its
    methods may be called from any thread and never wait for a viewer."""

    def __init__(self, host: str, port: int, name: str = "sumo-dataset-factory") -> None:
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="live-view", daemon=True)
        self._thread.start()
        self._name, self._session = name, str(time.time_ns())
        self._viewers: set[_Viewer] = set()
        self._channels: dict[int, dict[str, Any]] = {}
        self._latched: dict[int, tuple[int, bytes]] = {}  # channel id -> the message a new subscriber gets
        try:
            self._server: Server = asyncio.run_coroutine_threadsafe(self._start(host, port), self._loop).result(10)
        except BaseException:
            self._stop_loop()
            raise
        self.port = int(self._server.sockets[0].getsockname()[1])

    async def _start(self, host: str, port: int) -> Server:
        return await serve(self._serve, host, port, subprotocols=list(SUBPROTOCOLS), ping_interval=None,  # type: ignore[arg-type]
                           max_size=1 << 20, write_limit=1 << 20, close_timeout=CLOSE_S, compression=None)  # fmt: skip

    # --- any thread ---------------------------------------------------------------------------
    def advertise(self, channel_id: int, topic: str, proto: type | None) -> None:
        schema = channel_schema(proto, topic)
        text = base64.b64encode(schema.data).decode() if schema.encoding == "protobuf" else schema.data.decode()
        channel = {"id": channel_id, "topic": topic, "encoding": schema.message_encoding,
                   "schemaName": schema.name, "schema": text, "schemaEncoding": schema.encoding}  # fmt: skip
        self._loop.call_soon_threadsafe(self._advertise, channel)

    def publish(self, channel_id: int, log_time_ns: int, payload: bytes, latch: bool = False) -> None:
        """Send to the channel's subscribers; with ``latch``, to every later subscriber too."""
        self._loop.call_soon_threadsafe(self._publish, channel_id, log_time_ns, payload, latch)

    def close(self) -> None:
        """Disconnect every viewer once it has what was published (waiting at most ``DRAIN_S`` for
        that, then ``CLOSE_S`` for the disconnection) and stop."""
        with contextlib.suppress(TimeoutError, RuntimeError):  # a viewer that will not close is left behind
            asyncio.run_coroutine_threadsafe(self._close(), self._loop).result(DRAIN_S + CLOSE_S + 1.0)
        self._stop_loop()

    def _stop_loop(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(CLOSE_S)

    # --- the event loop's thread ----------------------------------------------------------------
    def _advertise(self, channel: dict[str, Any]) -> None:
        self._channels[channel["id"]] = channel
        for viewer in self._viewers:
            self._send_control(viewer, {"op": "advertise", "channels": [channel]})

    def _publish(self, channel_id: int, log_time_ns: int, payload: bytes, latch: bool) -> None:
        if latch:
            self._latched[channel_id] = (log_time_ns, payload)
        for viewer in self._viewers:
            subscription = viewer.subscription_of.get(channel_id)
            if subscription is not None:
                viewer.data.append(_message_data(subscription, log_time_ns, payload))
                viewer.pending.set()

    @staticmethod
    def _send_control(viewer: _Viewer, message: dict[str, Any]) -> None:
        viewer.control.append(json.dumps(message, separators=(",", ":")))
        viewer.pending.set()

    async def _serve(self, connection: ServerConnection) -> None:
        viewer = _Viewer(connection)
        self._send_control(viewer, {"op": "serverInfo", "name": self._name, "capabilities": [],
                                    "supportedEncodings": [], "metadata": {}, "sessionId": self._session})  # fmt: skip
        if self._channels:
            self._send_control(viewer, {"op": "advertise", "channels": list(self._channels.values())})
        self._viewers.add(viewer)
        sender = asyncio.create_task(self._send(viewer))
        try:
            async for text in connection:
                if isinstance(text, str):
                    self._request(viewer, json.loads(text))
        except (ConnectionClosed, ValueError):
            pass
        finally:
            self._viewers.discard(viewer)
            sender.cancel()

    def _request(self, viewer: _Viewer, request: dict[str, Any]) -> None:
        if request.get("op") == "subscribe":
            for sub in request.get("subscriptions", []):
                channel = int(sub["channelId"])
                viewer.channel_of[int(sub["id"])], viewer.subscription_of[channel] = channel, int(sub["id"])
                if channel in self._latched:
                    log_time_ns, payload = self._latched[channel]
                    viewer.data.append(_message_data(int(sub["id"]), log_time_ns, payload))
                    viewer.pending.set()
        elif request.get("op") == "unsubscribe":
            for sub_id in request.get("subscriptionIds", []):
                channel = viewer.channel_of.pop(int(sub_id), -1)
                viewer.subscription_of.pop(channel, None)

    async def _send(self, viewer: _Viewer) -> None:
        """Hand the viewer its messages, control first; give up on a viewer that stalls."""
        connection = viewer.connection
        while True:
            await viewer.pending.wait()
            viewer.pending.clear()
            while viewer.control or viewer.data:
                message: str | bytes = viewer.control.popleft() if viewer.control else viewer.data.popleft()
                try:
                    await asyncio.wait_for(connection.send(message), STALL_S)
                except (TimeoutError, ConnectionClosed):
                    connection.transport.abort()
                    return

    async def _close(self) -> None:
        deadline = asyncio.get_running_loop().time() + DRAIN_S
        while any(v.data or v.control for v in self._viewers) and asyncio.get_running_loop().time() < deadline:
            await asyncio.sleep(0.01)  # the frames already published reach the viewers that read
        self._server.close()
        for viewer in list(self._viewers):
            viewer.connection.transport.abort()
        await asyncio.wait_for(self._server.wait_closed(), CLOSE_S)


class LiveSink:
    """A Foxglove WebSocket server fed with every frame's messages; ``sensors`` ((kind, name)
    pairs of the rig) name the channels it advertises before the first frame."""

    def __init__(
        self, address: LiveAddress, map_world: Path | None = None, sensors: tuple[tuple[SensorKind, str], ...] = (),
        map_vectors: bool = False, events: bool = False, deskewed: tuple[str, ...] = (), occupancy: bool = False,
    ) -> None:  # fmt: skip
        try:
            self._server = FoxgloveServer(address.host, address.port)
        except OSError as err:
            reason = err.strerror or str(err)
            raise SinkError(f"live view: cannot listen on {address}: {reason}") from err
        self.host, self.port = address.host, self._server.port
        self._map_world = map_world
        self._channels: dict[str, int] = {}
        planned = planned_topics(sensors, map_world is not None, map_vectors, events, deskewed, occupancy)
        for topic, proto in planned if sensors else []:
            self._channel(topic, proto)

    def _channel(self, topic: str, proto: type | None) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            channel = self._channels[topic] = len(self._channels) + 1
            self._server.advertise(channel, topic, proto)
        return channel

    def encode(self, record: FrameRecord, images: FrameImages) -> McapFrame:
        frame = serialized_frame(record, images)
        if self._map_world is not None:
            frame = McapFrame(frame.timestamp_ns, (map_message(self._map_world, record.timestamp_ns), *frame.messages))
            self._map_world = None
        return frame

    def write(self, encoded: McapFrame) -> None:
        for message in encoded.messages:
            channel = self._channel(message.topic, message.proto)
            self._server.publish(channel, encoded.timestamp_ns, message.data, latch=message.topic == topics.MAP)

    def close(self) -> None:
        self._server.close()

    def abort(self) -> None:
        self._server.close()

    def keep(self) -> None:
        self._server.close()
