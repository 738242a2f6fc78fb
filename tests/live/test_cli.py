"""``murk live`` on the command line: the source's end, bad input (the method checked before the source is opened),
and Ctrl+C finishing a running recording."""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

from typer.testing import CliRunner

from murk.cli.main import app
from testkit.video import read_video
from tests.live._live import clip

runner = CliRunner()


def test_exit_at_end_reports_the_end(tmp_path: Path) -> None:
    path = clip(tmp_path, n=6, fps=30.0)
    result = runner.invoke(
        app, ["live", str(path), "--method", "post", "--port", "0", "--exit-at-end", "--out", str(tmp_path / "o")]
    )
    assert result.exit_code == 0, result.output
    assert "live view: http://127.0.0.1:" in result.output
    assert "source ended: end" in result.output
    assert "frames restored" in result.output
    assert not (tmp_path / "o").exists()


def test_bad_input_is_a_clear_error(tmp_path: Path) -> None:
    result = runner.invoke(app, ["live", str(tmp_path / "nope.mp4"), "--port", "0"])
    assert result.exit_code == 2 and "nope.mp4" in result.output and "not found" in result.output
    path = clip(tmp_path, n=3)
    result = runner.invoke(app, ["live", str(path), "--method", "nope", "--port", "0"])
    assert result.exit_code == 2 and "unknown 'nope'" in result.output
    result = runner.invoke(app, ["live", str(path), "--topic", "/cam", "--port", "0"])
    assert result.exit_code == 2 and "not a ROS bag" in result.output


def test_the_method_is_checked_before_the_source_is_opened(tmp_path: Path) -> None:
    """A stream server that accepts and never answers would keep ``murk live`` waiting for its first frame (about
    11 s) and then report the stream: a misspelt method, an unknown option or a missing weights file is reported
    first, and the server never sees a connection (issue 47)."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        url = f"http://127.0.0.1:{server.getsockname()[1]}/stream"
        missing = tmp_path / "missing.pt"
        for method, said in [
            ("jointd", "unknown 'jointd' (did you mean 'jointid'?)"),
            ("post?lamda=1", "unknown option 'lamda' (did you mean 'lam'?)"),
            (f"jointid?checkpoint={missing}", f"{missing}: checkpoint not found"),
            (f"lite+post?checkpoint={missing}", f"{missing}: checkpoint not found"),
        ]:
            result = runner.invoke(app, ["live", url, "--method", method, "--port", "0", "--out", str(tmp_path / "o")])
            assert result.exit_code == 2, (method, result.output)
            assert said in " ".join(result.output.split()), (method, result.output)
            assert url not in result.output  # the stream was not what it reported
        server.setblocking(False)
        try:  # the kernel completes a client's handshake without accept(): a connection would wait here
            conn, peer = server.accept()
        except BlockingIOError:
            pass
        else:
            conn.close()
            raise AssertionError(f"murk live connected to the source ({peer}) before checking its method")
    assert not (tmp_path / "o").exists()


def test_exposed_host_prints_a_warning(tmp_path: Path) -> None:
    path = clip(tmp_path, n=3, fps=30.0)
    result = runner.invoke(
        app, ["live", str(path), "-m", "post", "--host", "0.0.0.0", "--port", "0", "--exit-at-end", "-o", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    assert "warning: serving on 0.0.0.0" in result.output and "--token" in result.output


def test_ctrl_c_finishes_the_recording_and_exits_130(tmp_path: Path) -> None:
    path = clip(tmp_path, n=20, fps=30.0)
    out = tmp_path / "out"
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[2] / "src"), *sys.path])}
    cmd = [sys.executable, "-m", "murk", "live", str(path), "-m", "post", "--port", "0", "--loop", "--record"]
    proc = subprocess.Popen([*cmd, "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    head = b""
    try:
        assert proc.stdout is not None
        while b"live view: " not in head and (line := proc.stdout.readline()):
            head += line
        assert b"live view: " in head, head.decode()
        port = urlsplit(head.split(b"live view: ")[1].split()[0].decode()).port
        assert port, head.decode()
        # Frames shown after the recording's first one (its file appears with it) were recorded: the restore thread
        # records each frame before it hands it to be shown, and Ctrl+C finishes the one in progress. Two frames
        # restored before the recording may still be shown after it (one being shown, one waiting to be): seven
        # shown frames hold five recorded ones.
        deadline = time.monotonic() + 600  # only a fault reaches it
        while not list(out.glob("recording_*")):
            assert time.monotonic() < deadline and proc.poll() is None, head.decode()
            time.sleep(0.05)
        first = _status(port)["restored"]
        while _status(port)["restored"] < first + 7:
            assert time.monotonic() < deadline and proc.poll() is None, head.decode()
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)  # murk live handles SIGINT itself, whatever it inherited
        output, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    output = head + output
    text = output.decode()
    assert proc.returncode == 130, text
    (recording,) = out.glob("recording_*")
    assert f"recording saved: {recording}" in text
    frames = read_video(recording)
    assert len(frames) >= 5 and frames[0].shape == (48, 64, 3)  # finished and playable


def _status(port: int) -> dict:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    try:
        conn.request("GET", "/api/status")
        return json.loads(conn.getresponse().read())
    finally:
        conn.close()
