"""The page of ``murk live``: plain HTML, CSS and JavaScript shipped in the package (``assets/``; no CDN, no
build step, works offline), served by exact name only.

:data:`ASSETS` maps each URL path the server answers with a file to that file and its content type; any other
path is not a file of the page (the server answers 404). Nothing is looked up on the file system by a name
that came from a request.
"""

from __future__ import annotations

import functools
from importlib import resources

ASSETS: dict[str, tuple[str, str]] = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/live.js": ("live.js", "text/javascript; charset=utf-8"),
    "/live.css": ("live.css", "text/css; charset=utf-8"),
}
"""URL path -> (file in ``murk/live/assets``, content type)."""


@functools.cache
def asset(path: str) -> tuple[bytes, str] | None:
    """The bytes and content type of the page file at URL ``path``; None for any other path."""
    entry = ASSETS.get(path)
    if entry is None:
        return None
    name, content_type = entry
    return (resources.files("murk.live").joinpath("assets").joinpath(name).read_bytes(), content_type)
