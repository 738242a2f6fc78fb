"""``murk live --foxglove``: a client speaking Foxglove's WebSocket protocol (subprotocol foxglove.sdk.v1, the
one foxglove-sdk 0.30 accepts; plain WebSocket, testkit/ws.py)
receives raw, restored and depth CompressedImage messages stamped with the source's (a ROS bag's) header times."""

from __future__ import annotations

import json
import struct
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("foxglove")
pytest.importorskip("rosbags")

from murk.live.foxglove_publisher import TOPICS, FoxglovePublisher
from murk.live.restore_loop import LivePipeline
from murk.live.source import PacedSource, open_live_source
from testkit.ws import WebSocket
from tests._rosbags import BagBuilder, frames, stamp_ns
from tests.live._live import WAIT_S, make_restorer


def _fields(buf: bytes) -> dict[int, list[object]]:
    """A protobuf message's fields (varints and length-delimited only: what CompressedImage uses)."""
    out: dict[int, list[object]] = {}
    i = 0

    def varint() -> int:
        nonlocal i
        shift = value = 0
        while True:
            b = buf[i]
            i += 1
            value |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                return value

    while i < len(buf):
        key = varint()
        field, wire = key >> 3, key & 7
        if wire == 0:
            out.setdefault(field, []).append(varint())
        elif wire == 2:
            n = varint()
            out.setdefault(field, []).append(buf[i : i + n])
            i += n
        else:
            raise ValueError(f"wire type {wire} not expected in CompressedImage")
    return out


def test_protobuf_reader_matches_the_sdk_encoding() -> None:
    from foxglove.messages import CompressedImage, Timestamp

    msg = _fields(CompressedImage(timestamp=Timestamp(5, 7), frame_id="ab", data=b"xyz", format="jpeg").encode())
    assert _fields(msg[1][0]) == {1: [5], 2: [7]}  # type: ignore[arg-type]
    assert msg[2] == [b"xyz"] and msg[3] == [b"jpeg"] and msg[4] == [b"ab"]


def test_foxglove_client_receives_images_with_the_bag_stamps(tmp_path: Path) -> None:
    bag = BagBuilder(tmp_path / "dive.bag", "ros1").image("/cam/image", frames(6), "rgb8", frame_id="cam0").close()
    publisher = FoxglovePublisher("127.0.0.1", 0)
    ws = WebSocket(f"ws://127.0.0.1:{publisher.port}/", subprotocol="foxglove.sdk.v1", timeout_s=WAIT_S)
    try:
        channels: dict[str, int] = {}
        deadline = time.monotonic() + WAIT_S  # only a fault reaches it
        while len(channels) < 3 and time.monotonic() < deadline:
            opcode, payload = ws.recv()
            if opcode == 1:
                msg = json.loads(payload)
                if msg.get("op") == "advertise":
                    for ch in msg["channels"]:
                        assert ch["schemaName"] == "foxglove.CompressedImage"
                        channels[ch["topic"]] = ch["id"]
        assert set(channels) == set(TOPICS.values())
        assert publisher.subscribed() == set()
        subs = {i: topic for i, topic in enumerate(sorted(channels), start=1)}
        ws.send_text(
            json.dumps(
                {"op": "subscribe", "subscriptions": [{"id": i, "channelId": channels[t]} for i, t in subs.items()]}
            )
        )
        while publisher.subscribed() != set(channels):  # the subscriptions reach the server before the first frame
            assert time.monotonic() < deadline, f"subscribed: {publisher.subscribed()}"
            time.sleep(0.01)
        source = PacedSource(open_live_source(str(bag), topic="/cam/image"))
        pipeline = LivePipeline(source, make_restorer, "depth", tmp_path / "out", hooks=[publisher]).start()
        got: dict[str, list[tuple[int, int, dict]]] = {t: [] for t in channels}
        try:
            # The run ends first: every view shown by then has been handed to the publisher, so each topic's count
            # is known and every message waited for below is on its way (waiting for messages while the run went
            # on could wait for one more after the last).
            while pipeline.ended is None:
                pipeline.wait_view(10**9, WAIT_S)
                assert time.monotonic() < deadline, pipeline.status()
            while not all(len(m) >= pipeline.restored for m in got.values()):
                opcode, payload = ws.recv()
                if opcode == 2 and payload[0] == 0x01:  # MessageData
                    sub, log_ns = struct.unpack_from("<IQ", payload, 1)
                    got[subs[sub]].append((log_ns, 0, _fields(payload[13:])))
        finally:
            pipeline.stop()
    finally:
        ws.close()
        publisher.close()
    stamps = {stamp_ns(i) for i in range(6)}
    assert got["/murk/raw"], "no message received"
    for topic, messages in got.items():
        assert len(messages) == pipeline.restored, topic
        for log_ns, _, fields in messages:
            ts = _fields(fields[1][0])  # type: ignore[arg-type]
            source_ns = ts[1][0] * 1_000_000_000 + ts.get(2, [0])[0]  # type: ignore[operator]
            assert source_ns in stamps and log_ns == source_ns
            assert fields[3] == [b"jpeg"] and fields[4] == [b"cam0"]
            image = cv2.imdecode(np.frombuffer(fields[2][0], np.uint8), cv2.IMREAD_COLOR)  # type: ignore[arg-type]
            assert image.shape == (24, 32, 3)
    raw_stamps = [m[0] for m in got["/murk/raw"]]
    assert raw_stamps == sorted(raw_stamps) and raw_stamps == [m[0] for m in got["/murk/restored"]]
    assert [m[0] for m in got["/murk/depth"]] == raw_stamps  # the method estimates depth: published too
