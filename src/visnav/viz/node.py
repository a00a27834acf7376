"""The viewer as a launchable node (what a launch file's ``rviz`` maps to).

``ViewerNode`` opens a Rerun viewer (the web viewer on 127.0.0.1 by default, since
launches often run headless; ``web: false`` spawns the native viewer) and streams every
topic of its context's graph to it, placed in ``fixed_frame`` through TF as
``visnav view`` does. Parameters: ``fixed_frame`` (default: the TF root), ``web``
(true), ``save`` (an ``.rrd`` path, default none), ``config`` (an ``.rviz`` file: read
for the fixed frame only by the roslaunch import).
"""

from __future__ import annotations

from typing import Any

from visnav.graph.clock import Clock, ClockType
from visnav.graph.node import Node
from visnav.viz.sink import RerunSink
from visnav.viz.sources import LiveFeed
from visnav.viz.viewer import open_viewer

__all__ = ["ViewerNode"]


class ViewerNode(Node):
    """Streams the graph to Rerun (see the module docstring)."""

    def __init__(self, node_name: str = "viewer", **node_kwargs: Any) -> None:
        super().__init__(node_name, **node_kwargs)
        fixed = str(self.declare_parameter("fixed_frame", "").value) or None
        web = bool(self.declare_parameter("web", value=True).value)
        save = str(self.declare_parameter("save", "").value) or None
        self.declare_parameter("config", "")
        self.viewer = open_viewer(web=web, save=save)
        if self.viewer.url:
            self.get_logger().info(f"viewer: {self.viewer.url}")
        self.feed = LiveFeed(RerunSink(self.viewer.recording, fixed_frame=fixed), self.context)
        steady = Clock(ClockType.STEADY_TIME)
        self.create_timer(0.5, self._poll, clock=steady)

    def _poll(self) -> None:
        self.feed.scan()
        self.feed.sink.poll()

    def destroy_node(self) -> None:
        """Close the viewer, then destroy the node."""
        feed = getattr(self, "feed", None)
        if feed is not None:
            feed.close()
            self.viewer.close()
        super().destroy_node()
