"""Live view: the MCAP's messages served over the Foxglove WebSocket protocol while a run
writes its dataset. Open Foxglove, "Open connection", ``ws://127.0.0.1:8765``.

It listens on 127.0.0.1 unless the address names another host; it serves the same topics
and payloads as ``run.mcap`` (``/map`` again every ``MAP_REPEAT_FRAMES`` frames, for
viewers that connect late) and writes nothing to disk. Frames go out as fast as they are
made; a slow viewer drops messages, never the run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gtgen.errors import SinkError
from gtgen.frame import FrameRecord
from gtgen.sinks.images import FrameImages
from gtgen.sinks.mcap_sink import McapFrame, McapMessage, channel_schema, map_message, serialized_frame

if TYPE_CHECKING:
    import foxglove

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
MAP_REPEAT_FRAMES = 100


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
        raise ValueError(f"PORT, HOST:PORT or HOST, with a port from 0 to 65535, got {text!r}")
    return LiveAddress(host, int(port))


class LiveSink:
    """A Foxglove WebSocket server fed with every frame's messages."""

    def __init__(self, address: LiveAddress, map_world: Path | None = None) -> None:
        import foxglove  # the WebSocket server starts only when a live view is asked for

        self._foxglove = foxglove
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(
                name="sumo-dataset-factory", host=address.host, port=address.port, context=self._context
            )
        except Exception as err:  # the SDK raises its own errors for a busy port or a bad host
            raise SinkError(f"live view: cannot listen on {address}: {err}") from err
        self.host = address.host
        self.port = int(self._server.port)
        self._map_world = map_world
        self._map: McapMessage | None = None
        self._frames = 0
        self._channels: dict[str, foxglove.Channel] = {}

    def encode(self, record: FrameRecord, images: FrameImages) -> McapFrame:
        frame = serialized_frame(record, images)
        if self._map_world is not None and self._frames % MAP_REPEAT_FRAMES == 0:
            if self._map is None:
                self._map = map_message(self._map_world, record.timestamp_ns)
            frame = McapFrame(frame.timestamp_ns, (self._map, *frame.messages))
        self._frames += 1
        return frame

    def write(self, encoded: McapFrame) -> None:
        for message in encoded.messages:
            self._channel(message).log(message.data, log_time=encoded.timestamp_ns)

    def _channel(self, message: McapMessage) -> foxglove.Channel:
        channel = self._channels.get(message.topic)
        if channel is None:
            fg, described = self._foxglove, channel_schema(message)
            schema = fg.Schema(name=described.name, encoding=described.encoding, data=described.data)
            channel = fg.Channel(message.topic, schema=schema, message_encoding=described.message_encoding,
                                 context=self._context)  # fmt: skip
            self._channels[message.topic] = channel
        return channel

    def watched_topics(self) -> set[str]:
        """Topics some viewer subscribed to (among those advertised so far)."""
        return {topic for topic, channel in self._channels.items() if channel.has_sinks()}

    def close(self) -> None:
        self._server.stop()

    def abort(self) -> None:
        self._server.stop()
