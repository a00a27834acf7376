"""The viewer's default layout: the 3D view with every camera's images beside it.

RViz opens a 3D view with its Image displays docked to the side; :func:`default_blueprint`
builds the Rerun blueprint for that: the 3D view of the fixed frame (two thirds of the
width) and, to its right, one 2D view per camera entity (``world/cameras/<ns>``: its
images, depth and pinhole), stacked. The sink sends it again when a camera appears.
The time panel follows the newest data, as RViz shows now (a bag opened after it was
read shows its end, not a 1x replay from its start); scrub back on the time line.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["default_blueprint"]


def default_blueprint(root: str, cameras: Sequence[str], *, timeline: str = "ros_time") -> Any:
    """The blueprint: 3D view of ``root``, the ``cameras`` (entity paths) beside it.

    Args:
        root: the fixed frame's entity (``world``).
        cameras: camera entities, in the order they appeared.
        timeline: the timeline the time panel follows.
    """
    import rerun.blueprint as rrb  # noqa: PLC0415 (the optional SDK, like visnav.viz._rerun)

    view3d = rrb.Spatial3DView(origin=f"/{root}", name="3D")
    time_panel = rrb.TimePanel(timeline=timeline, play_state="following")
    if not cameras:
        return rrb.Blueprint(view3d, time_panel, collapse_panels=False)
    images = [
        rrb.Spatial2DView(origin=f"/{camera}", name=camera.rsplit("/", 1)[-1]) for camera in cameras
    ]
    return rrb.Blueprint(
        rrb.Horizontal(view3d, rrb.Vertical(*images), column_shares=[2, 1]),
        time_panel,
        collapse_panels=False,
    )
