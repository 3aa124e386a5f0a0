"""The live view: a Foxglove WebSocket client sees the MCAP's channels and receives the
same payloads as ``run.mcap``; a bad address or a busy port is one clear error."""

import json
import struct
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from websockets.sync.client import connect

from gtgen.errors import SinkError
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.images import FrameImages
from gtgen.sinks.live import LiveAddress, LiveSink, parse_live_address

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 1  # binary opcode: subscription id (uint32), log time (uint64), payload


def test_addresses_parse_with_localhost_and_8765_by_default():
    assert parse_live_address("9000") == LiveAddress("127.0.0.1", 9000)
    assert parse_live_address("0.0.0.0:9001") == LiveAddress("0.0.0.0", 9001)
    assert parse_live_address("myhost") == LiveAddress("myhost", 8765)
    for bad in ("host:port", "70000", "h:-1"):
        with pytest.raises(ValueError, match="PORT, HOST:PORT or HOST"):
            parse_live_address(bad)


def test_a_viewer_receives_every_topic_with_the_payloads_written_to_the_mcap(records, tmp_path):
    live = LiveSink(LiveAddress("127.0.0.1", 0))
    mcap = SinkGroup.open(SinkChoice(tmp_path, csv=False, kitti=False, yolo=False))
    received: dict[str, tuple[int, bytes]] = {}
    try:
        with connect(f"ws://127.0.0.1:{live.port}", subprotocols=[SUBPROTOCOL], open_timeout=5) as ws:
            mcap.write(records[0])
            first = live.encode(records[0], FrameImages(records[0].cameras))
            live.write(first)  # advertises every channel
            topics = _advertised(ws, count=len({m.topic for m in first.messages}))
            assert topics["/lidar"]["schemaName"] == "foxglove.PointCloud"
            assert topics["/lidar"]["encoding"] == "protobuf"
            assert topics["/gt/labels"]["encoding"] == "json"
            by_subscription = dict(enumerate(topics))
            subscriptions = [{"id": i, "channelId": topics[t]["id"]} for i, t in by_subscription.items()]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            deadline = time.monotonic() + 5.0
            while live.watched_topics() != set(topics) and time.monotonic() < deadline:
                time.sleep(0.02)
            for record in records[1:]:
                mcap.write(record)
                live.write(live.encode(record, FrameImages(record.cameras)))
            last_ns = records[-1].timestamp_ns
            while len(received) < len(topics) or any(t != last_ns for t, _ in received.values()):
                data = ws.recv(timeout=5)
                if isinstance(data, bytes) and data[0] == MESSAGE_DATA:
                    subscription, log_time = struct.unpack_from("<IQ", data, 1)
                    received[by_subscription[subscription]] = (log_time, data[13:])
    finally:
        live.close()
        mcap.close()
    last = _last_payloads(tmp_path / "run.mcap")
    assert set(received) == set(last)
    for topic, payload in last.items():
        assert received[topic][1] == payload, topic


def test_a_busy_port_is_one_clear_error():
    first = LiveSink(LiveAddress("127.0.0.1", 0))
    try:
        with pytest.raises(SinkError, match=rf"live view: cannot listen on 127\.0\.0\.1:{first.port}"):
            LiveSink(LiveAddress("127.0.0.1", first.port))
    finally:
        first.close()


def _advertised(ws, count: int) -> dict[str, dict]:
    """Channels the server advertised, by topic, once ``count`` are known."""
    topics: dict[str, dict] = {}
    while len(topics) < count:
        message = json.loads(ws.recv(timeout=5))
        if message["op"] == "advertise":
            topics.update({c["topic"]: c for c in message["channels"]})
    return topics


def _last_payloads(path: Path) -> dict[str, bytes]:
    with path.open("rb") as stream:
        return {c.topic: m.data for _, c, m in make_reader(stream).iter_messages()}
