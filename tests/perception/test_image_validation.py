"""Built-in nodes validate images before OpenCV sees them: only visnav's own errors escape."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Header, Image, MessageError, make, ns_to_time
from visnav.msgs.image import bytes_per_pixel, check_image, image_to_numpy
from visnav.perception import image_transport
from visnav.perception.depth_image_proc import PointCloudXyz, convert_metric
from visnav.perception.depth_to_scan import DepthImageToLaserScan
from visnav.perception.image_proc import Rectifier, image_color, image_mono
from visnav.perception.nodes import ImageProcNode

ENCODINGS = [
    "rgb8",
    "bgra8",
    "rgb16",
    "mono8",
    "mono16",
    "bayer_rggb8",
    "bayer_gbrg16",
    "yuv422",
    "yuv422_yuy2",
    "uyvy",
    "8UC3",
    "16UC1",
    "32FC1",
    "16SC2",
    "64FC4",
    "rgb9",
    "",
]

OPS: dict[str, Callable[[Image, CameraInfo], Any]] = {
    "image_mono": lambda m, i: image_mono(m),
    "image_color": lambda m, i: image_color(m),
    "rectify": lambda m, i: Rectifier().rectify(m, i),
    "jpeg": lambda m, i: image_transport.compress(m, format="jpeg"),
    "png": lambda m, i: image_transport.compress(m, format="png"),
    "convert_metric": lambda m, i: convert_metric(m),
    "point_cloud_xyz": lambda m, i: PointCloudXyz().convert(m, i),
    "depth_to_scan": lambda m, i: DepthImageToLaserScan().convert(m, i),
}


def _image(encoding: str, height: int, width: int, step: int, size: int) -> Image:
    data = np.arange(size, dtype=np.uint8)
    header = Header(stamp=ns_to_time(1), frame_id="c")
    return make(
        Image, header=header, height=height, width=width, encoding=encoding, step=step, data=data
    )


def _info(width: int, height: int, distorted: bool) -> CameraInfo:
    return make(
        CameraInfo,
        header=Header(stamp=ns_to_time(1), frame_id="c"),
        width=width,
        height=height,
        distortion_model="plumb_bob",
        d=np.array([0.1 if distorted else 0.0, 0, 0, 0, 0]),
        k=np.array([5.0, 0, width / 2, 0, 5, height / 2, 0, 0, 1]),
        r=np.eye(3).ravel(),
        p=np.array([5.0, 0, width / 2, 0, 0, 5, height / 2, 0, 0, 0, 1, 0]),
    )


@settings(max_examples=150, deadline=None)
@given(
    encoding=st.sampled_from(ENCODINGS),
    height=st.integers(0, 5),
    width=st.integers(0, 5),
    step_extra=st.integers(-2, 3),
    size_extra=st.integers(-3, 3),
    info_size=st.sampled_from([None, (4, 4), (1, 1)]),
    distorted=st.booleans(),
    op=st.sampled_from(sorted(OPS)),
)
def test_fuzzed_images_raise_only_visnav_errors(
    encoding: str,
    height: int,
    width: int,
    step_extra: int,
    size_extra: int,
    info_size: tuple[int, int] | None,
    distorted: bool,
    op: str,
) -> None:
    try:
        bpp = bytes_per_pixel(encoding)
    except VisnavError:
        bpp = 1
    step = max(0, width * bpp + step_extra)
    image = _image(encoding, height, width, step, max(0, step * height + size_extra))
    iw, ih = info_size or (width, height)
    with contextlib.suppress(VisnavError):
        OPS[op](image, _info(iw, ih, distorted))


@pytest.mark.parametrize(
    ("height", "width", "encoding", "step", "size", "match"),
    [
        (0, 0, "rgb8", 0, 0, r"Image.width x Image.height is 0x0 .*at least 1x1"),
        (3, 0, "mono8", 0, 0, r"is 0x3"),
        (2, 3, "uyvy", 6, 12, r"Image.width is 3 for encoding 'uyvy': expected an even width"),
        (2, 2, "rgb8", 6, 11, r"Image.data has 11 bytes: expected step \* height"),
        (2, 2, "rgb8", 5, 10, r"Image.step is 5: expected at least"),
        (2, 2, "rgb9", 6, 12, r"Image.encoding is 'rgb9'"),
    ],
)
def test_each_image_fault_is_named(
    height: int, width: int, encoding: str, step: int, size: int, match: str
) -> None:
    image = _image(encoding, height, width, step, size)
    with pytest.raises(MessageError, match=match):
        image_to_numpy(image)
    with pytest.raises(MessageError, match=match):
        check_image(image)
    for op in ("rectify", "png"):
        with pytest.raises(VisnavError, match=match):
            OPS[op](image, _info(4, 4, distorted=True))


def test_image_proc_node_drops_a_bad_image_it_would_pass_through(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with Context(transport="local") as ctx:
        node = ImageProcNode(context=ctx, namespace="/cam")
        probe = Node("probe", context=ctx)
        out: list[Image] = []
        for topic in ("image_mono", "image_color", "image_rect"):
            probe.create_subscription(Image, f"/cam/{topic}", out.append, 10)
        images = probe.create_publisher(Image, "/cam/image_raw", 5)
        infos = probe.create_publisher(CameraInfo, "/cam/camera_info", 5)
        images.publish(_image("mono8", 0, 0, 0, 0))  # mono8 would go out unchanged
        infos.publish(_info(4, 4, distorted=False))
        with caplog.at_level(logging.ERROR):
            ctx.spin_some()
        assert out == []
        assert node.dropped == 1
        assert "Image.width x Image.height is 0x0" in caplog.text
