"""``murk live`` as one library call: check the method, open the source, start the frame pipeline, the web server
and optionally the Foxglove publisher, wait for a stop request (or the source's end), and shut everything down in
order: web server, capture and restoration, a running recording (finished: a playable file), Foxglove."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from murk.live.restore_loop import FrameHook, LivePipeline
from murk.live.server import LiveServer, method_table
from murk.live.source import PacedSource, describe, open_live_source, reopener

EventFn = Callable[[str], None]


@dataclass(frozen=True)
class LiveOptions:
    """The settings of ``murk live`` (see ``murk live --help`` and docs/live.md).

    Attributes:
        source: camera index, video file, stream URL or ROS bag.
        method: restoration method spec (any registered method or chain, options after ``?``).
        topic: the image topic of a ROS bag.
        host, port: where the page is served (``127.0.0.1`` by default; ``port=0`` picks a free one).
        token: access token every request must carry (the printed URL holds it); None for none.
        out_dir: folder of snapshots and recordings (nothing is written elsewhere).
        loop: start a file or bag again at its end.
        exit_at_end: stop when the source ends (default: keep serving the last frame until stopped).
        record: start recording at once.
        foxglove, foxglove_port: also publish on a Foxglove WebSocket server on ``host:foxglove_port``.
    """

    source: str
    method: str = "lite+post"
    topic: str | None = None
    host: str = "127.0.0.1"
    port: int = 8080
    token: str | None = None
    out_dir: Path = Path("murk-live")
    loop: bool = False
    exit_at_end: bool = False
    record: bool = False
    foxglove: bool = False
    foxglove_port: int = 8765

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ValueError(f"--port: expected 0..65535, got {self.port}")
        if not 0 <= self.foxglove_port <= 65535:
            raise ValueError(f"--foxglove-port: expected 0..65535, got {self.foxglove_port}")
        if self.token is not None and (not self.token or not self.token.isascii() or not self.token.isprintable()):
            raise ValueError("--token: expected printable ASCII text")


@dataclass
class LiveReport:
    """How a live session went."""

    url: str = ""
    foxglove_url: str | None = None
    restored: int = 0
    dropped: int = 0
    broken: int = 0
    failed: int = 0
    ended: str | None = None
    stopped: bool = False
    recordings: list[Path] = field(default_factory=list)


def run_live(
    options: LiveOptions,
    *,
    shared: dict[str, Any] | None = None,
    should_stop: Callable[[], bool] = lambda: False,
    on_event: EventFn = lambda _text: None,
    poll_s: float = 0.1,
) -> LiveReport:
    """Serve the live view of ``options.source`` until ``should_stop()`` (or the source's end with
    ``exit_at_end``); ``shared`` holds the command's settings for the method (device, ...); ``on_event``
    receives the lines to show (the address, warnings, the source's end).

    The method (names, options, given weights files) is checked first, before the source is opened.

    Raises:
        InputFileError: the source cannot be opened, or a given weights file is not there. ValueError: an unknown
            method or option, a port in use, or ``--foxglove`` without the ``foxglove`` extra.
    """
    from murk.enhance.restorer import check, create

    settings = {"batch": 1} | dict(shared or {})

    def make_restorer(spec: str) -> Any:
        return create(spec, shared=settings)

    # the method's names, options and weights files, before the source is opened (a stream that never answers
    # would otherwise keep a misspelt method waiting) and before torch is imported
    check(options.method, shared=settings, files=True)
    reader = open_live_source(options.source, topic=options.topic)
    source = PacedSource(reader, reopen=reopener(options.source, options.topic), loop=options.loop)
    report = LiveReport()
    with contextlib.ExitStack() as stack:
        stack.callback(source.close)
        hooks: list[FrameHook] = []
        publisher = None
        if options.foxglove:
            from murk.live.foxglove_publisher import FoxglovePublisher

            publisher = FoxglovePublisher(options.host, options.foxglove_port)
            stack.callback(publisher.close)
            hooks.append(publisher)
            report.foxglove_url = publisher.url
        pipeline = LivePipeline(source, make_restorer, options.method, options.out_dir, hooks=hooks)
        stack.callback(_finish, pipeline, report)
        try:
            server = LiveServer(pipeline, options.host, options.port, token=options.token, methods=method_table())
        except OSError as exc:
            raise ValueError(f"--port {options.port}: cannot serve on {options.host} ({exc.strerror or exc})") from None
        stack.callback(server.stop)
        report.url = server.url
        pipeline.start()
        server.start()
        on_event(f"source: {describe(options.source, reader)}")
        on_event(f"method: {options.method}; snapshots and recordings go to {options.out_dir}")
        on_event(f"live view: {server.url}")
        if not server.loopback:
            on_event(
                f"warning: serving on {options.host}: anyone who can reach this machine can watch the feed, switch "
                "the method, take snapshots and record"
                + ("" if options.token else " (pass --token to require an access token)")
            )
        if publisher is not None:
            on_event(f"Foxglove: {publisher.url} (topics /murk/raw, /murk/restored, /murk/depth)")
        if options.record:
            on_event(f"recording to {pipeline.set_recording(True)}")
        told, stops = False, 0
        while not should_stop():
            if pipeline.recording_stops > stops:  # a write failed (a full disk): the view goes on
                stops = pipeline.recording_stops
                on_event(f"recording stopped: {pipeline.recording_stopped or 'a write failed'}")
            if pipeline.ended is not None and not told:
                told = True
                on_event(f"source ended: {pipeline.ended} (after {pipeline.restored} restored frames)")
                if options.exit_at_end:
                    break
            time.sleep(poll_s)
        report.stopped = should_stop()
    for path in report.recordings:
        on_event(f"recording saved: {path}")
    return report


def _finish(pipeline: LivePipeline, report: LiveReport) -> None:
    report.recordings = pipeline.stop()
    report.restored, report.dropped = pipeline.restored, pipeline.dropped
    report.broken, report.failed = pipeline.broken, pipeline.failed
    report.ended = pipeline.ended
