"""The launchable viewer node (what a roslaunch ``rviz`` node maps to)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rerun")

from visnav.graph import Context, Node
from visnav.msgs import Header, Image, ns_to_time, numpy_to_image
from visnav.node_registry import resolve_node_class


def test_viewer_node_streams_the_graph_to_a_recording(tmp_path: Path) -> None:
    rrd = tmp_path / "launch.rrd"
    cls = resolve_node_class("viz")
    with Context(transport="local") as ctx:
        pub = Node("camera", context=ctx).create_publisher(Image, "/camera/image_raw", 5)
        viewer = cls("rviz", context=ctx, parameter_overrides={"web": False, "save": str(rrd)})
        viewer._poll()  # subscribe to the topics that exist now
        img = numpy_to_image(
            np.full((6, 8, 3), 200, np.uint8),
            "rgb8",
            header=Header(stamp=ns_to_time(1_000_000_000), frame_id="camera_optical_frame"),
        )
        pub.publish(img)
        ctx.spin_some()
        assert viewer.feed.received == 1
        assert "/camera/image_raw" in viewer.feed.topics
        viewer.destroy_node()
    assert rrd.exists()
    assert rrd.stat().st_size > 0
