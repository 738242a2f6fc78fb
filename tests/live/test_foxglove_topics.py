"""``murk live --foxglove`` encodes only the topics some client subscribes to (issue 48, point 5): with nobody
watching Foxglove, a view costs no JPEG beyond the page's; a subscribed topic's JPEG is the view's own, shared with
every other reader of the same view."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove")

from murk.live.foxglove_publisher import FoxglovePublisher
from murk.live.restore_loop import LiveView


class _Channel:
    """A channel with or without a subscriber, recording what it is given to log."""

    def __init__(self, subscribed: bool) -> None:
        self.subscribed = subscribed
        self.logged: list[Any] = []

    def has_sinks(self) -> bool:
        return self.subscribed

    def log(self, message: Any, log_time: int) -> None:
        self.logged.append((message, log_time))


def _view(depth: bool) -> LiveView:
    rgb = np.tile(np.arange(64, dtype=np.uint8)[None, :, None], (48, 1, 3))
    depth_m = np.full((48, 64), 2.0, np.float32) if depth else None
    return LiveView(3, rgb, 255 - rgb, depth_m, 1, 5_000_000_007, 2, "lite", "cam0")


@pytest.mark.parametrize("subscribed", [(), ("restored",), ("raw", "restored", "depth")])
def test_only_subscribed_topics_are_encoded_and_published(subscribed: tuple[str, ...]) -> None:
    publisher = FoxglovePublisher("127.0.0.1", 0)
    try:
        channels = {key: _Channel(key in subscribed) for key in ("raw", "restored", "depth")}
        publisher._channels = channels  # type: ignore[assignment]
        view = _view(depth=True)
        publisher(view)
        for key, channel in channels.items():
            assert len(channel.logged) == (key in subscribed), key
            if channel.logged:
                message, log_time = channel.logged[0]
                assert log_time == view.source_ns and b"cam0" in message.encode()
        encoded = {key.split(":")[0] for key in view._jpeg}
        assert encoded == set(subscribed) - {"depth"}  # the depth preview is not one of the view's shared JPEGs
        if "restored" in subscribed:  # the message carries the view's own JPEG (protobuf: the bytes as they are)
            assert view.jpeg("restored", publisher.quality) in channels["restored"].logged[0][0].encode()
    finally:
        publisher.close()


@pytest.mark.parametrize("subscribed", [(), ("raw",), ("raw", "restored", "depth")])
def test_the_subscribed_images_are_the_pages_own_jpegs(subscribed: tuple[str, ...]) -> None:
    """Issue 48, point 5: a subscribed /murk/raw or /murk/restored is encoded once per view and the page shows the
    same JPEG (full_views tells the publish thread which); at another quality than the page's, none is shared."""
    publisher = FoxglovePublisher("127.0.0.1", 0)
    try:
        channels = {key: _Channel(key in subscribed) for key in ("raw", "restored", "depth")}
        publisher._channels = channels  # type: ignore[assignment]
        full = publisher.full_views()
        assert set(full) == set(subscribed) - {"depth"}
        rgb = np.random.default_rng(0).integers(0, 256, (1080, 1920, 3), dtype=np.uint8)
        view = LiveView(3, rgb, 255 - rgb, None, 1, 5, 2, "lite")
        page = dict(zip(("raw", "restored"), view.page_jpegs(full), strict=True))
        publisher(view)
        for key in ("raw", "restored"):
            if key in subscribed:
                assert page[key] is view.jpeg(key) and page[key] in channels[key].logged[0][0].encode()
        assert {k for k in view._jpeg if ":" in k} == {f"{k}:85" for k in full}  # none encoded twice
        publisher.quality = 70
        assert not publisher.full_views()
    finally:
        publisher.close()
