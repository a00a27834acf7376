"""``LiveView``: the graph of a running context streamed to the web viewer, kept light.

What ``visnav run --view``, ``visnav view`` (live) and the ``viewer`` node share: the web
viewer on fixed loopback ports (:func:`~visnav.viz.viewer.open_viewer`), a
:class:`~visnav.viz.RerunSink` behind a :class:`~visnav.viz.display_sink.DisplaySink`
(display rate, worker thread, JPEG images, decimated clouds), the simulator's world
geometry (:func:`~visnav.viz.scene.world_from_graph`) and a
:class:`~visnav.viz.LiveFeed` that subscribes to every topic shown (with ``paced``, a
:class:`~visnav.viz.paced_feed.PacedFeed`: the publishers in other processes send only
the messages shown). Nothing is written to disk but the viewer's log unless ``save`` is
given. ``visnav run --view`` runs it in a process of its own
(:mod:`visnav.viz.view_process`).
"""

from __future__ import annotations

import logging
from collections.abc import Collection, Mapping
from pathlib import Path
from types import TracebackType

from visnav.graph.context import Context
from visnav.viz.display_sink import DisplaySink
from visnav.viz.paced_feed import PacedFeed
from visnav.viz.rviz_config import RvizConfig
from visnav.viz.sink import RerunSink
from visnav.viz.sources import LiveFeed
from visnav.viz.viewer import DEFAULT_GRPC_PORT, DEFAULT_MEMORY_LIMIT, DEFAULT_WEB_PORT, open_viewer

__all__ = ["RENDERED_TYPES", "LiveView"]

_LOG = logging.getLogger("visnav.viz")

RENDERED_TYPES = frozenset(
    {"sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage", "sensor_msgs/msg/PointCloud2"}
)
"""Types the simulator produces only for subscribers (cameras, depth clouds)."""

_CLOUD = "sensor_msgs/msg/PointCloud2"
_CAMERA_INFO = "sensor_msgs/msg/CameraInfo"


class LiveView:
    """Streams a context's topics to a viewer (see the module docstring); close it.

    Args:
        context: the graph context to join.
        web: serve the web viewer (else spawn the native one, or only ``save``).
        port: the web page's port (0: a free one).
        grpc_port: the gRPC server's port (0: a free one).
        save: also write this ``.rrd`` file.
        memory_limit: what the viewer's server keeps for late pages.
        log_path: the viewer's own log (Rerun's messages).
        fixed_frame: the frame shown (default: the TF root).
        topics: only these topics (plus TF).
        max_points: clouds decimated to this many points.
        world: draw the simulator's world geometry (asks the ``sim`` node).
        packages: ``package://`` directories for the robot model.
        sensors_in_use_only: show an image or cloud topic (:data:`RENDERED_TYPES`) only
            once another node subscribes to it: the simulator renders a camera (and
            computes its cloud) only when it has a subscriber, so a viewer subscribing
            on its own would make a run render, and slow down, for display alone.
            ``visnav run --view`` sets it; ``visnav view`` and the ``viewer`` node show
            every topic, as RViz does. Topics named in ``topics`` are always shown, and
            so are clouds of nodes that publish no ``CameraInfo`` (a planner's map such
            as the drone's ``grid_map/occupancy_inflate``, computed, not rendered).
        rviz: an RViz config (:mod:`visnav.viz.rviz_config`): fixed frame (unless
            ``fixed_frame``), colours, TF axes; pass ``topics=rviz.topics`` to show only
            its enabled displays.
        paced: pace the display-rated subscriptions (a viewer in another process than
            the publishers; see :mod:`visnav.viz.paced_feed`).
    """

    def __init__(
        self,
        context: Context,
        *,
        web: bool = True,
        port: int = DEFAULT_WEB_PORT,
        grpc_port: int = DEFAULT_GRPC_PORT,
        save: str | Path | None = None,
        memory_limit: str = DEFAULT_MEMORY_LIMIT,
        log_path: str | Path | None = None,
        fixed_frame: str | None = None,
        topics: Collection[str] | None = None,
        max_points: int | None = 20_000,
        world: bool = True,
        packages: Mapping[str, str] | None = None,
        sensors_in_use_only: bool = False,
        rviz: RvizConfig | None = None,
        paced: bool = False,
    ) -> None:
        from visnav.viz.scene import world_from_graph  # noqa: PLC0415 - parameter client

        self.viewer = open_viewer(
            web=web,
            port=port,
            grpc_port=grpc_port,
            save=save,
            memory_limit=memory_limit,
            log_path=log_path,
        )
        try:
            rerun_sink = RerunSink(
                self.viewer.recording,
                fixed_frame=fixed_frame,
                max_points=max_points,
                packages=packages,
                rviz=rviz,
            )
            accept = self._in_use if sensors_in_use_only and topics is None else None
            feed_type = PacedFeed if paced else LiveFeed
            self.feed = feed_type(rerun_sink, context, topics=topics, accept=accept)
            node = self.feed.node
            loader = (lambda: world_from_graph(node)) if world else None
            self.sink = DisplaySink(rerun_sink, world_loader=loader)
            self.feed.sink = self.sink
        except BaseException:
            self.viewer.close()
            raise
        self._closed = False

    def _in_use(self, topic: str, type_name: str) -> bool:
        if type_name not in RENDERED_TYPES:
            return True
        me = self.feed.node.get_name()
        endpoints = self.feed.context.graph.endpoints(topic)
        if type_name == _CLOUD:  # a camera's cloud is rendered; a planner's map is not
            pubs = {e.node_fqn for e in endpoints if e.kind == "publisher"}
            cameras = {
                e.node_fqn
                for e in self.feed.context.graph.endpoints()
                if e.kind == "publisher" and e.type_name == _CAMERA_INFO
            }
            if pubs and not pubs & cameras:
                return True  # e.g. the drone's grid_map/occupancy_inflate (RViz shows it)
        return any(e.kind == "subscription" and e.node_name != me for e in endpoints)

    @property
    def url(self) -> str | None:
        """The web viewer's page (None without ``web``)."""
        return self.viewer.url

    def poll(self) -> None:
        """Subscribe to new topics, expire data that waited too long for TF."""
        self.feed.scan()
        self.sink.poll()

    def spin_once(self, timeout_s: float = 0.05) -> None:
        """Run the feed's callbacks (a viewer spinning its own context), rescan when due."""
        self.feed.spin_once(timeout_s)

    def close(self) -> None:
        """Stop the feed, log what is queued, close the viewer (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self.feed.close()
            self.sink.close()
            _LOG.debug(
                "viewer: worker CPU %.3f s in %d batches, messages received %d",
                self.sink.worker_cpu_s,
                self.sink.batches,
                self.feed.received,
            )
        finally:
            self.viewer.close()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
