"""Renders report.html in a real headless Chromium and checks that every image decoded and the table rendered.

Marked ``browser`` (CI skips it): run with ``make browser-test`` (installs Debian's chromium when missing).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from murk.data import sample_underwater_dir
from murk.report.compare import run_compare
from murk.report.methods import parse_method
from testkit.chromium import HEADLESS_FLAGS

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser-test installs it)")
def test_report_renders_in_chromium(tmp_path: Path) -> None:
    images = [sample_underwater_dir() / "suim" / "n_l_52_.jpg", sample_underwater_dir() / "funie_euvp" / "3.jpg"]
    run_compare(images, [parse_method("raw"), parse_method("post")], tmp_path)
    cmd = [
        CHROMIUM,
        *HEADLESS_FLAGS,
        f"--user-data-dir={tmp_path / 'profile'}",
        "--virtual-time-budget=5000",
        "--dump-dom",
        (tmp_path / "report.html").as_uri(),
    ]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True).stdout
    body = re.search(r"<body[^>]*>", dom)
    assert body, dom[:500]
    attrs = dict(re.findall(r'(data-[a-z-]+)="([^"]*)"', body.group(0)))
    assert attrs["data-images-total"] == "2"
    assert attrs["data-images-loaded"] == attrs["data-images-total"]  # every embedded image decoded
    assert attrs["data-table-rows"] == "2"  # the summary table rendered one row per method
