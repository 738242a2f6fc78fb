"""``murk live``: the restored camera feed in a local web page (and in Foxglove), side by side with the raw one."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from murk.cli._common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_PARTIAL,
    DeviceOpt,
    QuietOpt,
    make_console,
    resolve_device,
    stop_on_signals,
    topic_option,
)


def live(
    source: Annotated[
        str,
        typer.Argument(
            help="A camera index (0), a video file (played at its own rate), a stream URL (rtsp://..., http://...) "
            "or a ROS bag with --topic (replayed at its recorded speed).",
            show_default=False,
        ),
    ],
    method: Annotated[
        str,
        typer.Option(
            "--method",
            "-m",
            help="Restoration method or chain, options after '?' (e.g. lite+post?temporal=0.8); switchable from "
            "the page.",
        ),
    ] = "lite+post",
    topic: Annotated[str | None, topic_option("ROS bag")] = None,
    host: Annotated[
        str,
        typer.Option("--host", help="Address of the page; 0.0.0.0 exposes it to the network (a warning is printed)."),
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", min=0, max=65535, help="Port of the page (0: a free one).")] = 8080,
    token: Annotated[
        str | None,
        typer.Option("--token", help="Access token every request must carry (the printed URL holds it)."),
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Folder of snapshots and recordings (nothing is written elsewhere).")
    ] = Path("murk-live"),
    loop: Annotated[bool, typer.Option("--loop", help="Play a file or bag again from the start at its end.")] = False,
    exit_at_end: Annotated[
        bool, typer.Option("--exit-at-end", help="Exit when the source ends (default: keep the page until Ctrl+C).")
    ] = False,
    record: Annotated[bool, typer.Option("--record", help="Start recording the restored stream at once.")] = False,
    foxglove: Annotated[
        bool,
        typer.Option("--foxglove", help="Also publish raw/restored/depth images on a Foxglove WebSocket server."),
    ] = False,
    foxglove_port: Annotated[
        int, typer.Option("--foxglove-port", min=0, max=65535, help="Port of the Foxglove server.")
    ] = 8765,
    device: DeviceOpt = "cpu",
    quiet: QuietOpt = False,
) -> None:
    """Watch a camera, file, stream or bag restored live in a browser: raw | restored, method switch, snapshots,
    recording (docs/live.md). Ctrl+C stops it (a running recording is finished) with exit code 130."""
    from murk.live import LiveOptions, run_live

    console = make_console(quiet)
    loud = make_console(False)
    options = LiveOptions(
        source=source,
        method=method,
        topic=topic,
        host=host,
        port=port,
        token=token,
        out_dir=out,
        loop=loop,
        exit_at_end=exit_at_end,
        record=record,
        foxglove=foxglove,
        foxglove_port=foxglove_port,
    )

    def show(text: str) -> None:
        target = loud if text.startswith(("warning", "source ended", "live view", "recording saved")) else console
        target.print(escape(text), soft_wrap=True, highlight=False)

    with stop_on_signals() as stop:
        report = run_live(options, shared={"device": resolve_device(device)}, should_stop=stop, on_event=show)
    loud.print(
        f"{report.restored} frames restored, {report.dropped} dropped (source faster than {escape(method)}), "
        f"{report.broken} undecodable, {report.failed} failed",
        soft_wrap=True,
        highlight=False,
    )
    if report.stopped:
        raise typer.Exit(EXIT_INTERRUPTED)
    raise typer.Exit(EXIT_OK if report.ended == "end" and not report.failed else EXIT_PARTIAL)
