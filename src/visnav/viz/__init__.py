"""The viewer: ROS messages shown in Rerun, placed in a fixed frame through TF (as RViz).

Library::

    from visnav.viz import RerunSink, open_viewer

    with open_viewer(save="run.rrd", web=True) as viewer:   # web: 127.0.0.1 only
        print(viewer.url)
        sink = RerunSink(viewer.recording, fixed_frame="odom")
        sink.log("/camera/image_raw", image_msg)            # (topic, msg[, stamp_ns])
        sink.close()

:class:`RerunSink` converts and places messages; :func:`open_viewer` makes the
recording and its outputs; :class:`LiveFeed` and :func:`feed_bag` feed a sink from the
graph or a bag. Those need the optional Rerun SDK (``pip install 'visnav[viz]'``); they
are imported on first use, and without the SDK the import raises
:class:`RerunMissingError` with that instruction. :mod:`visnav.viz.display` (images to
RGB, used by ``visnav image view --snapshot``), :mod:`visnav.viz.geometry` and
:mod:`visnav.viz.placement` work without it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from visnav.viz.display import image_to_display, message_to_display, write_png
from visnav.viz.errors import RERUN_MISSING_TEXT, RerunMissingError, VizError
from visnav.viz.placement import FramePlacer

if TYPE_CHECKING:
    from visnav.viz.sink import SUPPORTED_TYPES, RerunSink
    from visnav.viz.sources import LiveFeed, feed_bag
    from visnav.viz.viewer import Viewer, open_viewer

__all__ = [
    "RERUN_MISSING_TEXT",
    "SUPPORTED_TYPES",
    "FramePlacer",
    "LiveFeed",
    "RerunMissingError",
    "RerunSink",
    "Viewer",
    "VizError",
    "feed_bag",
    "image_to_display",
    "message_to_display",
    "open_viewer",
    "write_png",
]

_LAZY = {
    "SUPPORTED_TYPES": "visnav.viz.sink",
    "RerunSink": "visnav.viz.sink",
    "LiveFeed": "visnav.viz.sources",
    "feed_bag": "visnav.viz.sources",
    "Viewer": "visnav.viz.viewer",
    "open_viewer": "visnav.viz.viewer",
}


def __getattr__(name: str) -> Any:
    """Import the Rerun-backed names on first use (raises RerunMissingError without rerun)."""
    module = _LAZY.get(name)
    if module is None:
        text = f"module 'visnav.viz' has no attribute {name!r}"
        raise AttributeError(text)
    return getattr(importlib.import_module(module), name)
