"""A perception node counts every dropped message and logs the reason throttled (5 s)."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Header, Image, make, ns_to_time
from visnav.perception.nodes import ImageProcNode


def _bad_image(stamp_ns: int) -> Image:
    header = Header(stamp=ns_to_time(stamp_ns), frame_id="c")
    data = np.zeros(3, dtype=np.uint8)  # 2x2 mono8 needs 4 bytes
    return make(Image, header=header, height=2, width=2, encoding="mono8", step=2, data=data)


def test_repeated_bad_images_are_counted_and_logged_once_per_period(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with Context(transport="local") as ctx:
        node = ImageProcNode(context=ctx, namespace="/cam")
        probe = Node("probe", context=ctx)
        images = probe.create_publisher(Image, "/cam/image_raw", 10)
        infos = probe.create_publisher(CameraInfo, "/cam/camera_info", 10)
        with caplog.at_level(logging.ERROR, logger="visnav.node"):
            for i in range(3):
                header = Header(stamp=ns_to_time(i + 1), frame_id="c")
                images.publish(_bad_image(i + 1))
                infos.publish(make(CameraInfo, header=header, width=2, height=2))
                ctx.spin_some()
    assert node.dropped == 3
    errors = [r.getMessage() for r in caplog.records if "dropped a message" in r.getMessage()]
    assert len(errors) == 1  # the next two fall within the 5 s throttle
    assert "dropped a message on /cam/image_raw + /cam/camera_info (1 so far)" in errors[0]
