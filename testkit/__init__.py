"""Helpers that the tests and the benchmarks share (both may import this package; murk never does).

- :mod:`testkit.chromium`: a headless Chromium driven over its DevTools protocol (browser tests, the live view's
  benchmark and soak);
- :mod:`testkit.ws`: the minimal WebSocket client under it (also the Foxglove tests);
- :mod:`testkit.video`: synthetic frames, small video files, an MJPEG camera, a clip of the shipped underwater
  photographs, reading a video back.

It lives outside ``src/``, so it is never shipped: the wheel packs ``murk`` only (``tools/check_wheel.py`` refuses
a wheel holding anything else). A helper only the tests use stays under ``tests/``.
"""
