"""The live view: a Foxglove WebSocket client (either protocol name) connected before the
first frame sees every channel, receives frame 0 on every topic and the static map, the
same payloads as ``run.mcap``; a viewer that never reads cannot hold the run up; a bad
address or a busy port is one clear error."""

import contextlib
import json
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from websockets.sync.client import connect

from gtgen.errors import SinkError
from gtgen.sinks.group import SinkChoice, SinkGroup
from gtgen.sinks.images import FrameImages
from gtgen.sinks.live import STALL_S, LiveAddress, LiveSink, parse_live_address
from gtgen.sinks.mcap_sink import frame_messages, planned_topics

MESSAGE_DATA = 1  # binary opcode: subscription id (uint32), log time (uint64), payload
RIG = (("lidar", "lidar"), ("camera", "camera"), ("radar", "radar"))


def _until_subscribed(live: LiveSink, count: int) -> None:
    """Wait (up to 10 s) until the server holds ``count`` subscriptions of one viewer: a loaded
    machine may take longer than any fixed sleep to read the viewer's subscribe message."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not any(len(v.subscription_of) >= count for v in list(live._server._viewers)):
        time.sleep(0.01)


@pytest.fixture
def world_file(tmp_path) -> Path:
    """A static world file (one ground quad) for the /map channel."""
    path = tmp_path / "world.npz"
    np.savez_compressed(path, vertices_m=np.array([[0, 0, 0], [50, 0, 0], [50, 50, 0], [0, 50, 0]], np.float32),
                        triangles=np.array([[0, 1, 2], [0, 2, 3]], np.int32), triangle_class=np.ones(2, np.uint8),
                        bounds_m=np.array([0.0, 0.0, 50.0, 50.0]), num_buildings=0)  # fmt: skip
    return path


def test_addresses_parse_with_localhost_and_8765_by_default():
    assert parse_live_address("9000") == LiveAddress("127.0.0.1", 9000)
    assert parse_live_address("0.0.0.0:9001") == LiveAddress("0.0.0.0", 9001)
    assert parse_live_address("myhost") == LiveAddress("myhost", 8765)
    for bad in ("host:port", "70000", "h:-1"):
        with pytest.raises(ValueError, match="PORT, HOST:PORT or HOST"):
            parse_live_address(bad)


def test_the_planned_topics_are_the_topics_of_a_frame(records):
    planned = dict(planned_topics(RIG, with_map=False))
    written = dict(
        (topic, type(m) if not isinstance(m, dict) else None)
        for topic, m in frame_messages(records[0], FrameImages(records[0].cameras))
    )
    assert planned == written


@pytest.mark.parametrize("subprotocol", ["foxglove.websocket.v1", "foxglove.sdk.v1"])
def test_a_viewer_connected_before_the_run_gets_frame_0_on_every_topic_and_the_map(
    records, tmp_path, world_file, subprotocol
):
    live = LiveSink(LiveAddress("127.0.0.1", 0), world_file, RIG)
    mcap = SinkGroup.open(SinkChoice(tmp_path, csv=False, kitti=False, yolo=False, map_world=world_file))
    received: dict[str, list[tuple[int, bytes]]] = {}
    try:
        with connect(f"ws://127.0.0.1:{live.port}", subprotocols=[subprotocol], open_timeout=5) as ws:
            assert ws.subprotocol == subprotocol
            topics = _advertised(ws, count=len(planned_topics(RIG, with_map=True)))
            assert (
                topics["/lidar"]["schemaName"] == "foxglove.PointCloud" and topics["/lidar"]["encoding"] == "protobuf"
            )
            assert topics["/gt/labels"]["encoding"] == "json"
            by_subscription = dict(enumerate(topics))
            subscriptions = [{"id": i, "channelId": topics[t]["id"]} for i, t in by_subscription.items()]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            _until_subscribed(live, len(topics))  # the subscriptions reach the server before the first frame
            for record in records:
                mcap.write(record)
                live.write(live.encode(record, FrameImages(record.cameras)))
            last_ns = records[-1].timestamp_ns
            while len(received) < len(topics) or any(v[-1][0] != last_ns for t, v in received.items() if t != "/map"):
                data = ws.recv(timeout=5)
                if isinstance(data, bytes) and data[0] == MESSAGE_DATA:
                    subscription, log_time = struct.unpack_from("<IQ", data, 1)
                    received.setdefault(by_subscription[subscription], []).append((log_time, data[13:]))
    finally:
        live.close()
        mcap.close()
    written = _payloads(tmp_path / "run.mcap")
    assert set(received) == set(written)
    for topic, messages in written.items():
        assert received[topic] == messages, topic  # frame 0 included, each message once


def test_a_late_subscriber_of_the_map_gets_it_when_it_subscribes(records, world_file):
    live = LiveSink(LiveAddress("127.0.0.1", 0), world_file, RIG)
    try:
        live.write(live.encode(records[0], FrameImages(records[0].cameras)))
        with connect(f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.websocket.v1"], open_timeout=5) as ws:
            topics = _advertised(ws, count=len(planned_topics(RIG, with_map=True)))
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": topics["/map"]["id"]}]}))
            data = ws.recv(timeout=5)
            while not isinstance(data, bytes):
                data = ws.recv(timeout=5)
            assert struct.unpack_from("<BIQ", data) == (MESSAGE_DATA, 7, records[0].timestamp_ns)
    finally:
        live.close()


def test_a_viewer_that_never_reads_does_not_hold_the_run_up(record_maker):
    big = record_maker(0, lidar_azimuth_steps=8192)
    live = LiveSink(LiveAddress("127.0.0.1", 0), None, RIG)
    with connect(f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.sdk.v1"], open_timeout=5, max_size=None,
                 max_queue=1, close_timeout=0.5) as ws:  # fmt: skip
        topics = _advertised(ws, count=len(planned_topics(RIG, with_map=False)))
        subscriptions = [{"id": i, "channelId": c["id"]} for i, c in enumerate(topics.values())]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        _until_subscribed(live, len(subscriptions))
        encoded = live.encode(big, FrameImages(big.cameras))
        start = time.monotonic()
        for _ in range(200):  # about 1 GB the viewer never takes
            live.write(encoded)
        # a write only queues (a viewer's oldest messages dropped beyond QUEUE_MESSAGES); one that
        # waited for this viewer would wait STALL_S, until the viewer is disconnected
        assert time.monotonic() - start < STALL_S / 2
        live.close()


def test_frames_go_out_uncompressed_whatever_the_viewer_offers(records):
    """Per-message deflate would compress each frame once per viewer (20 viewers slowed a run by
    65 %): the server declines it, so a viewer that offers it gets the payloads as they are."""
    live = LiveSink(LiveAddress("127.0.0.1", 0), None, RIG)
    try:
        with connect(
            f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.sdk.v1"], open_timeout=5, compression="deflate"
        ) as ws:
            assert "permessage-deflate" in ws.request.headers["Sec-WebSocket-Extensions"]
            assert ws.response.headers.get("Sec-WebSocket-Extensions") is None
            assert ws.protocol.extensions == []
            topics = _advertised(ws, count=len(planned_topics(RIG, with_map=False)))
            ws.send(
                json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": topics["/gt/labels"]["id"]}]})
            )
            _until_subscribed(live, 1)
            live.write(live.encode(records[0], FrameImages(records[0].cameras)))
            data = ws.recv(timeout=5)
            assert isinstance(data, bytes) and data[0] == MESSAGE_DATA
            assert json.loads(data[13:])["frame"] == 0
    finally:
        live.close()


def test_a_busy_port_is_one_clear_error():
    first = LiveSink(LiveAddress("127.0.0.1", 0))
    try:
        with pytest.raises(SinkError, match=rf"live view: cannot listen on 127\.0\.0\.1:{first.port}: "):
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


def _payloads(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = {}
    with path.open("rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            out.setdefault(channel.topic, []).append((message.log_time, message.data))
    return out


def test_a_viewer_that_reads_gets_the_last_frame_on_every_topic_when_the_run_closes(records):
    import threading

    live = LiveSink(LiveAddress("127.0.0.1", 0), None, RIG)
    last: dict[str, int] = {}
    with connect(f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.websocket.v1"], open_timeout=5) as ws:
        topics = _advertised(ws, count=len(planned_topics(RIG, with_map=False)))
        by_subscription = dict(enumerate(topics))
        subscriptions = [{"id": i, "channelId": topics[t]["id"]} for i, t in by_subscription.items()]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        _until_subscribed(live, len(topics))

        def read() -> None:
            with contextlib.suppress(Exception):  # the server closes the connection at the end
                while True:
                    data = ws.recv(timeout=5)
                    if isinstance(data, bytes) and data[0] == MESSAGE_DATA:
                        subscription, log_time = struct.unpack_from("<IQ", data, 1)
                        last[by_subscription[subscription]] = log_time

        reader = threading.Thread(target=read)
        reader.start()
        for record in records:
            live.write(live.encode(record, FrameImages(record.cameras)))
        live.close()  # right after the last frame, as a run ends
        reader.join(10)
    assert set(last) == set(topics)
    assert all(t == records[-1].timestamp_ns for t in last.values())
