"""``murk live --foxglove``: the raw and restored frames (and the depth map of methods that estimate it) published
live as ``foxglove.CompressedImage`` messages over Foxglove's WebSocket protocol, with the maintained
``foxglove-sdk`` package (the optional ``foxglove`` extra: ``pip install 'murk[foxglove]'``).

Topics: ``/murk/raw``, ``/murk/restored`` and ``/murk/depth`` (the depth colour preview of
:func:`murk.enhance.preview.colorize_depth`, 0-15 m, near = warm). Each message carries the frame's source time
(a ROS bag message's header stamp, a file's playback time, a camera's capture time) as its ``timestamp`` and as
its log time, and the source's ``frame_id`` (``camera`` when the source has none). Only the topics some client
subscribes to are encoded: with Foxglove on and nobody watching, a view costs nothing more than the page's. A
subscribed ``/murk/raw`` or ``/murk/restored`` is the view's full-resolution JPEG, encoded once and shown by the page
too (:meth:`FoxglovePublisher.full_views`, :class:`murk.live.restore_loop.SharesJpegs`).
"""

from __future__ import annotations

from collections.abc import Collection

from murk.enhance.preview import colorize_depth
from murk.io.images import to_uint
from murk.live.restore_loop import JPEG_QUALITY, LiveView, encode_jpeg

TOPICS = {"raw": "/murk/raw", "restored": "/murk/restored", "depth": "/murk/depth"}
INSTALL_HINT = "--foxglove needs the optional 'foxglove' extra: pip install 'murk[foxglove]' (foxglove-sdk)"


def foxglove_available() -> bool:
    try:
        import foxglove  # noqa: F401
    except ImportError:
        return False
    return True


class FoxglovePublisher:
    """A Foxglove WebSocket server publishing every :class:`LiveView` it is called with.

    Raises:
        ValueError: ``foxglove-sdk`` is not installed, or the server cannot listen on ``host:port``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, *, quality: int = JPEG_QUALITY) -> None:
        try:
            import foxglove
            from foxglove.channels import CompressedImageChannel
        except ImportError:
            raise ValueError(INSTALL_HINT) from None
        self.quality = quality
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name="murk live", host=host, port=port, context=self._context)
        except Exception as exc:  # the SDK raises its own error types
            raise ValueError(
                f"--foxglove-port {port}: cannot start the Foxglove server on {host} ({exc}); choose another "
                "--foxglove-port (0: a free one)"
            ) from None
        self.port = int(self._server.port)
        self.host = host
        self._channels = {k: CompressedImageChannel(t, context=self._context) for k, t in TOPICS.items()}

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def subscribed(self) -> set[str]:
        """The topics some client is subscribed to now (a message on any other topic goes nowhere)."""
        return {TOPICS[key] for key, channel in self._channels.items() if channel.has_sinks()}

    def full_views(self) -> Collection[str]:
        """Which of ``raw``/``restored`` the next view will be published as, at full resolution and the page's
        quality: the publish thread encodes those first and the page shows the same JPEGs (encoded once)."""
        if self.quality != JPEG_QUALITY:
            return ()
        return [key for key in ("raw", "restored") if self._channels[key].has_sinks()]

    def __call__(self, view: LiveView) -> None:
        from foxglove.messages import CompressedImage, Timestamp

        stamp = Timestamp(view.source_ns // 1_000_000_000, view.source_ns % 1_000_000_000)
        frame_id = view.frame_id or "camera"
        keys = [key for key in ("raw", "restored", "depth") if self._channels[key].has_sinks()]
        for key in keys:  # a topic no client subscribes to is not encoded (at 1920x1080 ~8 ms of CPU per JPEG)
            if key == "depth":
                if view.depth_m is None:
                    continue
                data = encode_jpeg(to_uint(colorize_depth(view.depth_m), 8), self.quality)
            else:
                data = view.jpeg(key, self.quality)  # shared with any other reader of the same view
            message = CompressedImage(timestamp=stamp, frame_id=frame_id, data=data, format="jpeg")
            self._channels[key].log(message, log_time=view.source_ns)

    def close(self) -> None:
        self._server.stop()
