"""The operator's live view (``murk live``): capture -> restore -> a local web page and, optionally, Foxglove.

One job per module: :mod:`murk.live.source` (sources paced in real time, stamped frames),
:mod:`murk.live.restore_loop` (capture and restore threads, newest frame wins, method switching, snapshots and
recording), :mod:`murk.live.outputs` (snapshot files, the recorder), :mod:`murk.live.page` (the page's files),
:mod:`murk.live.server` (the HTTP server), :mod:`murk.live.foxglove_publisher` (Foxglove) and
:mod:`murk.live.run` (:func:`run_live`, what the command calls). See docs/live.md.
"""

from murk.live.run import LiveOptions, LiveReport, run_live

__all__ = ["LiveOptions", "LiveReport", "run_live"]
