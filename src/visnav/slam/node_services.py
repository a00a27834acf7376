"""The SLAM node's services, with rtabmap's names where they fit.

In the node's namespace (a node ``slam`` serves ``/slam/reset``; named ``rtabmap`` it
serves ``/rtabmap/reset`` as rtabmap_ros does):

=================  ========================  ==============================================
name               type                      does
=================  ========================  ==============================================
``~/reset``        ``std_srvs/srv/Empty``    drops the map; the next frame starts a new one
                                             as at start (rtabmap's ``reset``)
``~/pause``        ``std_srvs/srv/Empty``    frames are left out (counted) until resumed;
                                             ``map -> odom`` keeps being published
``~/resume``       ``std_srvs/srv/Empty``    frames are used again
``~/save_map``     ``std_srvs/srv/Trigger``  writes the map to ``database_path`` now (the
                                             ``.npz`` and its ``.ply``), as at shutdown
=================  ========================  ==============================================

Where visnav differs from rtabmap: the map is saved by ``~/save_map`` (a ``Trigger``
whose message names the files or says why nothing was written) rather than rtabmap's
``backup`` (``Empty``, to ``database_path.back``); a reset in localization mode starts
localising in the saved map again (rtabmap's reset there clears its working memory).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from visnav.msgs.srv import get_service_type
from visnav.slam.worker import save_at_shutdown

if TYPE_CHECKING:
    from visnav.slam.node import SlamNode

__all__ = ["SlamServices"]


class SlamServices:
    """Serves the module docstring's services on a SLAM node.

    Args:
        node: the SLAM node (fully built).

    Attributes:
        paused: True between ``~/pause`` and ``~/resume``.
        paused_frames: frames left out while paused.
        resets: ``~/reset`` calls served.
    """

    def __init__(self, node: SlamNode) -> None:
        self.node = node
        self.paused = False
        self.paused_frames = 0
        self.resets = 0
        empty = get_service_type("std_srvs/srv/Empty")
        trigger = get_service_type("std_srvs/srv/Trigger")
        node.create_service(empty, "~/reset", self._on_reset)
        node.create_service(empty, "~/pause", self._on_pause)
        node.create_service(empty, "~/resume", self._on_resume)
        node.create_service(trigger, "~/save_map", self._on_save_map)

    def save_map(self) -> tuple[bool, str]:
        """Write the map to ``database_path`` now.

        Returns:
            ``(success, message)``: the files and counts, or why nothing was written.
        """
        node = self.node
        if node.localization:
            return False, (
                "localization mode reads the map at database_path and writes nothing; "
                "map with localization false to make a new one"
            )
        if not node.database_path:
            return False, (
                f"node {node.get_fully_qualified_name()!r} has no database_path, so there is "
                "nowhere to save the map. Fix: start it with database_path:=PATH.npz"
            )
        level, text = save_at_shutdown(node.worker, node.database_path)
        return level == "info", text

    def _on_reset(self, request: object, response: Any) -> Any:
        del request
        self.node.reset_map()
        self.resets += 1
        self.node.get_logger().info("reset: the map is dropped; the next frame starts a new one")
        return response

    def _on_pause(self, request: object, response: Any) -> Any:
        del request
        if not self.paused:
            self.node.get_logger().info("paused: frames are left out until resume")
        self.paused = True
        return response

    def _on_resume(self, request: object, response: Any) -> Any:
        del request
        if self.paused:
            self.node.get_logger().info(
                f"resumed ({self.paused_frames} frames left out while paused)"
            )
        self.paused = False
        return response

    def _on_save_map(self, request: object, response: Any) -> Any:
        del request
        response.success, response.message = self.save_map()
        log = self.node.get_logger()
        (log.info if response.success else log.warning)(f"save_map: {response.message}")
        return response
